"""Prometheus metrics of one service process, exposed at ``GET /metrics``.

Multi-process safety: the CPU-bound work runs in the worker processes of
:mod:`planner_api.pool.pool`, which record nothing. Each job is wrapped by :func:`run_measured`, which
returns, next to the job's JSON, a small :class:`JobSample` (the job's name, its time in the
worker, and for a plan its status and its planning and timing durations); the parent process
records the sample (:func:`record_job`). So every metric lives in the one process that serves
``/metrics`` and no shared-memory directory (``PROMETHEUS_MULTIPROC_DIR``) is needed. Each
application has its own registry (several apps in one process, e.g. tests, do not mix).

Metrics (``route`` is the route's path template, ``<unmatched>`` for unknown paths):

=========================================  =========  ==========================================
name                                       type       labels / meaning
=========================================  =========  ==========================================
planner_http_requests_total                counter    method, route, status
planner_http_request_duration_seconds      histogram  method, route: arrival to last byte
planner_http_requests_in_progress          gauge      requests being served
planner_job_duration_seconds               histogram  job: time of the job in its worker
planner_plan_outcomes_total                counter    status: solved, no_path, ..., timeout
planner_planning_duration_seconds          histogram  the planner's search (diagnostics)
planner_timing_duration_seconds            histogram  the time parameterisation (diagnostics)
planner_pool_workers                       gauge      worker processes
planner_pool_capacity                      gauge      jobs allowed in flight (workers + queue)
planner_pool_in_flight                     gauge      jobs running or waiting
planner_pool_busy_workers                  gauge      min(in flight, workers)
planner_pool_queue_depth                   gauge      jobs waiting for a worker
planner_pool_saturation                    gauge      in flight / capacity, 0..1
planner_pool_ready                         gauge      1 once every worker answered, else 0
planner_pool_rejected_total                counter    jobs refused with 503 (pool full)
planner_pool_worker_kills_total            counter    workers killed: job past deadline + grace,
                                                      or cancelled (client gone, DELETE)
planner_pool_worker_recycles_total         counter    workers recycled over the memory bound
planner_cache_entries                      gauge      cache: entries kept
planner_cache_bytes                        gauge      cache: bytes of the entries kept
planner_cache_hits_total                   counter    cache: lookups that found an entry
planner_cache_misses_total                 counter    cache: lookups that found none
planner_cache_budget_bytes                 gauge      cache: its bound in each process
planner_build_info                         gauge      version; always 1
=========================================  =========  ==========================================

The caches (:mod:`planner.caching`, ``cache`` its name) live in every process: each job's
:class:`JobSample` carries its worker's :func:`planner.caching.stats` after the job, and a
scrape sums the last report of each live worker with the serving process's own (a worker
replaced takes its counts with it, which Prometheus' ``rate`` reads as a counter reset).
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Any

from fastapi import APIRouter, Request, Response
from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, generate_latest
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.exposition import CONTENT_TYPE_LATEST
from pydantic import BaseModel

from planner import caching
from planner.endpoints import UNBOUNDED, Job, JobBudget, as_json
from planner_api.logging import REQUEST_ID

__all__ = [
    "CURRENT",
    "JobSample",
    "Metrics",
    "cache_report",
    "metrics",
    "record_job",
    "router",
    "run_here",
    "run_measured",
]

#: Buckets (s) for request and job durations: 1 ms to 60 s.
DURATION_BUCKETS = (
    0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0,
)  # fmt: skip
#: The ``route`` label of a path that matches no route (keeps the label set bounded).
UNMATCHED = "<unmatched>"


@dataclass(frozen=True, slots=True)
class JobSample:
    """What a worker reports about one finished job (picklable, a few bytes).

    Attributes
    ----------
    job : str
        The job function's name, e.g. ``"plan"``.
    seconds : float
        Wall time of the job in the worker, s (serialisation included).
    status : str or None
        A plan's ``status``; None for other jobs.
    planning_time_s, timing_time_s : float or None
        A plan's ``diagnostics`` durations, s (None when absent).
    pid : int or None
        The process that ran the job.
    caches : tuple or None
        That process's caches after the job: (name, entries, bytes, hits, misses,
        budget bytes) each (:func:`cache_report`).
    """

    job: str
    seconds: float
    status: str | None = None
    planning_time_s: float | None = None
    timing_time_s: float | None = None
    pid: int | None = None
    caches: tuple[tuple[str, int, int, int, int, int], ...] | None = None

    def __reduce__(self) -> tuple[type[JobSample], tuple[Any, ...]]:
        # one flat tuple: a slotted dataclass's own pickling walks its fields in Python, in
        # the worker and again in the event loop, on every job
        return JobSample, (
            self.job,
            self.seconds,
            self.status,
            self.planning_time_s,
            self.timing_time_s,
            self.pid,
            self.caches,
        )


def cache_report() -> tuple[tuple[str, int, int, int, int, int], ...]:
    """This process's :func:`planner.caching.stats` as plain tuples (a few hundred bytes
    pickled): (name, entries, bytes, hits, misses, budget bytes) per cache."""
    return tuple((name, *s) for name, s in caching.stats().items())


def run_measured(
    job: Job,
    request: Any,
    *,
    budget: JobBudget = UNBOUNDED,
    request_id: str | None = None,
) -> tuple[bytes, JobSample]:
    """In a worker: :func:`planner.endpoints.as_json` of ``job(request, budget)`` and its
    :class:`JobSample`.

    ``request_id`` is set for the job so that its log lines carry it. Exceptions of the job
    propagate unchanged (the parent maps them to HTTP answers).
    """
    models: list[BaseModel] = []

    def keep(r: Any, b: JobBudget) -> BaseModel:
        model = job(r, b)
        models.append(model)
        return model

    token = REQUEST_ID.set(request_id)
    start = time.perf_counter()
    try:
        content = as_json(keep, request, budget)
    finally:
        REQUEST_ID.reset(token)
    seconds = time.perf_counter() - start
    return content, _sample(
        job, seconds, models[0] if models else None, os.getpid(), cache_report()
    )


def run_here(job: Job, request: Any, *, budget: JobBudget = UNBOUNDED) -> bytes:
    """In the serving process (the event loop's cheap jobs,
    :func:`planner_api.routes._common.run_inline`): :func:`planner.endpoints.as_json` of
    ``job(request, budget)``, its :class:`JobSample` recorded at once (:func:`record_job`).
    Without the cache report a worker sends: this process's caches are read live at scrape
    time (:class:`_CacheCollector`), so building one per request would be thrown away; and
    the request id is already the request's (the loop serves it)."""
    models: list[BaseModel] = []

    def keep(r: Any, b: JobBudget) -> BaseModel:
        model = job(r, b)
        models.append(model)
        return model

    start = time.perf_counter()
    content = as_json(keep, request, budget)
    record_job(_sample(job, time.perf_counter() - start, models[0] if models else None))
    return content


def _sample(
    job: Job,
    seconds: float,
    model: BaseModel | None,
    pid: int | None = None,
    caches: tuple[tuple[str, int, int, int, int, int], ...] | None = None,
) -> JobSample:
    """The :class:`JobSample` of one job's answer ``model`` (a plan's status and durations)."""
    from planner.wire import PlanResponse

    name = getattr(job, "__name__", type(job).__name__)
    if isinstance(model, PlanResponse):
        return JobSample(
            name,
            seconds,
            str(model.status),
            model.diagnostics.planning_time_s,
            model.diagnostics.timing_time_s,
            pid=pid,
            caches=caches,
        )
    return JobSample(name, seconds, pid=pid, caches=caches)


class _PoolCollector:
    """Reads the worker pool's state at scrape time (nothing to keep in sync)."""

    def __init__(self, get_pool: Callable[[], Any]) -> None:
        self._get_pool = get_pool

    def collect(self) -> Iterator[Metric]:
        pool = self._get_pool()
        if pool is None:
            return
        in_flight = pool.in_flight
        workers = pool.workers
        capacity = pool.capacity
        values = {
            "planner_pool_workers": ("Worker processes.", workers),
            "planner_pool_capacity": ("Jobs allowed in flight (workers + queue).", capacity),
            "planner_pool_in_flight": ("Jobs running or waiting for a worker.", in_flight),
            "planner_pool_busy_workers": ("Workers running a job.", min(in_flight, workers)),
            "planner_pool_queue_depth": ("Jobs waiting for a worker.", max(in_flight - workers, 0)),
            "planner_pool_saturation": ("Jobs in flight / capacity (1: the next job gets 503).",
                                        in_flight / capacity),
            "planner_pool_ready": ("1 while /v1/ready says ready (a worker is warm).",
                                   1 if pool.state == "ready" else 0),
            "planner_pool_warm_workers": ("Worker processes alive and warm.",
                                          pool.warm_workers),
        }  # fmt: skip
        for name, (doc, value) in values.items():
            yield GaugeMetricFamily(name, doc, value=value)
        yield CounterMetricFamily(
            "planner_pool_rejected",
            "Jobs refused because the pool was full (503).",
            value=pool.rejected,
        )
        yield CounterMetricFamily(
            "planner_pool_worker_restarts",
            "Worker processes that died and were replaced.",
            value=pool.restarts,
        )
        yield CounterMetricFamily(
            "planner_pool_worker_kills",
            "Workers killed because their job ran past its "
            "deadline plus the overrun grace, or was cancelled (replaced warm).",
            value=pool.kills,
        )
        yield CounterMetricFamily(
            "planner_pool_worker_recycles",
            "Workers recycled because their memory after a "
            "job exceeded PLANNER_WORKER_MAX_RSS_MB (replacement warm first).",
            value=pool.recycles,
        )


class _CacheCollector:
    """The caches of the serving process and of its live workers (their last reports,
    :meth:`Metrics.record_job`), summed per cache at scrape time."""

    def __init__(self, get_pool: Callable[[], Any]) -> None:
        self._get_pool = get_pool
        self._lock = threading.Lock()
        #: pid -> the last cache report of that worker
        self._reports: dict[int, tuple[tuple[str, int, int, int, int, int], ...]] = {}

    def record(self, sample: JobSample) -> None:
        """Keep a worker's report (the serving process's own is read live)."""
        if sample.caches is not None and sample.pid is not None and sample.pid != os.getpid():
            with self._lock:
                self._reports[sample.pid] = sample.caches

    def collect(self) -> Iterator[Metric]:
        pool = self._get_pool()
        live = set(pool.pids) if pool is not None else set()
        with self._lock:
            for pid in [p for p in self._reports if p not in live]:
                del self._reports[pid]  # a worker gone: its caches with it
            reports = [*self._reports.values(), cache_report()]
        totals: dict[str, list[int]] = {}
        for report in reports:
            for name, *values in report:
                total = totals.setdefault(name, [0, 0, 0, 0, 0])
                for i, v in enumerate(values[:4]):
                    total[i] += v
                total[4] = max(total[4], values[4])
        # in the order of a report's values: entries, bytes, hits, misses, budget
        families: tuple[GaugeMetricFamily | CounterMetricFamily, ...] = (
            GaugeMetricFamily("planner_cache_entries", "Entries kept.", labels=["cache"]),
            GaugeMetricFamily(
                "planner_cache_bytes", "Bytes of the entries kept.", labels=["cache"]
            ),
            CounterMetricFamily(
                "planner_cache_hits", "Lookups that found an entry.", labels=["cache"]
            ),
            CounterMetricFamily(
                "planner_cache_misses", "Lookups that found none.", labels=["cache"]
            ),
            GaugeMetricFamily(
                "planner_cache_budget_bytes",
                "The cache's bound in each process (its share of PLANNER_CACHE_MB), bytes.",
                labels=["cache"],
            ),
        )
        for name, values in sorted(totals.items()):
            for family, value in zip(families, values, strict=True):
                family.add_metric([name], value)
        yield from families


class Metrics:
    """The metrics of one application, in their own registry.

    Parameters
    ----------
    get_pool : callable
        Returns the application's :class:`planner_api.pool.WorkerPool` (or None before start-up);
        read at every scrape.
    version : str
        The service version, for ``planner_build_info``.
    """

    def __init__(self, get_pool: Callable[[], Any], version: str) -> None:
        self.registry = CollectorRegistry(auto_describe=True)
        r = self.registry
        self.requests = Counter(
            "planner_http_requests",
            "HTTP requests answered.",
            ["method", "route", "status"],
            registry=r,
        )
        self.latency = Histogram(
            "planner_http_request_duration_seconds",
            "Time from a request's arrival to its last byte, s.",
            ["method", "route"],
            buckets=DURATION_BUCKETS,
            registry=r,
        )
        self.in_progress = Gauge(
            "planner_http_requests_in_progress", "Requests being served.", registry=r
        )
        self.job_seconds = Histogram(
            "planner_job_duration_seconds",
            "Time of a job in its worker process, s.",
            ["job"],
            buckets=DURATION_BUCKETS,
            registry=r,
        )
        self.plan_outcomes = Counter(
            "planner_plan_outcomes", "Finished plans by status.", ["status"], registry=r
        )
        self.planning_seconds = Histogram(
            "planner_planning_duration_seconds",
            "The planner's search, s.",
            buckets=DURATION_BUCKETS,
            registry=r,
        )
        self.timing_seconds = Histogram(
            "planner_timing_duration_seconds",
            "Time parameterisation of a path, s.",
            buckets=DURATION_BUCKETS,
            registry=r,
        )
        Gauge("planner_build_info", "Service version.", ["version"], registry=r).labels(
            version
        ).set(1)
        # each label set's child, found once: prometheus_client's ``labels()`` checks and
        # locks on every call (as many entries as the label sets exported, so bounded alike)
        self._request_children: dict[tuple[str, str, int], tuple[Any, Any]] = {}
        self._job_children: dict[str, Any] = {}
        self._outcome_children: dict[str, Any] = {}
        r.register(_PoolCollector(get_pool))
        self._caches = _CacheCollector(get_pool)
        r.register(self._caches)

    def record_job(self, sample: JobSample) -> None:
        """Record one job's :class:`JobSample` (in the process that serves /metrics)."""
        child = self._job_children.get(sample.job)
        if child is None:
            child = self._job_children[sample.job] = self.job_seconds.labels(sample.job)
        child.observe(sample.seconds)
        self._caches.record(sample)
        if sample.status is not None:
            outcome = self._outcome_children.get(sample.status)
            if outcome is None:
                outcome = self.plan_outcomes.labels(sample.status)
                self._outcome_children[sample.status] = outcome
            outcome.inc()
        if sample.planning_time_s is not None:
            self.planning_seconds.observe(sample.planning_time_s)
        if sample.timing_time_s is not None:
            self.timing_seconds.observe(sample.timing_time_s)

    def record_request(self, method: str, route: str, status: int, seconds: float) -> None:
        """Record one answered HTTP request."""
        children = self._request_children.get((method, route, status))
        if children is None:
            children = (
                self.requests.labels(method, route, str(status)),
                self.latency.labels(method, route),
            )
            self._request_children[method, route, status] = children
        children[0].inc()
        children[1].observe(seconds)

    def exposition(self) -> bytes:
        """The registry in Prometheus' text format."""
        return generate_latest(self.registry)


#: The metrics of the application serving the current request (set by the request
#: middleware, :class:`planner_api.middleware.RequestObserver`), read by :func:`record_job`.
CURRENT: ContextVar[Metrics | None] = ContextVar("metrics", default=None)


def record_job(sample: JobSample) -> None:
    """Record ``sample`` in the current request's application metrics (nothing outside one)."""
    metrics = CURRENT.get()
    if metrics is not None:
        metrics.record_job(sample)


router = APIRouter(tags=["meta"])


@router.get("/metrics", include_in_schema=False)
def metrics(request: Request) -> Response:
    """Prometheus text exposition of this process's metrics."""
    m: Metrics = request.app.state.metrics
    return Response(m.exposition(), media_type=CONTENT_TYPE_LATEST)
