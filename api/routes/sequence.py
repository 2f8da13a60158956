"""POST /v1/sequence: task sequences, computed in a worker like a plan.

The job is :func:`planner.endpoints.sequence.sequence`. A finished sequence is a 200 whatever
its status (``solved`` only when every leg is; else the status of the first leg that failed,
its index in ``message``); errors are for invalid input (422: no targets, more than
``PLANNER_MAX_SEQUENCE_TARGETS``, a negative blend or one larger than half its shorter leg),
a full pool (503) or the request's deadline (504).
"""

from __future__ import annotations

from fastapi import APIRouter, Request, Response

from planner.endpoints import answer_sample_limit
from planner.endpoints import sequence as jobs
from planner.wire import SequenceRequest, SequenceResponse
from planner_api.deps import Deadline, Pool, SettingsDep
from planner_api.exceptions import LimitExceededError
from planner_api.routes._common import check_obstacle_count, run_job
from planner_api.routes.direct import DirectRoute, DirectSpec, answered_directly
from planner_api.routes.scenes import resolve_scene
from planner_api.routes.worker_body import (
    BodySpec,
    RouteLimits,
    parsed_in_worker,
)

__all__ = ["prepare_sequence", "router", "sequence"]

router = APIRouter(prefix="/v1", tags=["plan"], route_class=DirectRoute)


def prepare_sequence(body: SequenceRequest, limits: RouteLimits) -> SequenceRequest:
    """The sequence route's own checks (wherever the body is parsed): the targets, the search
    budget and the obstacles within the service's limits."""
    if len(body.targets) > limits.max_sequence_targets:
        raise LimitExceededError(
            f"at most {limits.max_sequence_targets} targets per sequence "
            f"(PLANNER_MAX_SEQUENCE_TARGETS), got {len(body.targets)}",
            ("body", "targets"),
        )
    if body.planner.time_budget_s > limits.request_timeout_s:
        raise LimitExceededError(
            f"planner.time_budget_s must be at most the service's request budget "
            f"{limits.request_timeout_s:g} s, got {body.planner.time_budget_s:g}",
            ("body", "planner", "time_budget_s"),
        )
    check_obstacle_count(body.obstacles, limits.max_obstacles, ("body", "obstacles"))
    return body


@router.post("/sequence", response_model=SequenceResponse)
@parsed_in_worker(
    BodySpec(SequenceRequest, prepare_sequence, lambda _: jobs.sequence, resolve_scene)
)
@answered_directly(DirectSpec(SequenceRequest))  # the body validated in the worker
async def sequence(
    body: SequenceRequest, pool: Pool, deadline: Deadline, settings: SettingsDep, request: Request
) -> Response:
    """One trajectory from ``start`` through every target in order (and back with
    ``cycle``): at rest at each ``stop`` target, passing through the others within their
    ``blend``; with ``objective`` "time" the working modes of Cartesian "any" targets are
    chosen for the shortest cycle (in the named ``scene``, if any)."""
    body = prepare_sequence(body, settings)
    body = await resolve_scene(request, body)
    samples = answer_sample_limit(settings.max_trajectory_samples, settings.max_response_bytes)
    return await run_job(
        pool,
        jobs.sequence,
        body,
        deadline,
        design_defaults=settings.design_defaults,
        max_samples=samples,
    )
