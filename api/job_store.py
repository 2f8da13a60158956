"""Long jobs (``POST /v1/jobs``): the kinds a long job can run, and the jobs themselves.

A long job is one endpoint's request run in the background through the worker pool, with
its own time budget (``PLANNER_JOB_TIMEOUT_S``, from when it starts) instead of the request's.
At most ``PLANNER_JOBS_RUNNING`` run at once in each replica (the others wait, ``queued``), so
long jobs leave workers to the interactive requests. Its status is polled by id; its
``result`` is the endpoint's response body, its ``error`` the error answer the endpoint would
have given.

Where the jobs live, and what they survive: every job is a row of the ``jobs`` table in the
scene store's database (:mod:`planner_api.job_table`: the SQLite file, or the PostgreSQL
database that replicas share), written through the store's own threads
(:mod:`planner_api.store_access`; a store that cannot answer is a 503 ``store_unavailable``
for every job route, a submit included). The replica that accepted a job runs it (its task
and its worker are in that process); any replica answers its status, lists it and cancels
it: a ``DELETE`` through another replica marks the row ``cancelled``, which the running
replica reads within :data:`CANCEL_POLL_S` and kills the job's worker. A finished job (its
result included) survives restarts until its time to live. A job that was queued or running
in a replica that stopped is answered ``failed``, error type ``lost_on_restart``: at once
when the replica stopped on its own (SIGTERM, a deploy), within
:data:`planner_api.job_table.STALE_S` of its last heartbeat when it died.

Bounds, over the table (every replica's jobs): at most ``PLANNER_MAX_JOBS`` jobs are kept (a
new one evicts the oldest finished job; when every kept job is unfinished, a new one is
refused, 503 ``too_many_jobs``), a tenant may have ``PLANNER_JOBS_PER_TENANT`` unfinished
jobs (one more: 429 ``too_many_jobs``), a finished job is kept ``PLANNER_JOB_TTL_S``
seconds, and the results take at most ``PLANNER_JOBS_MAX_MB`` in all (a new result evicts the
oldest finished jobs until it fits; a result over ``PLANNER_JOB_RESULT_MAX_MB`` fails its
job, 422 ``result_too_large``). Past that, its id answers 404 naming these bounds. A job
belongs to the tenant that submitted it (:mod:`planner_api.tenants`): for every other tenant
its id answers the same 404 as an id never given (no existence leak), and a listing shows
each tenant its own jobs only.

Not to be confused with :mod:`planner.endpoints`, the package of the job *functions* that every
endpoint runs in a worker; this module's kinds name them.
"""

from __future__ import annotations

import asyncio
import contextvars
import json
import logging
import time
import uuid
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, ValidationError

from planner.endpoints import Job
from planner.endpoints import cartesian as cartesian_jobs
from planner.endpoints import design as design_jobs
from planner.endpoints import plan as plan_jobs
from planner.endpoints import sequence as sequence_jobs
from planner.endpoints import timing as timing_jobs
from planner.wire import (
    CartesianRequest,
    DesignCheckRequest,
    DesignOptimizeRequest,
    JobError,
    JobStatus,
    JobSummary,
    PlanRequest,
    RegionsRequest,
    SequenceRequest,
    TimingRequest,
)
from planner_api.errors import error_answer
from planner_api.exceptions import (
    JobNotFoundError,
    LimitExceededError,
    PoolSaturatedError,
    ResultTooLargeError,
    ShuttingDownError,
    StoreUnavailableError,
)
from planner_api.job_table import HEARTBEAT_S, JobRow, JobTable
from planner_api.pool import CLIENT_GONE
from planner_api.store_access import StoreAccess
from planner_api.tenants import DEFAULT_TENANT

__all__ = ["CANCEL_POLL_S", "LONG_JOBS", "JobStore", "LongJobKind"]

logger = logging.getLogger(__name__)

_LOC = ("body", "request")
#: Seconds between two tries of a long job to enter a saturated worker pool.
SATURATED_RETRY_S = 0.05
#: Seconds between two reads of whether this replica's jobs were cancelled elsewhere.
CANCEL_POLL_S = 0.25
#: Tries of writing a job's end before it is left to the heartbeat.
_END_TRIES = 4
#: Seconds the stop waits for the cancelled jobs' tasks (each kills its worker at once).
_CLOSE_WAIT_S = 5.0


@dataclass(frozen=True, slots=True)
class LongJobKind:
    """What a kind runs: the endpoint's request model, its job function, whether its answer
    carries a trajectory (bounded samples) and whether its request has obstacles."""

    model: type[BaseModel]
    job: Job
    trajectory: bool = False
    obstacles: bool = False

    def validate(self, request: dict[str, Any]) -> Any:
        """The request as the endpoint validates it; a 422 located under body.request."""
        try:
            return self.model.model_validate(request)
        except ValidationError as exc:
            raise RequestValidationError(
                [{**e, "loc": (*_LOC, *e["loc"])} for e in exc.errors(include_url=False)]
            ) from exc

    def check_limits(
        self,
        request: Any,
        *,
        max_obstacles: int,
        job_timeout_s: float,
        max_sequence_targets: int,
    ) -> None:
        """The endpoint's size limits (:class:`LimitExceededError`, 422 at the field); a
        plan's or a sequence's search budget may use the long job's budget instead of the
        request's."""
        if self.obstacles and len(request.obstacles) > max_obstacles:
            raise LimitExceededError(
                f"at most {max_obstacles} obstacles per request, got {len(request.obstacles)}",
                (*_LOC, "obstacles"),
            )
        if isinstance(request, SequenceRequest) and len(request.targets) > max_sequence_targets:
            raise LimitExceededError(
                f"at most {max_sequence_targets} targets per sequence "
                f"(PLANNER_MAX_SEQUENCE_TARGETS), got {len(request.targets)}",
                (*_LOC, "targets"),
            )
        searches = isinstance(request, PlanRequest | SequenceRequest)
        if searches and request.planner.time_budget_s > job_timeout_s:
            raise LimitExceededError(
                f"planner.time_budget_s must be at most the long job's budget "
                f"{job_timeout_s:g} s (PLANNER_JOB_TIMEOUT_S), got "
                f"{request.planner.time_budget_s:g}",
                (*_LOC, "planner", "time_budget_s"),
            )


#: The kinds of ``POST /v1/jobs`` (:data:`planner.wire.JOB_KINDS`), each an endpoint's job.
LONG_JOBS: dict[str, LongJobKind] = {
    "plan": LongJobKind(PlanRequest, plan_jobs.plan, trajectory=True, obstacles=True),
    "sequence": LongJobKind(
        SequenceRequest, sequence_jobs.sequence, trajectory=True, obstacles=True
    ),
    "cartesian": LongJobKind(
        CartesianRequest, cartesian_jobs.cartesian, trajectory=True, obstacles=True
    ),
    "timing": LongJobKind(TimingRequest, timing_jobs.timing, trajectory=True, obstacles=True),
    "design_check": LongJobKind(DesignCheckRequest, design_jobs.design_check),
    "design_optimize": LongJobKind(DesignOptimizeRequest, design_jobs.optimize_design),
    "regions": LongJobKind(RegionsRequest, design_jobs.regions),
}

#: Runs a job by its deadline (a :func:`time.monotonic` value): the answer's JSON bytes.
Runner = Callable[[float], Awaitable[bytes]]


class JobStore:
    """The long jobs of the service: their rows in the store's ``jobs`` table (every
    replica's, :mod:`planner_api.job_table`) and the tasks this replica runs (see the module
    docstring for what it keeps).

    Parameters
    ----------
    access : StoreAccess
        The store's threads (:mod:`planner_api.store_access`): every call goes through them.
    max_jobs : int
        Jobs kept at once in the table, finished or not, over every replica.
    per_tenant : int
        Unfinished jobs one tenant may have at once (``PLANNER_JOBS_PER_TENANT``).
    ttl_s : float
        How long a finished job is kept, s.
    running : int
        Jobs this replica runs at once; the others are ``queued``.
    timeout_s : float
        Time budget of one job from when it starts, s.
    max_result_bytes : int
        The largest result of one job (``PLANNER_JOB_RESULT_MAX_MB``); a larger one fails it.
    max_total_bytes : int
        The results kept at once in the table (``PLANNER_JOBS_MAX_MB``): the oldest finished
        jobs are evicted to make room for a new result.
    poll_s : float
        How often this replica reads whether its jobs were cancelled elsewhere, s.
    """

    def __init__(
        self,
        access: StoreAccess,
        *,
        max_jobs: int,
        ttl_s: float,
        running: int,
        timeout_s: float,
        per_tenant: int | None = None,
        max_result_bytes: int = 32 * 2**20,
        max_total_bytes: int = 512 * 2**20,
        poll_s: float = CANCEL_POLL_S,
    ) -> None:
        if not 0 < max_result_bytes <= max_total_bytes:
            raise ValueError("max_result_bytes must be > 0 and at most max_total_bytes")
        self.access = access
        self.max_jobs = max_jobs
        self.per_tenant = per_tenant if per_tenant is not None else max(1, max_jobs // 2)
        self.ttl_s = ttl_s
        self.timeout_s = timeout_s
        self.max_result_bytes = max_result_bytes
        self.max_total_bytes = max_total_bytes
        self.poll_s = poll_s
        #: This replica's id in the rows it owns (random at each start).
        self.replica = uuid.uuid4().hex
        self._slots = asyncio.Semaphore(running)
        self._tasks: dict[str, asyncio.Task[None]] = {}  # the jobs this replica runs
        self._watcher: asyncio.Task[None] | None = None

    def _not_found(self, job_id: str) -> JobNotFoundError:
        return JobNotFoundError(
            f"no job {job_id!r} here: it never existed, or it finished more than "
            f"{self.ttl_s:g} s ago (PLANNER_JOB_TTL_S), or it was evicted (at most "
            f"{self.max_jobs} jobs are kept, PLANNER_MAX_JOBS, and their results take at most "
            f"{self.max_total_bytes / 2**20:g} MB, PLANNER_JOBS_MAX_MB)"
        )

    async def submit(self, kind: str, run: Runner, tenant: str = DEFAULT_TENANT) -> JobRow:
        """Store a job of ``kind`` for ``tenant`` and start it here (queued until a slot is
        free). 429 when the tenant has ``per_tenant`` unfinished jobs, 503 when the table is
        full of unfinished jobs or the store cannot answer (nothing is started then)."""
        row = JobRow(
            id=uuid.uuid4().hex, tenant=tenant, kind=kind, status="queued", submitted_at=time.time()
        )
        retry = max(1, round(min(self.timeout_s, 60.0)))
        await self.access.jobs(
            lambda t: t.insert(
                row,
                self.replica,
                max_jobs=self.max_jobs,
                per_tenant=self.per_tenant,
                retry_after_s=retry,
            ),
            write=True,
        )
        context = contextvars.copy_context()
        context.run(CLIENT_GONE.set, None)  # the submitting request's client may leave
        loop = asyncio.get_running_loop()
        self._tasks[row.id] = loop.create_task(self._run(row, run), context=context)
        if self._watcher is None or self._watcher.done():
            self._watcher = loop.create_task(self._watch())
        return row

    async def _enter(self, run: Runner) -> asyncio.Future[bytes]:
        """The job's run, once the worker pool took it: while every worker is busy and the
        pool's queue is full (interactive requests), the job waits, queued, and tries again
        instead of failing with their 503. A saturated pool refuses at once (before its first
        wait), so one step of the run tells."""
        while True:
            attempt = asyncio.ensure_future(run(time.monotonic() + self.timeout_s))
            await asyncio.sleep(0)
            if attempt.done() and not attempt.cancelled():
                exc = attempt.exception()
                if isinstance(exc, PoolSaturatedError) and not isinstance(exc, ShuttingDownError):
                    await asyncio.sleep(SATURATED_RETRY_S)
                    continue
            return attempt

    async def _run(self, row: JobRow, run: Runner) -> None:
        try:
            async with self._slots:
                attempt = await self._enter(run)
                try:
                    if not await self.access.jobs(lambda t: t.start(row.id), write=True):
                        attempt.cancel()  # cancelled (or lost) while it waited
                        return
                    content = await attempt
                except BaseException:
                    attempt.cancel()  # kills its worker
                    raise
            if len(content) > self.max_result_bytes:
                raise ResultTooLargeError(
                    f"the job's result is {len(content) / 2**20:.1f} MB, more than "
                    f"PLANNER_JOB_RESULT_MAX_MB = {self.max_result_bytes / 2**20:g} MB; ask "
                    "for less (a lower timing.sample_rate_hz, a coarser grid) or run it as a "
                    "request",
                    _LOC,
                )
            await asyncio.shield(self._end(row.id, "done", result=content))
        except asyncio.CancelledError:
            pass  # cancelled, lost or stopping: its row says so already (not re-raised)
        except Exception as exc:
            answer = await error_answer(exc)
            detail = json.loads(bytes(answer.body))["detail"]
            error = JobError(status_code=answer.status_code, detail=detail)
            await asyncio.shield(self._end(row.id, "failed", error=error))
        finally:
            self._tasks.pop(row.id, None)

    async def _end(self, job_id: str, status: str, **outcome: Any) -> None:
        """Write the job's end, tried a few times: a store that does not answer leaves the
        row unfinished, lost once this replica's heartbeat for it stops."""
        for attempt in range(_END_TRIES):
            try:
                await self.access.jobs(
                    lambda t: t.finish(
                        job_id, status, max_total_bytes=self.max_total_bytes, **outcome
                    ),
                    write=True,
                )
                return
            except StoreUnavailableError as exc:
                logger.warning("job %s: its end not stored (try %d): %s", job_id, attempt + 1, exc)
                await asyncio.sleep(self.poll_s * 2**attempt)
        logger.error("job %s: its end (%s) could not be stored", job_id, status)

    async def _watch(self) -> None:
        """While this replica runs jobs: every ``poll_s`` read which of them ended elsewhere
        (cancelled through another replica, failed as lost) and cancel their tasks; every
        :data:`HEARTBEAT_S` refresh their heartbeat."""
        beat = time.monotonic()
        while True:
            await asyncio.sleep(self.poll_s)
            if not self._tasks:
                beat = time.monotonic()  # a new job's row carries its first heartbeat
                continue
            ids = list(self._tasks)
            try:
                # ids bound now (a lambda would close over the loop's variable)
                for job_id in await self.access.jobs(partial(JobTable.ended, job_ids=ids)):
                    task = self._tasks.get(job_id)
                    if task is not None:
                        task.cancel()
                if time.monotonic() - beat >= HEARTBEAT_S:
                    await self.access.jobs(lambda t: t.heartbeat(self.replica), write=True)
                    beat = time.monotonic()
            except StoreUnavailableError as exc:
                logger.warning("long jobs: the store did not answer the watch: %s", exc)
            except Exception:
                logger.exception("long jobs: the watch failed; trying again")

    async def get(self, job_id: str, tenant: str = DEFAULT_TENANT) -> JobRow:
        """The job ``job_id`` of ``tenant``; :class:`JobNotFoundError` (404) when it is not
        kept, or is another tenant's (the same answer: module docstring)."""
        row = await self.access.jobs(lambda t: t.get(tenant, job_id))
        if row is None:
            raise self._not_found(job_id)
        return row

    async def list(self, tenant: str = DEFAULT_TENANT) -> list[JobRow]:
        """The jobs of ``tenant`` still kept, in submission order."""
        return await self.access.jobs(lambda t: t.list(tenant))

    async def cancel(self, job_id: str, tenant: str = DEFAULT_TENANT) -> JobRow:
        """Cancel a queued or running job of ``tenant``: its row says ``cancelled`` from now
        on, and the replica running it kills its worker (at once when it is this one, within
        ``poll_s`` otherwise). A finished job is left as it is; another tenant's: 404."""
        row = await self.access.jobs(lambda t: t.cancel(tenant, job_id), write=True)
        if row is None:
            raise self._not_found(job_id)
        task = self._tasks.get(job_id)
        if task is not None and row.status == "cancelled":
            task.cancel()
        return row

    async def close(self) -> None:
        """This replica is stopping: its unfinished jobs are failed as lost
        (``lost_on_restart``) in the table, then their tasks cancelled (their workers
        killed) before the pool stops, which would otherwise wait for them."""
        if self._watcher is not None:
            self._watcher.cancel()
        if self._tasks:
            try:
                await self.access.jobs(lambda t: t.lose_owned(self.replica), write=True)
            except Exception as exc:  # the rows go lost by their heartbeat instead
                logger.warning("long jobs: not marked lost at stop: %s", exc)
        tasks = list(self._tasks.values())
        for task in tasks:
            task.cancel()
        if tasks:  # let the cancels reach the pool (their workers killed) before it stops
            await asyncio.wait(tasks, timeout=_CLOSE_WAIT_S)

    def summary(self, row: JobRow) -> JobSummary:
        """The job as a line of ``GET /v1/jobs``."""
        return JobSummary(
            id=row.id,
            kind=row.kind,
            status=row.status,
            created=row.submitted_at,
            finished=row.finished_at,
            submitted_at=row.submitted_at,
            started_at=row.started_at,
            finished_at=row.finished_at,
            expires_at=row.expires_at,
        )

    def status_json(self, row: JobRow) -> bytes:
        """The job as :class:`planner.wire.JobStatus` JSON, its result spliced in as the
        endpoint's bytes (not parsed and written again)."""
        status = JobStatus(**self.summary(row).model_dump(), error=row.error).model_dump_json(
            exclude={"result"}
        )
        result = row.result if row.status == "done" and row.result is not None else b"null"
        return status[:-1].encode() + b',"result":' + result + b"}"
