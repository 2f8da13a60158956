"""The warm-up of a service worker: everything a worker's first job would otherwise pay is
paid before the worker takes jobs (:class:`planner_api.pool.WorkerPool` announces a worker warm,
and ``/v1/ready`` counts it, only after this returns).

Measured on a 2-core machine: after the library's kernels alone were warm, the first plan
through the service's job path still took 5.5 s (OMPL's and toppra's first calls, the service
modules' imports) against 11 ms for the second one.
"""

from __future__ import annotations

import asyncio
import json
import logging
import time
from typing import Any

__all__ = ["post_scope", "start_worker", "warm_up_inline", "warm_up_loop", "warm_up_worker"]

logger = logging.getLogger(__name__)

#: Seconds :func:`warm_up_loop` waits for a warm worker before it warms the plan route.
_POOL_WAIT_S = 600.0

_POSTURE = {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"}
#: A start from which a short straight line of P is valid (docs/cartesian.md's example).
_CARTESIAN_START = {"q": [-0.2187, 2.8609, 0.2807], "assembly_mode": "+"}


def start_worker(cache_mb: float, warm: bool) -> float:
    """What each worker runs before it takes jobs (the pool's ``warm_up``, bound to the
    settings with :func:`functools.partial`): its caches sized by ``PLANNER_CACHE_MB``
    (:func:`planner.caching.configure`; a spawned worker would start at the library's
    default), then, with ``warm``, :func:`warm_up_worker`. Returns its seconds."""
    from planner import caching

    t0 = time.perf_counter()
    caching.configure(budget_mb=cache_mb)
    if warm:
        warm_up_worker()
    return time.perf_counter() - t0


def warm_up_worker() -> float:
    """The library's warm-up (:func:`planner.warmup.warm_up`: numba kernels, OMPL, toppra,
    ruckig, matplotlib), then the service's own jobs once each, through the path a request
    takes (:func:`planner_api.metrics.run_measured`): a plan timed by TOPPRA and one by Ruckig (with
    an obstacle, so the clearance kernels run too), a straight tool path, fk and ik. Returns its seconds."""
    from planner.warmup import quiet_library_logs, warm_up

    t0 = time.perf_counter()
    warm_up()
    with quiet_library_logs():
        _run_jobs()
    return time.perf_counter() - t0


def warm_up_inline() -> float:
    """The warm-up of the serving process itself, for the jobs it runs in its event loop
    (:func:`planner_api.routes._common.run_inline`): fk, ik and analyze once each, which loads
    their numba kernels (~2 s on a loaded 2-core machine, which would otherwise block the event
    loop on the first such request). Run in a thread at start-up; ``/v1/ready`` waits for it.
    Returns its seconds."""
    from planner.endpoints import kinematics
    from planner.warmup import quiet_library_logs
    from planner.wire import AnalyzeRequest, FKRequest, IKRequest
    from planner_api.metrics import run_measured

    t0 = time.perf_counter()
    with quiet_library_logs():
        run_measured(kinematics.fk, FKRequest.model_validate({"q": _POSTURE["q"]}))
        run_measured(kinematics.ik, IKRequest.model_validate({"p": [0.5, 0.05, 0.2]}))
        run_measured(kinematics.analyze, AnalyzeRequest.model_validate(_POSTURE))
    return time.perf_counter() - t0


async def warm_up_loop(app: Any) -> float:
    """The warm-up of the serving process's event loop, before ``/v1/ready`` says ready:
    :func:`warm_up_inline` in a thread (the numba kernels), then once the pool has a warm
    worker, one request each to ``/v1/fk``, ``/v1/ik``, ``/v1/analyze`` and ``/v1/plan``
    through the application's router (its routing table, the routes' handlers, the request
    models' validators, the JSON encoders, the hand-over to a worker and back: the first
    plan after ready was 10-13x the steady state without this). The requests go below the
    middleware (no metrics, no access log: they are nobody's); a failed one is logged, and
    the service starts anyway. Returns its seconds."""
    t0 = time.perf_counter()
    await asyncio.to_thread(warm_up_inline)
    pool = app.state.pool
    waited = 0.0
    while pool.state != "ready" and waited < _POOL_WAIT_S:
        await asyncio.sleep(0.05)
        waited += 0.05
    plan = {
        "start": _POSTURE,
        "goal": {"q": [0.6, 2.3, 0.8], "assembly_mode": "+"},
        "planner": {"seed": 1},
    }
    for path, body in (
        ("/v1/fk", {"q": _POSTURE["q"]}),
        ("/v1/ik", {"p": [0.5, 0.05, 0.2]}),
        ("/v1/analyze", _POSTURE),
        ("/v1/plan", plan),
        ("/v1/plan", plan),
    ):
        status = await _request(app, path, body)
        if status != 200:
            logger.warning("the event loop's warm-up request to %s answered %s", path, status)
    return time.perf_counter() - t0


def post_scope(path: str, headers: list[tuple[bytes, bytes]]) -> dict[str, Any]:
    """The ASGI scope of a POST to ``path`` from the loopback with ``headers``: what the
    loop's warm-up sends through the router (and benchmarks/ops_overhead.py through the app)."""
    return {
        "type": "http",
        "asgi": {"version": "3.0"},
        "http_version": "1.1",
        "method": "POST",
        "scheme": "http",
        "path": path,
        "raw_path": path.encode(),
        "root_path": "",
        "query_string": b"",
        "headers": headers,
        "client": ("127.0.0.1", 0),
        "server": ("127.0.0.1", 0),
    }


async def _request(app: Any, path: str, body: dict) -> int:
    """One POST of ``body`` to ``path`` through ``app``'s router (below the middleware),
    with the service's first API key if it has keys: the answer's status."""
    keys = app.state.settings.tenant_keys
    headers = [(b"content-type", b"application/json"), (b"host", b"localhost")]
    if keys:
        headers.append((b"x-api-key", next(iter(keys)).encode()))
    raw = json.dumps(body).encode()
    scope = {**post_scope(path, headers), "state": {}, "app": app}
    sent = [{"type": "http.request", "body": raw, "more_body": False}]
    never: asyncio.Future[None] = asyncio.get_running_loop().create_future()
    status = 0

    async def receive() -> dict:
        if sent:
            return sent.pop()
        await never  # no disconnect: the client watch waits here until it is cancelled
        raise AssertionError("unreachable")

    async def send(message: dict) -> None:
        nonlocal status
        if message["type"] == "http.response.start":
            status = message["status"]

    await app.router(scope, receive, send)
    return status


def _run_jobs() -> None:
    from planner.endpoints import JobBudget, cartesian, kinematics, plan
    from planner.wire import CartesianRequest, FKRequest, IKRequest, PlanRequest
    from planner_api.metrics import run_measured
    from planner_api.routes import worker_body  # noqa: F401  (a large body's job, imported)

    budget = JobBudget(deadline=time.monotonic() + 120.0)
    for method in ("toppra", "ruckig"):
        body = {
            "start": _POSTURE,
            "goal": {"q": [0.6, 2.3, 0.8], "assembly_mode": "+"},
            "obstacles": [{"type": "sphere", "center": [2.0, 2.0, 2.0], "radius": 0.1}],
            "planner": {"seed": 1},
            "timing": {"method": method},
        }
        run_measured(plan.plan, PlanRequest.model_validate(body), budget=budget)
    straight = {"start": _CARTESIAN_START, "waypoints": [[0.45, 0.3, 0.1]]}
    run_measured(cartesian.cartesian, CartesianRequest.model_validate(straight), budget=budget)
    run_measured(kinematics.fk, FKRequest.model_validate({"q": _POSTURE["q"]}), budget=budget)
    run_measured(kinematics.ik, IKRequest.model_validate({"p": [0.5, 0.05, 0.2]}), budget=budget)
