"""Errors of the service itself (not of the library); :mod:`planner_api.errors` maps each one, and
every :class:`planner.exceptions.PlannerError`, to an HTTP answer.

::

    ServiceError
    ├── PoolSaturatedError        503 + Retry-After: every worker busy, queue full
    │   └── ShuttingDownError     503 + Retry-After: the process is stopping (retry elsewhere)
    ├── PoolNotRunningError       503: the worker pool was not started (no lifespan)
    ├── DeadlineExceededError     504: the request's time budget ran out
    ├── WorkerCrashedError        502: a worker process died during the job
    ├── JobCancelledError         499: the job was cancelled (its worker stopped)
    │   └── ClientDisconnectedError  499: the client went away; its job was cancelled
    ├── JobNotFoundError          404: no long job of that id (never, or expired)
    ├── TooManyJobsError          503 + Retry-After: the long-job list is full
    │   └── TenantJobsError       429 + Retry-After: the tenant has PLANNER_JOBS_PER_TENANT
    │                             unfinished jobs
    ├── LimitExceededError        422: a request exceeds a size limit of the service settings
    ├── QuotaExceededError        422 or 413: a tenant's scene count or stored bytes would pass
    │                             PLANNER_SCENES_MAX or PLANNER_SCENE_BYTES_MAX
    ├── StoreUnavailableError     503 + Retry-After: the scene store cannot answer in time
    └── AuthenticationError       401: missing or wrong API key
"""

from __future__ import annotations

__all__ = [
    "AuthenticationError",
    "ClientDisconnectedError",
    "DeadlineExceededError",
    "JobCancelledError",
    "JobNotFoundError",
    "LimitExceededError",
    "PoolNotRunningError",
    "PoolSaturatedError",
    "QuotaExceededError",
    "ResultTooLargeError",
    "ServiceError",
    "ShuttingDownError",
    "StoreUnavailableError",
    "TenantJobsError",
    "TooManyJobsError",
    "WorkerCrashedError",
]


class ServiceError(Exception):
    """Base of the errors of the service itself."""


class PoolSaturatedError(ServiceError):
    """Every worker is busy and the queue is full: retry after ``retry_after_s`` seconds."""

    def __init__(self, message: str, retry_after_s: int) -> None:
        super().__init__(message, retry_after_s)
        self.message = message
        self.retry_after_s = retry_after_s

    def __str__(self) -> str:
        return self.message


class ShuttingDownError(PoolSaturatedError):
    """The process is shutting down: the job was not taken, or its share of the shutdown
    grace ran out and it was cancelled. Another replica can serve the retry."""


class PoolNotRunningError(ServiceError):
    """The application's worker pool is not running (its lifespan was not started, e.g. a
    ``TestClient`` used without ``with``)."""


class DeadlineExceededError(ServiceError):
    """The request's time budget ran out before its job finished."""


class WorkerCrashedError(ServiceError):
    """The worker process running the job died; only this job fails, and a replacement
    worker is started (and warmed) in the background."""


class JobCancelledError(ServiceError):
    """The job was cancelled while it ran: its worker was stopped (and is replaced)."""


class ClientDisconnectedError(JobCancelledError):
    """The client closed its connection before the answer: its job was cancelled. Nobody
    reads the answer (recorded as 499, nginx's "client closed request")."""


class JobNotFoundError(ServiceError):
    """No long job has this id: it never existed, or its result expired (kept a bounded
    time and count, ``PLANNER_JOB_TTL_S`` and ``PLANNER_MAX_JOBS``)."""


class TooManyJobsError(PoolSaturatedError):
    """The long-job list is full of jobs not finished yet: retry later."""


class TenantJobsError(TooManyJobsError):
    """The tenant has ``PLANNER_JOBS_PER_TENANT`` jobs not finished yet (429, not 503: the
    bound is the tenant's own and holds over every replica, so another replica would refuse
    the same; a load balancer retrying 503s elsewhere must not retry it)."""


class LimitExceededError(ServiceError):
    """A request is larger than a limit of the settings (``loc`` names the field)."""

    #: The ``type`` of its 422 answer.
    error_type = "limit_exceeded"

    def __init__(self, message: str, loc: tuple[str | int, ...]) -> None:
        super().__init__(message, loc)
        self.message = message
        self.loc = loc

    def __str__(self) -> str:
        return self.message


class ResultTooLargeError(LimitExceededError):
    """A long job's result is larger than ``PLANNER_JOB_RESULT_MAX_MB`` (422
    ``result_too_large``)."""

    error_type = "result_too_large"


class AuthenticationError(ServiceError):
    """The API key is missing or wrong."""


class QuotaExceededError(ServiceError):
    """A scene PUT would take its tenant past a quota: ``status`` is 422 for the count
    (``PLANNER_SCENES_MAX``), 413 for the stored bytes (``PLANNER_SCENE_BYTES_MAX``); the
    message names the setting, the limit and what the PUT would make of it."""

    def __init__(self, message: str, status: int, loc: tuple[str | int, ...]) -> None:
        super().__init__(message, status, loc)
        self.message = message
        self.status = status
        self.loc = loc

    def __str__(self) -> str:
        return self.message


class StoreUnavailableError(ServiceError):
    """The scene store cannot answer within ``PLANNER_STORE_TIMEOUT_S``: its write lock is
    held, its database unreachable, or every store thread is busy. Retry after
    ``retry_after_s`` seconds (nothing was changed)."""

    def __init__(self, message: str, retry_after_s: int) -> None:
        super().__init__(message, retry_after_s)
        self.message = message
        self.retry_after_s = retry_after_s

    def __str__(self) -> str:
        return self.message
