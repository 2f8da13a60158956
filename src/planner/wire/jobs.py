"""``POST /v1/jobs``, ``GET /v1/jobs``, ``GET /v1/jobs/{id}``, ``DELETE /v1/jobs/{id}``: long
jobs.

A long job is one endpoint's request run in the background: submitted (202 with its ``id``),
polled, and cancelled by id; its ``result`` is the endpoint's response body, the same JSON
the endpoint would have answered. ``docs/service.md`` says what the jobs survive (they live in
the service's store, shared by its replicas: a finished job survives a restart; one that was
running is then ``failed`` with the error type ``lost_on_restart``).
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, RootModel

from planner.wire.common import _Request, _Response
from planner.wire.meta import ErrorItem

__all__ = [
    "JOB_KINDS",
    "JobError",
    "JobKind",
    "JobList",
    "JobRequest",
    "JobState",
    "JobStatus",
    "JobSummary",
]

#: The endpoints a long job can run, by kind: ``plan`` is ``POST /v1/plan``, ``sequence``
#: ``/v1/sequence``, ``cartesian`` ``/v1/cartesian``, ``timing`` ``/v1/timing``,
#: ``design_check`` ``/v1/design/check``, ``design_optimize`` ``/v1/design/optimize``,
#: ``regions`` ``/v1/design/regions``.
JOB_KINDS = (
    "plan", "sequence", "cartesian", "timing", "design_check", "design_optimize", "regions",
)  # fmt: skip
JobKind = Literal[
    "plan", "sequence", "cartesian", "timing", "design_check", "design_optimize", "regions"
]
#: ``queued`` (waiting for a slot), ``running``, then one of ``done`` (``result`` set),
#: ``failed`` (``error`` set), ``cancelled``.
JobState = Literal["queued", "running", "done", "failed", "cancelled"]


class JobRequest(_Request):
    """Body of ``POST /v1/jobs``."""

    kind: JobKind = Field(description="The endpoint the job runs (see JOB_KINDS).")
    request: dict[str, Any] = Field(
        description="That endpoint's request body, validated as the endpoint validates it "
        "(a 422 locates a bad field under body.request)."
    )


class JobError(_Response):
    """Why a job failed: the HTTP status and error body the endpoint would have answered
    (or 503 ``lost_on_restart``: the replica running it stopped before it finished)."""

    status_code: int = Field(description="e.g. 422 (bad input found by the job), 504.")
    detail: list[ErrorItem]


class JobStatus(_Response):
    """Answer of ``POST /v1/jobs`` (202), ``GET /v1/jobs/{id}`` and ``DELETE /v1/jobs/{id}``."""

    id: str
    kind: JobKind
    status: JobState
    submitted_at: float = Field(description="When the job was submitted, Unix time, s.")
    started_at: float | None = Field(None, description="When it started running, Unix s.")
    finished_at: float | None = Field(None, description="When it ended, Unix time, s.")
    expires_at: float | None = Field(
        None,
        description="When a finished job is forgotten (its id then answers 404), Unix s.",
    )
    result: dict[str, Any] | None = Field(
        None, description="With status 'done': the endpoint's response body."
    )
    error: JobError | None = Field(None, description="With status 'failed'.")


class JobSummary(_Response):
    """One job of ``GET /v1/jobs``: its id, kind, state and times (no result). ``created`` and
    ``finished`` are the conventions' names; ``submitted_at`` ... ``expires_at`` the same times
    under the names of :class:`JobStatus`."""

    id: str
    kind: JobKind
    status: JobState
    created: float = Field(description="When the job was submitted, Unix time, s.")
    finished: float | None = Field(None, description="When it ended, Unix time, s (null: not yet).")
    submitted_at: float = Field(description="When the job was submitted, Unix time, s.")
    started_at: float | None = Field(None, description="When it started running, Unix s.")
    finished_at: float | None = Field(None, description="When it ended, Unix time, s.")
    expires_at: float | None = Field(
        None, description="When a finished job is forgotten, Unix time, s."
    )


class JobList(RootModel[list[JobSummary]]):
    """Answer of ``GET /v1/jobs``: the jobs of the request's tenant still kept, oldest first,
    as a JSON array (the conventions' ``[{"id", "kind", "status", "created", "finished"}]``;
    ``.root`` is the list)."""
