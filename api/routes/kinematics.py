"""POST /v1/fk, /v1/ik and /v1/analyze: one posture at a time, computed in the event loop (a
fixed, sub-millisecond cost: :func:`planner_api.routes._common.run_inline`)."""

from __future__ import annotations

from fastapi import APIRouter, Response

from planner.endpoints import kinematics as jobs
from planner.wire import (
    AnalyzeRequest,
    AnalyzeResponse,
    FKRequest,
    FKResponse,
    IKRequest,
    IKResponse,
)
from planner_api.deps import Deadline, SettingsDep
from planner_api.routes._common import run_inline

__all__ = ["analyze", "fk", "ik", "router"]

router = APIRouter(prefix="/v1", tags=["kinematics"])


@router.post("/fk", response_model=FKResponse)
async def fk(body: FKRequest, deadline: Deadline, settings: SettingsDep) -> Response:
    """Direct kinematics: the postures of the actuated joints ``q`` (both assembly modes
    unless one is asked; none when q does not close the loop)."""
    return run_inline(jobs.fk, body, deadline, design_defaults=settings.design_defaults)


@router.post("/ik", response_model=IKResponse)
async def ik(body: IKRequest, deadline: Deadline, settings: SettingsDep) -> Response:
    """Inverse kinematics: one posture per working mode reaching ``p``."""
    return run_inline(jobs.ik, body, deadline, design_defaults=settings.design_defaults)


@router.post("/analyze", response_model=AnalyzeResponse)
async def analyze(body: AnalyzeRequest, deadline: Deadline, settings: SettingsDep) -> Response:
    """Jacobians A and B, kappa(A), kappa(B), singularity margins and modes of a posture."""
    return run_inline(jobs.analyze, body, deadline, design_defaults=settings.design_defaults)
