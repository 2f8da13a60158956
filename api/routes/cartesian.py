"""POST /v1/cartesian: straight tool paths, computed in a worker like a plan.

The job is :func:`planner.endpoints.cartesian.cartesian`. A finished path is a 200 whatever its
status (``solved`` exactly when ``fraction`` = 1); errors are for invalid input (422), a full
pool (503) or the request's deadline (504).
"""

from __future__ import annotations

from fastapi import APIRouter, Request, Response

from planner.endpoints import answer_sample_limit
from planner.endpoints import cartesian as jobs
from planner.wire import CartesianRequest, CartesianResponse
from planner_api.deps import Deadline, Pool, SettingsDep
from planner_api.routes._common import obstacles_within_limit, run_job
from planner_api.routes.direct import DirectRoute, DirectSpec, answered_directly
from planner_api.routes.scenes import resolve_scene
from planner_api.routes.worker_body import (
    BodySpec,
    parsed_in_worker,
)

__all__ = ["cartesian", "router"]

router = APIRouter(prefix="/v1", tags=["plan"], route_class=DirectRoute)


@router.post("/cartesian", response_model=CartesianResponse)
@parsed_in_worker(
    BodySpec(CartesianRequest, obstacles_within_limit, lambda _: jobs.cartesian, resolve_scene)
)
@answered_directly(DirectSpec(CartesianRequest))  # the body validated in the worker
async def cartesian(
    body: CartesianRequest, pool: Pool, deadline: Deadline, settings: SettingsDep, request: Request
) -> Response:
    """Move P on straight segments from the start's P through ``waypoints`` in the start's
    working and assembly mode, within ``path_tolerance`` of the polyline, under every rule of
    a plan; where a rule would break, stop at the last valid point (``no_path``, ``fraction``
    < 1, ``message`` naming the rule, the measured value and the point)."""
    body = obstacles_within_limit(body, settings)
    body = await resolve_scene(request, body)
    samples = answer_sample_limit(settings.max_trajectory_samples, settings.max_response_bytes)
    return await run_job(
        pool,
        jobs.cartesian,
        body,
        deadline,
        design_defaults=settings.design_defaults,
        max_samples=samples,
    )
