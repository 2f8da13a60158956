"""The job of ``/v1/sequence``: a task sequence planned and timed in one trajectory."""

from __future__ import annotations

from dataclasses import replace

from planner.endpoints import UNBOUNDED, JobBudget
from planner.wire import SequenceRequest, SequenceResponse, sequence_inputs, sequence_response

__all__ = ["sequence"]


def sequence(request: SequenceRequest, budget: JobBudget = UNBOUNDED) -> SequenceResponse:
    """``POST /v1/sequence``: convert (:func:`planner.wire.sequence_inputs`, once), solve
    (:func:`planner.solve_sequence`: every leg planned by :func:`planner.solve`, the joined
    path timed by its timing step, re-checked densely; the mode search of
    ``objective="time"``), respond (:func:`planner.wire.sequence_response`, built once).

    A library error is a 422 naming its field (a blend larger than half its shorter leg at
    ``targets.i.blend``); a leg that fails gives the sequence its status, the leg's index in
    ``message``; the request's deadline passing during the timing gives ``timeout``."""
    from planner.sequence import solve_sequence

    inputs = sequence_inputs(request)
    kwargs = inputs.solve_kwargs()
    kwargs["timing"] = replace(inputs.timing, max_samples=budget.max_samples)
    result = solve_sequence(
        inputs.design, inputs.start, inputs.targets, deadline=budget.deadline, **kwargs
    )
    return sequence_response(result, format=request.timing.format)
