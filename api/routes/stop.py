"""POST /v1/stop: the braking trajectory to rest from a running trajectory's state, computed
in a worker."""

from __future__ import annotations

from fastapi import APIRouter, Response

from planner.endpoints import answer_sample_limit
from planner.endpoints import stop as jobs
from planner.wire.execution import StopRequest, StopResponse
from planner_api.deps import Deadline, Pool, SettingsDep
from planner_api.routes._common import obstacles_within_limit, run_job

__all__ = ["router", "stop"]

router = APIRouter(prefix="/v1", tags=["execution"])


@router.post("/stop", response_model=StopResponse)
async def stop(
    body: StopRequest, pool: Pool, deadline: Deadline, settings: SettingsDep
) -> Response:
    """Bring a running trajectory (``t``, ``q``, ``qd``, ``qdd``, read between samples as a
    controller reads it: quintic per interval) to rest from its state at ``at``: along its own
    path where the limits allow (a time scaling), else by the quickest Ruckig brake, keeping
    ``limits`` and the validity rules of ``margins`` and ``obstacles``. A malformed trajectory
    or an ``at`` outside it is a 422 naming the field; a stop no braking keeps valid is a 200
    with status ``invalid_start``."""
    body = obstacles_within_limit(body, settings)
    samples = answer_sample_limit(settings.max_trajectory_samples, settings.max_response_bytes)
    return await run_job(
        pool,
        jobs.stop,
        body,
        deadline,
        design_defaults=settings.design_defaults,
        max_samples=samples,
    )
