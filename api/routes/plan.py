"""POST /v1/plan and /v1/plan/batch.

The job is :func:`planner.endpoints.plan.plan`, resolved through the ``get_plan_function`` dependency
(tests override it). A finished search is a 200 whatever its status; errors are for invalid
input (422), a full pool (503) or the request's deadline (504).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Request, Response
from fastapi.exceptions import RequestValidationError

from planner.endpoints import JobBudget, answer_sample_limit
from planner.endpoints import plan as jobs
from planner.wire import PlanBatchRequest, PlanBatchResponse, PlanRequest, PlanResponse
from planner_api.deps import (
    ClientWatch,
    Deadline,
    Pool,
    SettingsDep,
    get_deadline,
    get_pool,
)
from planner_api.exceptions import LimitExceededError
from planner_api.pool import WorkerPool
from planner_api.routes._common import (
    check_obstacle_count,
    json_response,
    run_in_rounds,
    run_job,
    run_jobs,
    with_design_defaults,
)
from planner_api.routes.direct import DirectRoute, DirectSpec, answered_directly
from planner_api.routes.scenes import resolve_scene
from planner_api.routes.worker_body import (
    BodyInvalidError,
    BodySpec,
    Limits,
    RouteLimits,
    answer_of_worker_body,
    load_json,
    parsed_in_worker,
    validate_data,
    worker_body,
)

__all__ = [
    "check_batch",
    "check_limits",
    "get_plan_function",
    "plan",
    "plan_batch",
    "plan_job_of",
    "prepare_batch",
    "prepare_plan",
    "router",
]

router = APIRouter(prefix="/v1", tags=["plan"], route_class=DirectRoute)

PlanFunction = Callable[[PlanRequest, JobBudget], PlanResponse]


async def get_plan_function() -> PlanFunction:
    """The job that answers one plan request (a module-level, picklable function)."""
    return jobs.plan


PlanJob = Annotated[PlanFunction, Depends(get_plan_function)]


def check_limits(request: PlanRequest, settings: RouteLimits, loc: tuple[str | int, ...]) -> None:
    """Raise :class:`LimitExceededError` when a request exceeds a size limit of the settings."""
    if request.planner.time_budget_s > settings.request_timeout_s:
        raise LimitExceededError(
            f"planner.time_budget_s must be at most the service's request budget "
            f"{settings.request_timeout_s:g} s, got {request.planner.time_budget_s:g}",
            (*loc, "planner", "time_budget_s"),
        )
    check_obstacle_count(request.obstacles, settings.max_obstacles, (*loc, "obstacles"))


def prepare_plan(body: PlanRequest, limits: RouteLimits) -> PlanRequest:
    """The plan route's own checks (wherever the body is parsed)."""
    check_limits(body, limits, ("body",))
    return body


def plan_job_of(request: Request) -> PlanFunction:
    """The plan job, as the ``get_plan_function`` dependency gives it (tests override it)."""
    override = request.app.dependency_overrides.get(get_plan_function)
    return override() if override is not None else jobs.plan


async def _plan(
    request: Request, body: PlanRequest, pool: WorkerPool, deadline: float, job: PlanFunction
) -> Response:
    """The plan route's work on a parsed body, its dependencies resolved."""
    settings = request.app.state.settings
    body = prepare_plan(body, settings)
    body = await resolve_scene(request, body)
    samples = answer_sample_limit(settings.max_trajectory_samples, settings.max_response_bytes)
    return await run_job(
        pool, job, body, deadline, design_defaults=settings.design_defaults, max_samples=samples
    )


@router.post("/plan", response_model=PlanResponse)
@parsed_in_worker(BodySpec(PlanRequest, prepare_plan, plan_job_of, resolve_scene))
@answered_directly(DirectSpec(PlanRequest))  # the body validated in the worker
async def plan(
    body: PlanRequest,
    pool: Pool,
    deadline: Deadline,
    settings: SettingsDep,
    job: PlanJob,
    request: Request,
) -> Response:
    """Plan (and time) a motion from ``start`` to ``goal`` (in the named ``scene``, if any)."""
    return await _plan(request, body, pool, deadline, job)


def prepare_batch(body: PlanBatchRequest, limits: RouteLimits) -> PlanBatchRequest:
    """The batch route's own checks (wherever the body is parsed): the count, then every
    item's limits as a plan's, each located at its index."""
    if len(body.requests) > limits.max_batch:
        raise LimitExceededError(
            f"at most {limits.max_batch} requests per batch, got {len(body.requests)}",
            ("body", "requests"),
        )
    for i, item in enumerate(body.requests):
        check_limits(item, limits, ("body", "requests", i))
    return body


def check_batch(work: tuple[bytes, Limits]) -> tuple[list[bytes] | None, Any]:
    """In a worker: a large batch body parsed and checked as the route checks it: (each
    request's JSON again, None), or (None, the parsed batch) when a request names a scene
    (the server resolves it)."""
    raw, limits = work
    data = load_json(raw)
    body = prepare_batch(validate_data(PlanBatchRequest, data), limits)
    if any(item.scene is not None for item in body.requests):
        return None, body
    return [json.dumps(item).encode() for item in data["requests"]], None


async def _run_batch(
    request: Request, pool: WorkerPool, job: PlanFunction, body: PlanBatchRequest, deadline: float
) -> Response:
    """A checked batch's scenes resolved, designs completed, plans run in order."""
    settings = request.app.state.settings
    if any(item.scene is not None for item in body.requests):
        body = body.model_copy(
            update={"requests": [await resolve_scene(request, item) for item in body.requests]}
        )
    body = with_design_defaults(body, settings.design_defaults)
    samples = answer_sample_limit(
        settings.max_trajectory_samples, settings.max_response_bytes, len(body.requests)
    )
    results = await run_jobs(pool, job, body.requests, deadline, max_samples=samples)
    return _batch_answer(results)


async def _batch_large(request: Request, raw: bytes) -> Response:
    """A batch body larger than ``PLANNER_INLINE_PARSE_BYTES``: checked in one worker, each
    plan then parsed again in the worker that runs it (never on the event loop)."""
    settings = request.app.state.settings
    pool, deadline = await get_pool(request), await get_deadline(request)
    job = plan_job_of(request)
    async with ClientWatch(request):
        try:
            items, parsed = await pool.run(
                check_batch, (raw, Limits.of(settings)), deadline=deadline
            )
        except BodyInvalidError as exc:
            raise RequestValidationError(exc.items) from None
        if parsed is not None:
            return await _run_batch(request, pool, job, parsed, deadline)
        assert items is not None, "check_batch gives the items when it parsed none"
        samples = answer_sample_limit(
            settings.max_trajectory_samples, settings.max_response_bytes, len(items)
        )
        budget = JobBudget(deadline, samples)
        works = [worker_body(PlanRequest, job, item, settings, budget) for item in items]
        results = await run_in_rounds(pool, answer_of_worker_body, works, deadline)
    return _batch_answer(results)


def _batch_answer(results: list[bytes]) -> Response:
    return json_response(b'{"results":[' + b",".join(results) + b"]}")


@router.post("/plan/batch", response_model=PlanBatchResponse)
@parsed_in_worker(BodySpec(PlanBatchRequest, prepare_batch, plan_job_of, handle=_batch_large))
async def plan_batch(
    body: PlanBatchRequest,
    pool: Pool,
    deadline: Deadline,
    settings: SettingsDep,
    job: PlanJob,
    request: Request,
) -> Response:
    """Many plan requests, spread over the workers, answered in order. A body larger than
    ``PLANNER_INLINE_PARSE_BYTES`` is checked in a worker, and each plan parsed in its own."""
    body = prepare_batch(body, settings)
    return await _run_batch(request, pool, job, body, deadline)
