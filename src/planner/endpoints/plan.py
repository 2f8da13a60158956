"""The job of ``/v1/plan`` (and each item of ``/v1/plan/batch``)."""

from __future__ import annotations

from dataclasses import replace

from planner.endpoints import UNBOUNDED, JobBudget
from planner.wire import PlanRequest, PlanResponse, plan_inputs, plan_response

__all__ = ["plan"]


def plan(request: PlanRequest, budget: JobBudget = UNBOUNDED) -> PlanResponse:
    """``POST /v1/plan``: convert (:func:`planner.wire.plan_inputs`, once), solve
    (:func:`planner.solve`: the plan with the goal options ``prefer`` and ``tolerance``, then
    the timing of its path under the path's own rules, re-checked densely; one deadline
    policy, the library's), respond (:func:`planner.wire.plan_response`, built once).

    A library error is a 422 naming the field it came from. Timing outcomes: the request's
    deadline passing gives status ``timeout``; a path the timing cannot turn into a checked
    trajectory (no profile, or the dense re-check fails after the repairs) gives ``no_path``
    with the reason, the path kept and ``diagnostics.timing_error`` naming the failed rule.
    """
    from planner.solver import solve

    inputs = plan_inputs(request)
    timing = replace(inputs.timing, max_samples=budget.max_samples)
    kwargs = {**inputs.solve_kwargs(), "timing": timing}
    # an error of the timing step names its field under ``timing.`` (the default location of a
    # library error is the body, :mod:`planner_api.errors`)
    solution = solve(inputs.design, inputs.start, inputs.goal, deadline=budget.deadline, **kwargs)
    return plan_response(solution, format=request.timing.format)
