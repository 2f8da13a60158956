"""The job of ``/v1/dynamics``: actuator torques and mass matrices of N motions."""

from __future__ import annotations

from planner.endpoints import UNBOUNDED, JobBudget
from planner.wire import DynamicsRequest, DynamicsResponse, dynamics_answer

__all__ = ["dynamics"]


def dynamics(request: DynamicsRequest, budget: JobBudget = UNBOUNDED) -> DynamicsResponse:
    """``POST /v1/dynamics``: :func:`planner.dynamics.inverse_dynamics` of the request's
    motions (a singular posture is a 422 naming ``q.<i>``)."""
    return dynamics_answer(request)
