"""POST /v1/dynamics: actuator torques and the mass matrix of N motions, computed in a
worker."""

from __future__ import annotations

from fastapi import APIRouter, Response

from planner.endpoints import dynamics as jobs
from planner.wire import DynamicsRequest, DynamicsResponse
from planner_api.deps import Deadline, Pool, SettingsDep
from planner_api.routes._common import run_job

__all__ = ["dynamics", "router"]

router = APIRouter(prefix="/v1", tags=["dynamics"])


@router.post("/dynamics", response_model=DynamicsResponse)
async def dynamics(
    body: DynamicsRequest, pool: Pool, deadline: Deadline, settings: SettingsDep
) -> Response:
    """Inverse dynamics of the closed chain: for each of N motions (q, qd, qdd; rad, rad/s,
    rad/s^2) the actuator torques ``tau`` (N m) and the mass matrix ``M(q)`` in actuated
    coordinates, ``tau = M qdd + h(q, qd)``, under ``gravity`` with ``design.inertia`` (or the
    documented defaults). A posture that does not assemble or is parallel-singular is a 422
    naming ``q.<i>``."""
    return await run_job(
        pool, jobs.dynamics, body, deadline, design_defaults=settings.design_defaults
    )
