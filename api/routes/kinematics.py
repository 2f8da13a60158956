"""POST /v1/fk, /v1/ik and /v1/analyze: one posture at a time, computed in the event loop (a
fixed, sub-millisecond cost: :func:`planner_api.routes._common.run_inline`), answered without
FastAPI's dependency solving (:mod:`planner_api.routes.direct`)."""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import Any

from fastapi import APIRouter, Request, Response

from planner.endpoints import Job
from planner.endpoints import kinematics as jobs
from planner.wire import (
    AnalyzeRequest,
    AnalyzeResponse,
    FKRequest,
    FKResponse,
    IKRequest,
    IKResponse,
)
from planner_api.deps import Deadline, SettingsDep, get_deadline
from planner_api.routes._common import run_inline
from planner_api.routes.direct import DirectRoute, DirectSpec, answered_directly

__all__ = ["analyze", "fk", "ik", "router"]

router = APIRouter(prefix="/v1", tags=["kinematics"], route_class=DirectRoute)


def _direct(job: Job) -> Callable[[Request, Any], Awaitable[Response]]:
    """The route of ``job`` without FastAPI's dependency solving."""

    async def answer(request: Request, body: Any) -> Response:
        deadline = await get_deadline(request)
        defaults = request.app.state.settings.design_defaults
        return run_inline(job, body, deadline, design_defaults=defaults)

    return answer


@router.post("/fk", response_model=FKResponse)
@answered_directly(DirectSpec(FKRequest, _direct(jobs.fk)))
async def fk(body: FKRequest, deadline: Deadline, settings: SettingsDep) -> Response:
    """Direct kinematics: the postures of the actuated joints ``q`` (both assembly modes
    unless one is asked; none when q does not close the loop)."""
    return run_inline(jobs.fk, body, deadline, design_defaults=settings.design_defaults)


@router.post("/ik", response_model=IKResponse)
@answered_directly(DirectSpec(IKRequest, _direct(jobs.ik)))
async def ik(body: IKRequest, deadline: Deadline, settings: SettingsDep) -> Response:
    """Inverse kinematics: one posture per working mode reaching ``p``."""
    return run_inline(jobs.ik, body, deadline, design_defaults=settings.design_defaults)


@router.post("/analyze", response_model=AnalyzeResponse)
@answered_directly(DirectSpec(AnalyzeRequest, _direct(jobs.analyze)))
async def analyze(body: AnalyzeRequest, deadline: Deadline, settings: SettingsDep) -> Response:
    """Jacobians A and B, kappa(A), kappa(B), singularity margins and modes of a posture."""
    return run_inline(jobs.analyze, body, deadline, design_defaults=settings.design_defaults)
