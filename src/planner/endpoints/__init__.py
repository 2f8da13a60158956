"""Each endpoint's work without HTTP, one module per resource as in
:mod:`planner_api.routes`: a request model of :mod:`planner.wire` in, its response model out.
The service runs these functions in its worker processes (:mod:`planner_api`), the CLI in its
own process (:mod:`planner_cli`), tests and benchmarks directly: one answer for one request
whoever asks. It sits above the wire and the core (a motion endpoint converts the request
once, runs the motion pipeline :func:`planner.motion.run`, and builds the response once) and
below the service and the CLI; it knows nothing of HTTP (no FastAPI, no service settings).

This module holds what every endpoint shares: its budget (:class:`JobBudget`), the answer's
sample bound, and :func:`as_json` (the call a worker makes). A library error raised while
converting one field is located there (:func:`planner.wire.located`), so the service can name
the field in its 422 answer.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel

__all__ = ["BYTES_PER_SAMPLE", "UNBOUNDED", "Job", "JobBudget", "answer_sample_limit", "as_json"]


@dataclass(frozen=True, slots=True)
class JobBudget:
    """What one job may spend, handed to it as a parameter (every job is
    ``job(request, budget)``).

    Attributes
    ----------
    deadline : float or None
        The request's deadline, a :func:`time.monotonic` value (one clock for every process
        of the machine); None: no deadline (e.g. the CLI).
    max_samples : int or None
        The most trajectory samples the answer may carry (from the service's settings, see
        :func:`answer_sample_limit`); None: the library's cap.
    """

    deadline: float | None = None
    max_samples: int | None = None


#: No deadline, the library's sample cap: the budget of a job called in-process.
UNBOUNDED = JobBudget()
#: A bound on the JSON bytes of one trajectory sample (t, q, qd, qdd, jerk, p, |dP/dt|: 17
#: numbers of at most ~22 characters each, with brackets and commas).
BYTES_PER_SAMPLE = 400


def answer_sample_limit(max_samples: int, max_response_bytes: int, answers: int = 1) -> int:
    """The most trajectory samples per answer when ``answers`` answers share one response
    of at most ``max_response_bytes`` and no answer may carry more than ``max_samples``."""
    return max(2, min(max_samples, max_response_bytes // (BYTES_PER_SAMPLE * max(answers, 1))))


#: A job: request model and budget in, response model out.
Job = Callable[[Any, JobBudget], BaseModel]


def as_json(job: Job, request: Any, budget: JobBudget = UNBOUNDED) -> bytes:
    """``job(request, budget)`` serialised to JSON bytes, in the worker: the event loop then
    only forwards bytes (no re-validation, no pickling of large response models). The
    budget's deadline is the request's, for jobs that can stop early (planning, timing); its
    ``max_samples`` bounds the trajectory samples of the answer (a 422 naming
    ``timing.sample_rate_hz`` beyond it, decided before any sample is computed)."""
    return job(request, budget).model_dump_json().encode()
