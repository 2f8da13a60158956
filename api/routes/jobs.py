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

from typing import Annotated

from fastapi import APIRouter, Depends, Request, Response

from planner.wire import ErrorResponse, JobList, JobRequest, JobStatus
from planner_api.deps import Pool, SettingsDep, Tenant
from planner_api.exceptions import PoolNotRunningError, ShuttingDownError
from planner_api.job_store import LONG_JOBS, JobStore
from planner_api.jobs import answer_sample_limit
from planner_api.routes._common import run_job
from planner_api.routes.plan import PlanJob
from planner_api.routes.scenes import resolve_scene

__all__ = ["cancel_job", "get_job", "get_job_store", "list_jobs", "router", "submit_job"]

router = APIRouter(prefix="/v1", tags=["jobs"])

_NOT_FOUND = {404: {"model": ErrorResponse, "description": "No such job (or it expired)."}}


def get_job_store(request: Request) -> JobStore:
    """The application's long-job list (created by its lifespan)."""
    store = getattr(request.app.state, "jobs", None)
    if store is None:
        raise PoolNotRunningError("the job list is not running (application not started)")
    return store


Jobs = Annotated[JobStore, Depends(get_job_store)]


@router.post("/jobs", status_code=202, response_model=JobStatus)
async def submit_job(
    body: JobRequest,
    pool: Pool,
    settings: SettingsDep,
    store: Jobs,
    plan_job: PlanJob,
    http: Request,
    tenant: Tenant,
) -> Response:
    """Run an endpoint's request in the background (``kind`` names the endpoint): 202 with
    the job's ``id`` and ``status``, then poll ``GET /v1/jobs/{id}``. The request is
    validated now (a 422 under ``body.request``); errors found while it runs make the job
    ``failed`` with the error answer the endpoint would have given."""
    if pool.state == "stopping":
        raise ShuttingDownError(
            "the service is shutting down; submit the job to another replica",
            settings.retry_after_s,
        )
    kind = LONG_JOBS[body.kind]
    request = kind.validate(body.request)
    kind.check_limits(
        request,
        max_obstacles=settings.max_obstacles,
        job_timeout_s=settings.job_timeout_s,
        max_sequence_targets=settings.max_sequence_targets,
    )
    request = await resolve_scene(http, request)  # a named scene's obstacles, as the endpoint
    job = plan_job if body.kind == "plan" else kind.job
    # a long job's answer is kept in the store: its samples fit its own bound too
    result_bytes = min(settings.max_response_bytes, store.max_result_bytes)
    samples = (
        answer_sample_limit(settings.max_trajectory_samples, result_bytes)
        if kind.trajectory
        else None
    )
    defaults = settings.design_defaults

    async def run(deadline: float) -> bytes:
        answer = await run_job(
            pool, job, request, deadline, design_defaults=defaults, max_samples=samples
        )
        return bytes(answer.body)

    entry = await store.submit(body.kind, run, tenant)
    return Response(
        store.status_json(entry),
        status_code=202,
        media_type="application/json",
        headers={"Location": f"/v1/jobs/{entry.id}"},
    )


@router.get("/jobs", response_model=JobList)
async def list_jobs(store: Jobs, tenant: Tenant) -> JobList:
    """The request's tenant's jobs still kept, oldest first: id, kind, status and times (a
    job's result: ``GET /v1/jobs/{id}``)."""
    return JobList(jobs=[store.summary(e) for e in await store.list(tenant)])


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
