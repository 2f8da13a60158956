"""The endpoint of ``/v1/sequence``: a task sequence planned and timed in one trajectory."""

from __future__ import annotations

from planner.endpoints import UNBOUNDED, JobBudget
from planner.wire import SequenceRequest, SequenceResponse, sequence_inputs, sequence_response
from planner.wire.execution import on_running_clock

__all__ = ["sequence"]


def sequence(request: SequenceRequest, budget: JobBudget = UNBOUNDED) -> SequenceResponse:
    """``POST /v1/sequence``: convert (:func:`planner.wire.sequence_inputs`, once), solve
    (:func:`planner.sequence.plan_sequence`: the legs and the joined path through the motion
    pipeline, timed once and re-checked densely; the mode search of ``objective="time"``),
    respond (:func:`planner.wire.sequence_response`, built once).

    A library error is a 422 naming its field (a blend larger than half its shorter leg at
    ``targets.i.blend``); a leg that fails gives the sequence its status, the leg's index in
    ``message``; the request's deadline passing gives ``timeout``. With ``replace``: from the
    running state at ``replace.at``, times on the running clock (:mod:`planner.wire.execution`)."""
    from planner.sequence import plan_sequence

    inputs = sequence_inputs(request, deadline=budget.deadline, max_samples=budget.max_samples)
    result = plan_sequence(
        inputs.problem, inputs.targets, cycle=inputs.cycle, objective=inputs.objective
    )
    return on_running_clock(sequence_response(result, format=request.timing.format), request)
