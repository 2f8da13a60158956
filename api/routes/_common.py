"""What the routes share: running a job in the worker pool and answering its JSON."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

from fastapi import Response
from pydantic import BaseModel

from api.logging import REQUEST_ID
from api.metrics import record_job, run_measured
from api.workers import WorkerPool

__all__ = ["json_response", "run_job", "run_jobs"]


def json_response(content: bytes) -> Response:
    """An ``application/json`` answer of ready-made bytes."""
    return Response(content=content, media_type="application/json")


async def run_job(
    pool: WorkerPool, job: Callable[[Any], BaseModel], body: Any, deadline: float
) -> Response:
    """``job(body)`` in a worker, serialised there, with the request's ``deadline``; the
    answer as it is (the route's ``response_model`` documents it, the job's return type
    guarantees it). The worker reports the job's durations, recorded here
    (:mod:`api.metrics`)."""
    job_json = partial(run_measured, job, deadline=deadline, request_id=REQUEST_ID.get())
    content, sample = await pool.run(job_json, body, deadline=deadline)
    record_job(sample)
    return json_response(content)


async def run_jobs(
    pool: WorkerPool, job: Callable[[Any], BaseModel], bodies: Sequence[Any], deadline: float
) -> list[bytes]:
    """``job`` over ``bodies`` spread over the workers: the JSON of each answer, in order."""
    job_json = partial(run_measured, job, deadline=deadline, request_id=REQUEST_ID.get())
    answers = await pool.map(job_json, bodies, deadline=deadline)
    for _, sample in answers:
        record_job(sample)
    return [content for content, _ in answers]
