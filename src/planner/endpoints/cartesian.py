"""The job of ``/v1/cartesian``: a straight tool path, certified, and its timing."""

from __future__ import annotations

from planner.endpoints import UNBOUNDED, JobBudget
from planner.exceptions import InputError
from planner.wire import (
    CartesianRequest,
    CartesianResponse,
    cartesian_inputs,
    cartesian_response,
    located,
)

__all__ = ["cartesian"]


def cartesian(request: CartesianRequest, budget: JobBudget = UNBOUNDED) -> CartesianResponse:
    """``POST /v1/cartesian``: the request's library objects
    (:func:`planner.wire.cartesian_inputs`), :func:`planner.cartesian.plan.plan_cartesian`
    (the straight path, certified, and its timing), and one response built once
    (:func:`planner.wire.cartesian_response`).

    The answer's samples are bounded by ``budget.max_samples`` (a 422 naming
    ``timing.sample_rate_hz`` beyond it, checked once the trajectory is known).
    ``plan_cartesian`` stops at the request's deadline (``budget.deadline``, checked between
    its chunks of probes, its refinement rounds and in the timing) with
    :class:`planner.exceptions.DeadlineError` (504).
    """
    from planner.cartesian.plan import plan_cartesian

    inputs = cartesian_inputs(request)
    try:
        result = plan_cartesian(
            inputs.design,
            inputs.start,
            inputs.waypoints,
            obstacles=inputs.obstacles,
            margins=inputs.margins,
            limits=inputs.limits,
            deadline=budget.deadline,
            **inputs.options,
        )
    except InputError as exc:  # the sample bound names sample_rate_hz, a field of timing
        where = ("body", "timing") if exc.field == "sample_rate_hz" else ("body",)
        with located(*where):
            raise
    traj = result.trajectory
    if traj is not None and budget.max_samples is not None and len(traj.t) > budget.max_samples:
        rate = request.timing.sample_rate_hz
        with located("body", "timing"):
            raise InputError(
                f"sample_rate_hz = {rate:g} Hz gives {len(traj.t)} samples over the "
                f"trajectory's {traj.duration:.4g} s, more than the limit of "
                f"{budget.max_samples}: lower the rate",
                field="sample_rate_hz",
            )
    return cartesian_response(result, format=request.timing.format)
