"""The endpoint of ``/v1/plan`` (and each item of ``/v1/plan/batch``)."""

from __future__ import annotations

from planner.endpoints import UNBOUNDED, JobBudget
from planner.wire import PlanRequest, PlanResponse, plan_inputs, solution_response
from planner.wire.execution import on_running_clock

__all__ = ["plan"]


def plan(request: PlanRequest, budget: JobBudget = UNBOUNDED) -> PlanResponse:
    """``POST /v1/plan``: convert (:func:`planner.wire.plan_inputs`, once: the motion problem
    with the budget's deadline and sample bound, and the goal), run the pipeline
    (:func:`planner.motion.run` of :class:`planner.solver.GoalMotion`: the plan with the goal
    options ``prefer`` and ``tolerance``, the timing of its path under the path's own rules,
    re-checked densely; one deadline policy), respond (:func:`planner.wire.solution_response`,
    built once).

    A library error is a 422 naming the field it came from (an error of the timing step
    under ``timing.``). Timing outcomes: the request's deadline passing gives status
    ``timeout``; a path the timing cannot turn into a checked trajectory (no profile, or the
    dense re-check fails after the repairs) gives ``no_path`` with the reason, the path kept
    and ``diagnostics.timing_error`` naming the failed rule. With ``replace``, the answer
    starts from the running state at ``replace.at`` and its times are on the running clock
    (:mod:`planner.wire.execution`).
    """
    from planner.motion import run
    from planner.solver import GoalMotion

    inputs = plan_inputs(request, deadline=budget.deadline, max_samples=budget.max_samples)
    solution = run(inputs.problem, GoalMotion(inputs.goal, inputs.prefer, inputs.tolerance))
    return on_running_clock(solution_response(solution, format=request.timing.format), request)
