"""POST /v1/timing: time-parameterise a client-supplied joint path, computed in a worker."""

from __future__ import annotations

from fastapi import APIRouter, Response

from planner.endpoints import answer_sample_limit
from planner.endpoints import timing as jobs
from planner.wire import TimingRequest, TimingResponse
from planner_api.deps import Deadline, Pool, SettingsDep
from planner_api.routes._common import obstacles_within_limit, run_job
from planner_api.routes.direct import DirectRoute, DirectSpec, answered_directly
from planner_api.routes.worker_body import (
    BodySpec,
    parsed_in_worker,
)

__all__ = ["router", "timing"]

router = APIRouter(prefix="/v1", tags=["timing"], route_class=DirectRoute)


@router.post("/timing", response_model=TimingResponse)
@parsed_in_worker(BodySpec(TimingRequest, obstacles_within_limit, lambda _: jobs.timing))
@answered_directly(DirectSpec(TimingRequest))  # the body validated in the worker
async def timing(
    body: TimingRequest, pool: Pool, deadline: Deadline, settings: SettingsDep
) -> Response:
    """Turn a joint path (N x 3 waypoints, rad) into a trajectory from rest to rest with
    toppra or ruckig under ``limits``, checked densely against the joint limits, the assembly
    mode and (with ``margins`` or ``obstacles``) the planner's validity rules. A waypoint that
    breaks a joint limit or does not assemble is a 422 naming it; a path that breaks another
    rule, or cannot be timed, is a 200 with a ``status`` (``invalid_path``, ``infeasible``)."""
    body = obstacles_within_limit(body, settings)
    samples = answer_sample_limit(settings.max_trajectory_samples, settings.max_response_bytes)
    return await run_job(
        pool,
        jobs.timing,
        body,
        deadline,
        design_defaults=settings.design_defaults,
        max_samples=samples,
    )
