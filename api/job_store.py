"""Long jobs (``POST /v1/jobs``): the kinds a long job can run and the in-memory list of jobs.

A long job is one endpoint's request run in the background through the worker pool, with
its own time budget (``PLANNER_JOB_TIMEOUT_S``, from when it starts) instead of the request's.
At most ``PLANNER_JOBS_RUNNING`` run at once (the others wait, ``queued``), so long jobs
leave workers to the interactive requests. Its status is polled by id; its ``result`` is the
endpoint's response body, its ``error`` the error answer the endpoint would have given.

What the list survives, exactly: it lives in the memory of one service process. It does not
survive a restart of that process (a crash, a deploy, SIGTERM), and it is not shared between
replicas: a poll must reach the replica that accepted the job (sticky routing, or one
replica). A finished job is kept ``PLANNER_JOB_TTL_S`` seconds; at most ``PLANNER_MAX_JOBS``
jobs are kept (a new one evicts the oldest finished job; when every kept job is unfinished,
a new one is refused, 503), and their results take at most ``PLANNER_JOBS_MAX_MB`` in all (a
new result evicts the oldest finished jobs until it fits; a result over
``PLANNER_JOB_RESULT_MAX_MB`` fails its job, 422 ``result_too_large``). Past that, its id
answers 404 naming these bounds. A job belongs
to the tenant that submitted it (:mod:`planner_api.tenants`): for every other tenant its id
answers the same 404 as an id never given (no existence leak), and a listing shows each
tenant its own jobs only. The bounds are the process's, shared by the tenants. A cancelled
job (``DELETE``) has its worker killed at once (:meth:`planner_api.workers.WorkerPool.cancel`)
and replaced, warm, in the background.

Not to be confused with :mod:`planner_api.jobs`, the package of the job *functions* that every
endpoint runs in a worker; this module's kinds name them.
"""

from __future__ import annotations

import asyncio
import contextvars
import json
import time
import uuid
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any

from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, ValidationError

from planner.wire import (
    CartesianRequest,
    DesignCheckRequest,
    DesignOptimizeRequest,
    JobError,
    JobState,
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
    TooManyJobsError,
)
from planner_api.jobs import Job
from planner_api.jobs import cartesian as cartesian_jobs
from planner_api.jobs import design as design_jobs
from planner_api.jobs import plan as plan_jobs
from planner_api.jobs import sequence as sequence_jobs
from planner_api.jobs import timing as timing_jobs
from planner_api.tenants import DEFAULT_TENANT
from planner_api.workers import CLIENT_GONE

__all__ = ["LONG_JOBS", "JobStore", "LongJobKind"]

_LOC = ("body", "request")
#: Seconds between two tries of a long job to enter a saturated worker pool.
SATURATED_RETRY_S = 0.05


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


@dataclass(eq=False)
class _Entry:
    id: str
    kind: str
    tenant: str = DEFAULT_TENANT
    status: JobState = "queued"
    submitted_at: float = field(default_factory=time.time)
    started_at: float | None = None
    finished_at: float | None = None
    expires: float | None = None  # monotonic: when a finished job is forgotten
    result: bytes | None = None
    error: JobError | None = None
    task: asyncio.Task[None] | None = field(default=None, repr=False)

    @property
    def finished(self) -> bool:
        return self.status in ("done", "failed", "cancelled")


class JobStore:
    """The long jobs of one service process (see the module docstring for what it keeps).

    Parameters
    ----------
    max_jobs : int
        Jobs kept at once, finished or not.
    ttl_s : float
        How long a finished job is kept, s.
    running : int
        Jobs running at once; the others are ``queued``.
    timeout_s : float
        Time budget of one job from when it starts, s.
    max_result_bytes : int
        The largest result of one job (``PLANNER_JOB_RESULT_MAX_MB``); a larger one fails it.
    max_total_bytes : int
        The results kept at once, in all (``PLANNER_JOBS_MAX_MB``): the oldest finished jobs
        are evicted to make room for a new result.
    """

    def __init__(
        self,
        *,
        max_jobs: int,
        ttl_s: float,
        running: int,
        timeout_s: float,
        max_result_bytes: int = 32 * 2**20,
        max_total_bytes: int = 512 * 2**20,
    ) -> None:
        if not 0 < max_result_bytes <= max_total_bytes:
            raise ValueError("max_result_bytes must be > 0 and at most max_total_bytes")
        self.max_jobs = max_jobs
        self.ttl_s = ttl_s
        self.timeout_s = timeout_s
        self.max_result_bytes = max_result_bytes
        self.max_total_bytes = max_total_bytes
        #: Bytes of the results kept now.
        self.held_bytes = 0
        self._slots = asyncio.Semaphore(running)
        self._jobs: dict[str, _Entry] = {}  # in submission order

    def _drop(self, key: str) -> None:
        """Forget a job, and the bytes of its result."""
        entry = self._jobs.pop(key)
        if entry.result is not None:
            self.held_bytes -= len(entry.result)

    def _forget_expired(self) -> None:
        now = time.monotonic()
        for key in [k for k, e in self._jobs.items() if e.expires is not None and e.expires <= now]:
            self._drop(key)

    def _keep(self, entry: _Entry, content: bytes) -> None:
        """Keep ``content`` as ``entry``'s result, evicting the oldest finished jobs until the
        results fit ``max_total_bytes``; a result over ``max_result_bytes`` fails the job."""
        if len(content) > self.max_result_bytes:
            raise ResultTooLargeError(
                f"the job's result is {len(content) / 2**20:.1f} MB, more than "
                f"PLANNER_JOB_RESULT_MAX_MB = {self.max_result_bytes / 2**20:g} MB; ask for "
                "less (a lower timing.sample_rate_hz, a coarser grid) or run it as a request",
                _LOC,
            )
        self._forget_expired()
        for key in [k for k, e in self._jobs.items() if e.result is not None]:
            if self.held_bytes + len(content) <= self.max_total_bytes:
                break
            self._drop(key)
        entry.result = content
        self.held_bytes += len(content)

    def _not_found(self, job_id: str) -> JobNotFoundError:
        return JobNotFoundError(
            f"no job {job_id!r} here: it never existed on this service process, or it "
            f"finished more than {self.ttl_s:g} s ago (PLANNER_JOB_TTL_S), or it was evicted "
            f"(at most {self.max_jobs} jobs are kept, PLANNER_MAX_JOBS, and their results "
            f"take at most {self.max_total_bytes / 2**20:g} MB, PLANNER_JOBS_MAX_MB), or the process "
            "restarted (jobs live in its memory only)"
        )

    def submit(self, kind: str, run: Runner, tenant: str = DEFAULT_TENANT) -> _Entry:
        """Register a job of ``kind`` for ``tenant`` and start it (queued until a slot is
        free)."""
        self._forget_expired()
        if len(self._jobs) >= self.max_jobs:
            oldest = next((k for k, e in self._jobs.items() if e.finished), None)
            if oldest is None:
                raise TooManyJobsError(
                    f"{len(self._jobs)} long jobs are queued or running (at most "
                    f"{self.max_jobs}, PLANNER_MAX_JOBS); retry when one has finished",
                    retry_after_s=max(1, round(min(self.timeout_s, 60.0))),
                )
            self._drop(oldest)
        entry = _Entry(id=uuid.uuid4().hex, kind=kind, tenant=tenant)
        self._jobs[entry.id] = entry
        context = contextvars.copy_context()
        context.run(CLIENT_GONE.set, None)  # the submitting request's client may leave
        entry.task = asyncio.get_running_loop().create_task(self._run(entry, run), context=context)
        return entry

    async def _run(self, entry: _Entry, run: Runner) -> None:
        try:
            async with self._slots:
                while True:
                    entry.status, entry.started_at = "running", time.time()
                    try:
                        content = await run(time.monotonic() + self.timeout_s)
                        break
                    except PoolSaturatedError as exc:
                        if isinstance(exc, ShuttingDownError):
                            raise  # no worker will free up: the job fails with the 503
                        # every worker busy and the pool's queue full (interactive requests):
                        # the job waits, queued, instead of failing with their 503
                        entry.status, entry.started_at = "queued", None
                        await asyncio.sleep(SATURATED_RETRY_S)
            self._keep(entry, content)
            entry.status = "done"
        except asyncio.CancelledError:
            entry.status = "cancelled"  # our own task, cancelled by cancel(): not re-raised
        except Exception as exc:
            answer = await error_answer(exc)
            detail = json.loads(bytes(answer.body))["detail"]
            entry.error = JobError(status_code=answer.status_code, detail=detail)
            entry.status = "failed"
        finally:
            self._finish(entry)

    def _finish(self, entry: _Entry) -> None:
        if entry.finished_at is None:
            entry.finished_at = time.time()
            entry.expires = time.monotonic() + self.ttl_s

    def get(self, job_id: str, tenant: str = DEFAULT_TENANT) -> _Entry:
        """The job ``job_id`` of ``tenant``; :class:`JobNotFoundError` (404) when it is not
        kept, or is another tenant's (the same answer: module docstring)."""
        self._forget_expired()
        entry = self._jobs.get(job_id)
        if entry is None or entry.tenant != tenant:
            raise self._not_found(job_id)
        return entry

    def list(self, tenant: str = DEFAULT_TENANT) -> list[_Entry]:
        """The jobs of ``tenant`` still kept, in submission order."""
        self._forget_expired()
        return [e for e in self._jobs.values() if e.tenant == tenant]

    def cancel(self, job_id: str, tenant: str = DEFAULT_TENANT) -> _Entry:
        """Cancel a queued or running job of ``tenant`` (its worker is killed at once and
        replaced); a finished job is left as it is. The job's status is ``cancelled`` from
        now on. Another tenant's job: 404, untouched."""
        entry = self.get(job_id, tenant)
        if not entry.finished and entry.task is not None:
            entry.task.cancel()
            entry.status = "cancelled"
            self._finish(entry)
        return entry

    def close(self) -> None:
        """Cancel every unfinished job (the process is stopping: nothing is kept)."""
        for entry in self._jobs.values():
            if entry.task is not None and not entry.task.done():
                entry.task.cancel()

    def summary(self, entry: _Entry) -> JobSummary:
        """The job as a line of ``GET /v1/jobs``."""
        return JobSummary(
            id=entry.id,
            kind=entry.kind,  # type: ignore[arg-type]
            status=entry.status,
            submitted_at=entry.submitted_at,
            started_at=entry.started_at,
            finished_at=entry.finished_at,
            expires_at=_wall_clock(entry.expires),
        )

    def status_json(self, entry: _Entry) -> bytes:
        """The job as :class:`planner.wire.JobStatus` JSON, its result spliced in as the
        endpoint's bytes (not parsed and written again)."""
        expires_at = _wall_clock(entry.expires)
        status = JobStatus(
            id=entry.id,
            kind=entry.kind,  # type: ignore[arg-type]
            status=entry.status,
            submitted_at=entry.submitted_at,
            started_at=entry.started_at,
            finished_at=entry.finished_at,
            expires_at=expires_at,
            error=entry.error,
        ).model_dump_json(exclude={"result"})
        result = entry.result if entry.status == "done" and entry.result is not None else b"null"
        return status[:-1].encode() + b',"result":' + result + b"}"


def _wall_clock(expires: float | None) -> float | None:
    """A monotonic expiry as Unix time (None stays None)."""
    if expires is None:
        return None
    return time.time() + max(expires - time.monotonic(), 0.0)
