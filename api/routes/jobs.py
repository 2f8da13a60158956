"""POST /v1/jobs, GET /v1/jobs, GET /v1/jobs/{id}, DELETE /v1/jobs/{id}: long jobs, run in
the background, each the request's tenant's (another tenant's id is a 404).

The kinds and the jobs are :mod:`planner_api.job_store` (rows of the store's ``jobs`` table,
shared by the replicas: what they keep and survive is said there and in
``docs/service.md``); every route waits on the store through its own threads, and answers
503 ``store_unavailable`` when the store cannot answer. A job runs its endpoint's job function through
:func:`planner_api.routes._common.run_job`, as the endpoint does, with the long job's budget
as its deadline. These routes have no client watch: a long job is meant to outlive the
request that submitted it.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from functools import partial
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Request, Response
from fastapi.exceptions import RequestValidationError

from planner.endpoints import Job, JobBudget, answer_sample_limit
from planner.wire import ErrorResponse, JobList, JobRequest, JobStatus
from planner_api.deps import Pool, SettingsDep, Tenant, get_deadline, get_pool, request_tenant
from planner_api.exceptions import PoolNotRunningError, ShuttingDownError
from planner_api.job_store import LONG_JOBS, JobStore, Runner
from planner_api.metrics import record_job
from planner_api.pool import WorkerPool
from planner_api.routes._common import run_job
from planner_api.routes.plan import plan_job_of
from planner_api.routes.scenes import resolve_scene
from planner_api.routes.worker_body import (
    BodyInvalidError,
    BodySpec,
    WorkerBodyRoute,
    parse_body,
    parsed_in_worker,
    run_worker_body,
    unchanged,
    worker_body,
)
from planner_api.settings import Settings

__all__ = [
    "cancel_job",
    "check_job_request",
    "get_job",
    "get_job_store",
    "list_jobs",
    "router",
    "submit_job",
]

router = APIRouter(prefix="/v1", tags=["jobs"], route_class=WorkerBodyRoute)

_NOT_FOUND: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorResponse, "description": "No such job (or it expired)."}
}


def get_job_store(request: Request) -> JobStore:
    """The application's long-job list (created by its lifespan)."""
    store = getattr(request.app.state, "jobs", None)
    if store is None:
        raise PoolNotRunningError("the job list is not running (application not started)")
    return store


Jobs = Annotated[JobStore, Depends(get_job_store)]


def check_job_request(work: tuple[bytes, dict[str, Any]]) -> tuple[str, bytes | None, Any]:
    """In a worker: a large ``POST /v1/jobs`` body parsed and checked as the route checks it
    (:func:`planner_api.routes.worker_body.parse_body`, the kind's validation and limits):
    (its kind, its request as JSON again, or None and the parsed request when it names a
    scene, which the server resolves)."""
    raw, limits = work
    body = parse_body(JobRequest, raw)
    kind = LONG_JOBS[body.kind]
    try:
        request = kind.validate(body.request)
    except RequestValidationError as exc:
        raise BodyInvalidError(
            [{"loc": list(e["loc"]), "msg": e["msg"], "type": e["type"]} for e in exc.errors()]
        ) from None
    kind.check_limits(request, **limits)
    if getattr(request, "scene", None) is not None:
        return body.kind, None, request
    return body.kind, json.dumps(body.request).encode(), None


def _limits(settings: Settings) -> dict[str, Any]:
    return {
        "max_obstacles": settings.max_obstacles,
        "job_timeout_s": settings.job_timeout_s,
        "max_sequence_targets": settings.max_sequence_targets,
    }


async def _submit(http: Request, kind_name: str, make_run: Callable[..., Runner]) -> Response:
    """Register a job of ``kind_name`` for the request's tenant: 202 with its status.
    ``make_run(job, samples)`` gives the job's runner."""
    settings: Settings = http.app.state.settings
    store = get_job_store(http)
    kind = LONG_JOBS[kind_name]
    job = plan_job_of(http) if kind_name == "plan" else kind.job
    # a long job's answer is kept in the store: its samples fit its own bound too
    result_bytes = min(settings.max_response_bytes, store.max_result_bytes)
    samples = (
        answer_sample_limit(settings.max_trajectory_samples, result_bytes)
        if kind.trajectory
        else None
    )
    entry = await store.submit(kind_name, make_run(job, samples), await request_tenant(http))
    return Response(
        store.status_json(entry),
        status_code=202,
        media_type="application/json",
        headers={"Location": f"/v1/jobs/{entry.id}"},
    )


def _refuse_when_stopping(http: Request) -> None:
    pool = getattr(http.app.state, "pool", None)
    if pool is not None and pool.state == "stopping":
        raise ShuttingDownError(
            "the service is shutting down; submit the job to another replica",
            http.app.state.settings.retry_after_s,
        )


async def _submit_large(http: Request, raw: bytes) -> Response:
    """A ``POST /v1/jobs`` body larger than ``PLANNER_INLINE_PARSE_BYTES``: checked in a worker
    now (a 422 as the route gives it), and, when it runs, parsed again in its worker from the
    request's JSON (never on the event loop). One that names a scene comes back parsed, and
    runs as a small one does."""
    _refuse_when_stopping(http)
    settings: Settings = http.app.state.settings
    pool = await get_pool(http)
    try:
        kind_name, inner, parsed = await pool.run(
            check_job_request, (raw, _limits(settings)), deadline=await get_deadline(http)
        )
    except BodyInvalidError as exc:
        raise RequestValidationError(exc.items) from None
    if parsed is not None:
        request = await resolve_scene(http, parsed)
        return await _submit(http, kind_name, partial(_parsed_runner, pool, request, settings))
    assert inner is not None, "check_job_request gives the inner body when it parsed none"
    model = LONG_JOBS[kind_name].model

    def make_run(job: Job, samples: int | None) -> Runner:
        async def run(deadline: float) -> bytes:
            work = worker_body(model, job, inner, settings, JobBudget(deadline, samples))
            _, (content, sample) = await pool.run(run_worker_body, work, deadline=deadline)
            record_job(sample)
            return content

        return run

    return await _submit(http, kind_name, make_run)


def _parsed_runner(
    pool: WorkerPool, request: Any, settings: Settings, job: Job, samples: int | None
) -> Runner:
    async def run(deadline: float) -> bytes:
        answer = await run_job(
            pool,
            job,
            request,
            deadline,
            design_defaults=settings.design_defaults,
            max_samples=samples,
        )
        return bytes(answer.body)

    return run


@router.post("/jobs", status_code=202, response_model=JobStatus)
@parsed_in_worker(BodySpec(JobRequest, unchanged, plan_job_of, handle=_submit_large))
async def submit_job(
    body: JobRequest, pool: Pool, settings: SettingsDep, http: Request
) -> Response:
    """Run an endpoint's request in the background (``kind`` names the endpoint): 202 with
    the job's ``id`` and ``status``, then poll ``GET /v1/jobs/{id}``. The request is
    validated now (a 422 under ``body.request``); errors found while it runs make the job
    ``failed`` with the error answer the endpoint would have given. A body larger than
    ``PLANNER_INLINE_PARSE_BYTES`` is checked, and later run, in a worker."""
    _refuse_when_stopping(http)
    kind = LONG_JOBS[body.kind]
    request = kind.validate(body.request)
    kind.check_limits(request, **_limits(settings))
    request = await resolve_scene(http, request)  # a named scene's obstacles, as the endpoint
    return await _submit(http, body.kind, partial(_parsed_runner, pool, request, settings))


@router.get("/jobs", response_model=JobList)
async def list_jobs(store: Jobs, tenant: Tenant) -> JobList:
    """The request's tenant's jobs still kept, oldest first: id, kind, status and times (a
    job's result: ``GET /v1/jobs/{id}``)."""
    return JobList([store.summary(e) for e in await store.list(tenant)])


@router.get("/jobs/{job_id}", response_model=JobStatus, responses=_NOT_FOUND)
async def get_job(job_id: str, store: Jobs, tenant: Tenant) -> Response:
    """A job's status; with status ``done`` its ``result`` (the endpoint's response body),
    with ``failed`` its ``error``. 404 once it is no longer kept, or when it is another
    tenant's."""
    entry = await store.get(job_id, tenant)
    return Response(store.status_json(entry), media_type="application/json")


@router.delete("/jobs/{job_id}", response_model=JobStatus, responses=_NOT_FOUND)
async def cancel_job(job_id: str, store: Jobs, tenant: Tenant) -> Response:
    """Cancel a queued or running job: its status is ``cancelled`` at once, and its worker is
    stopped (and replaced) by the replica that runs it, at once when it is this one, within
    a fraction of a second otherwise. A finished job is answered as it is; another tenant's
    is a 404."""
    entry = await store.cancel(job_id, tenant)
    return Response(store.status_json(entry), media_type="application/json")
