"""What the routes share: running a job, in the worker pool or (cheap bounded jobs) in the
event loop, and answering its JSON.

Which jobs run in the event loop (:func:`run_inline`): those whose cost is bounded by the
request's size limits and is well under a millisecond, one posture's kinematics (fk, ik,
analyze) and the constant preset list. Sending them to a worker costs more than the job (the
pickling, the pipe both ways, a thread hand-over: ~1 ms against the job's ~0.3 ms), and the
event loop blocked for a fraction of a millisecond delays no one. Everything whose cost grows
with what the request asks (plans, timing, sections, design studies) crosses to a worker once
(:func:`run_job`)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

from fastapi import Response
from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, ValidationError

from planner.endpoints import Job, JobBudget
from planner.wire import DesignModel
from planner_api.exceptions import LimitExceededError
from planner_api.logging import REQUEST_ID
from planner_api.metrics import record_job, run_here, run_measured
from planner_api.pool import WorkerPool

__all__ = [
    "check_obstacle_count",
    "json_response",
    "obstacles_within_limit",
    "run_in_rounds",
    "run_inline",
    "run_job",
    "run_jobs",
    "with_design_defaults",
]

_BUILT_IN = DesignModel()


def check_obstacle_count(obstacles: Sequence[Any], limit: int, loc: tuple[str | int, ...]) -> None:
    """:class:`LimitExceededError` (422 at ``loc``) when a request has more than ``limit``
    obstacles (the service's ``max_obstacles``)."""
    if len(obstacles) > limit:
        raise LimitExceededError(
            f"at most {limit} obstacles per request, got {len(obstacles)}", loc
        )


def obstacles_within_limit(body: Any, limits: Any) -> Any:
    """A route's check when its only limit is the obstacle count (``limits.max_obstacles``;
    the ``prepare`` of :mod:`planner_api.routes.worker_body`, module-level so that it crosses
    to a worker)."""
    check_obstacle_count(body.obstacles, limits.max_obstacles, ("body", "obstacles"))
    return body


def with_design_defaults(body: Any, defaults: DesignModel, loc: tuple = ("body",)) -> Any:
    """``body`` with its ``design`` (and each batch request's) completed from ``defaults``,
    the service's ``PLANNER_DEFAULT_DESIGN``: absent fields take the configured robot's values,
    not the built-in default robot's. A no-op when the two are the same robot.

    Raises ``RequestValidationError`` (a 422 naming ``body.design``) when the merged design
    breaks a rule, e.g. a given ``joint_min`` above the configured ``joint_max``.
    """
    if defaults == _BUILT_IN or not isinstance(body, BaseModel):
        return body
    fields = type(body).model_fields
    update: dict[str, Any] = {}
    if "design" in fields:
        given = (
            # the request model's own field (checked above), unknown to BaseModel
            body.design.model_dump(exclude_unset=True)  # type: ignore[attr-defined]
            if "design" in body.model_fields_set
            else {}
        )
        try:
            update["design"] = DesignModel.model_validate({**defaults.model_dump(), **given})
        except ValidationError as exc:
            raise RequestValidationError(
                [{**e, "loc": (*loc, "design", *e["loc"])} for e in exc.errors(include_url=False)]
            ) from exc
    if "requests" in fields:
        update["requests"] = [
            with_design_defaults(r, defaults, (*loc, "requests", i))
            for i, r in enumerate(body.requests)  # type: ignore[attr-defined]  # a batch's field
        ]
    return body.model_copy(update=update) if update else body


def json_response(content: bytes) -> Response:
    """An ``application/json`` answer of ready-made bytes."""
    return Response(content=content, media_type="application/json")


def run_inline(
    job: Job,
    body: Any,
    deadline: float,
    *,
    design_defaults: DesignModel = _BUILT_IN,
) -> Response:
    """``job(body)`` in this process, in the event loop: for the cheap bounded jobs only (the
    module docstring). Otherwise as :func:`run_job`: the body's design completed from
    ``design_defaults``, the answer's bytes as the job serialises them, its duration recorded
    in the metrics, its errors raised to the exception handlers."""
    body = with_design_defaults(body, design_defaults)
    return json_response(run_here(job, body, budget=JobBudget(deadline)))


async def run_job(
    pool: WorkerPool,
    job: Job,
    body: Any,
    deadline: float,
    *,
    design_defaults: DesignModel = _BUILT_IN,
    max_samples: int | None = None,
) -> Response:
    """``job(body)`` in a worker, serialised there, with the request's ``deadline``; the
    answer as it is (the route's ``response_model`` documents it, the job's return type
    guarantees it). The worker reports the job's durations, recorded here
    (:mod:`planner_api.metrics`). The body's design is completed from ``design_defaults`` first
    (:func:`with_design_defaults`). ``max_samples`` bounds the answer's trajectory samples
    (:func:`planner.endpoints.answer_sample_limit`)."""
    body = with_design_defaults(body, design_defaults)
    job_json = partial(
        run_measured,
        job,
        budget=JobBudget(deadline, max_samples),
        request_id=REQUEST_ID.get(),
    )
    content, sample = await pool.run(job_json, body, deadline=deadline)
    record_job(sample)
    return json_response(content)


async def run_jobs(
    pool: WorkerPool,
    job: Job,
    bodies: Sequence[Any],
    deadline: float,
    *,
    max_samples: int | None = None,
) -> list[bytes]:
    """``job`` over ``bodies`` spread over the workers: the JSON of each answer, in order.

    Submitted in chunks of at most one job per worker, so that a batch larger than the pool's
    capacity (workers + queue) is served in rounds instead of being refused whole; a 503
    still answers a pool that is saturated by other requests.
    """
    job_json = partial(
        run_measured,
        job,
        budget=JobBudget(deadline, max_samples),
        request_id=REQUEST_ID.get(),
    )
    return await run_in_rounds(pool, job_json, bodies, deadline)


async def run_in_rounds(
    pool: WorkerPool, fn: Callable[[Any], tuple[bytes, Any]], args: Sequence[Any], deadline: float
) -> list[bytes]:
    """``fn`` (which answers a job's JSON and its metrics sample, as
    :func:`planner_api.metrics.run_measured`) over ``args``, in rounds of one job per worker
    (:func:`run_jobs`): the JSON of each answer, in order, each sample recorded."""
    contents: list[bytes] = []
    for start in range(0, len(args), pool.workers):
        answers = await pool.map(fn, args[start : start + pool.workers], deadline=deadline)
        for content, sample in answers:
            record_job(sample)
            contents.append(content)
    return contents
