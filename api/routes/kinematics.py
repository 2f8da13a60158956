"""POST /v1/fk, /v1/ik and /v1/analyze: one posture at a time, computed in a worker."""

from __future__ import annotations

from fastapi import APIRouter

from api import compute
from api.deps import Deadline, Pool
from planner.schemas import (
    AnalyzeRequest,
    AnalyzeResponse,
    FKRequest,
    FKResponse,
    IKRequest,
    IKResponse,
)

router = APIRouter(prefix="/v1", tags=["kinematics"])


@router.post("/fk", response_model=FKResponse)
async def fk(body: FKRequest, pool: Pool, deadline: Deadline) -> FKResponse:
    """Direct kinematics: the postures of the actuated joints ``q`` (both assembly modes
    unless one is asked; none when q does not close the loop)."""
    return await pool.run(compute.fk, body, deadline=deadline)


@router.post("/ik", response_model=IKResponse)
async def ik(body: IKRequest, pool: Pool, deadline: Deadline) -> IKResponse:
    """Inverse kinematics: one posture per working mode reaching ``p``."""
    return await pool.run(compute.ik, body, deadline=deadline)


@router.post("/analyze", response_model=AnalyzeResponse)
async def analyze(body: AnalyzeRequest, pool: Pool, deadline: Deadline) -> AnalyzeResponse:
    """Jacobians A and B, kappa(A), kappa(B), singularity margins and modes of a posture."""
    return await pool.run(compute.analyze, body, deadline=deadline)
