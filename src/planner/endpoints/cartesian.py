"""The endpoint of ``/v1/cartesian``: a straight tool path, certified, and its timing."""

from __future__ import annotations

from planner.endpoints import UNBOUNDED, JobBudget
from planner.wire import (
    CartesianRequest,
    CartesianResponse,
    cartesian_inputs,
    cartesian_response,
)

__all__ = ["cartesian"]


def cartesian(request: CartesianRequest, budget: JobBudget = UNBOUNDED) -> CartesianResponse:
    """``POST /v1/cartesian``: convert (:func:`planner.wire.cartesian_inputs`, once), run the
    pipeline (:func:`planner.motion.run` of :class:`planner.cartesian.StraightMotion`: the
    straight path, certified, and its timing), respond (:func:`planner.wire.cartesian_response`,
    built once).

    As for a plan: the answer's samples are bounded by ``budget.max_samples``, checked before
    any sample is computed (a 422 naming ``timing.sample_rate_hz`` beyond it); the request's
    deadline passing (between the chunks of probes, the refinement rounds, or in the timing)
    gives status ``timeout``.
    """
    from planner.cartesian import StraightMotion
    from planner.motion import run

    inputs = cartesian_inputs(request, deadline=budget.deadline, max_samples=budget.max_samples)
    result = run(inputs.problem, StraightMotion(inputs.waypoints, inputs.path_tolerance))
    return cartesian_response(result, format=request.timing.format)
