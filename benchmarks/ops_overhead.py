"""Cost of the observability layer per request: the request-id / metrics / access-log
middleware (:class:`planner_api.middleware.RequestObserver`) and the job sample returned by the
workers (:func:`planner_api.metrics.run_measured` against :func:`planner.endpoints.as_json`).

Both are timed in-process, with and without the layer, in the same run, on the same inputs
(medians of batches; the ratio is of those medians):

- middleware: one ASGI request through a trivial endpoint app, bare vs wrapped by the
  observer (access log at INFO to a discarded stream, as in production);
- job wrapper: the fk job serialised by ``as_json`` vs by ``run_measured``;
- the whole application (issue 43): one ``POST /v1/fk`` through the service's ASGI app (its
  middleware, routing, body validation, the fk job, the answer) against a bare FastAPI app
  echoing the same body into a pydantic model, in the same process, CPU time of the calling
  thread (what the event loop spends per request, without the HTTP server's parsing).

    PYTHONPATH=src:. python benchmarks/ops_overhead.py [--n 20000]
"""

from __future__ import annotations

import argparse
import asyncio
import io
import logging
import statistics
import time
from collections.abc import Awaitable, Callable

from _machine import print_machine
from fastapi import FastAPI
from pydantic import BaseModel

from planner.endpoints import as_json
from planner.endpoints import kinematics as jobs
from planner.wire import FKRequest
from planner_api.logging import JsonFormatter, RequestIdFilter
from planner_api.metrics import Metrics, run_measured
from planner_api.middleware import RequestObserver


async def _endpoint(scope, receive, send) -> None:  # type: ignore[no-untyped-def]
    await send(
        {
            "type": "http.response.start",
            "status": 200,
            "headers": [(b"content-type", b"application/json")],
        }
    )
    await send({"type": "http.response.body", "body": b"{}"})


def _time_asgi(app: Callable[..., Awaitable[None]], n: int, batch: int = 500) -> float:
    scope = {
        "type": "http",
        "method": "POST",
        "path": "/v1/fk",
        "headers": [(b"x-request-id", b"bench-1")],
        "client": ("127.0.0.1", 1),
    }

    async def receive() -> dict:
        return {"type": "http.request", "body": b"", "more_body": False}

    async def send(_message: dict) -> None:
        return None

    size = max(1, min(batch, n))  # fewer requests than a batch: one batch of them all

    async def run() -> list[float]:
        per_call = []
        for _ in range(max(1, n // size)):
            start = time.perf_counter()
            for _ in range(size):
                await app(dict(scope), receive, send)
            per_call.append((time.perf_counter() - start) / size)
        return per_call

    return statistics.median(asyncio.run(run()))


_BODY = b'{"q": [0.2, 1.0, 2.0]}'


def _fk_scope(path: str) -> dict:
    from planner_api.warmup import post_scope

    headers = [
        (b"host", b"localhost"),
        (b"content-type", b"application/json"),
        (b"content-length", str(len(_BODY)).encode()),
    ]
    return post_scope(path, headers)


def _cpu_per_request(app: Callable[..., Awaitable[None]], path: str, n: int) -> float:
    """Median thread CPU seconds per ``POST path`` of the fk body through ``app``, in
    batches of 100 (the first batches, its warm-up, dropped); every answer must be 200."""
    statuses: list[int] = []

    async def receive() -> dict:
        return {"type": "http.request", "body": _BODY, "more_body": False}

    async def send(message: dict) -> None:
        if message["type"] == "http.response.start":
            statuses.append(message["status"])

    async def run() -> list[float]:
        per_call = []
        for k in range(max(1, n // 100) + 3):  # at least one batch measured
            c0 = time.thread_time()
            for _ in range(100):
                await app(_fk_scope(path), receive, send)
            if k >= 3:
                per_call.append((time.thread_time() - c0) / 100)
        return per_call

    result = statistics.median(asyncio.run(run()))
    assert set(statuses) == {200}, set(statuses)
    return result


class _Body(BaseModel):
    q: list[float]


def _bare_app() -> Callable[..., Awaitable[None]]:
    """The floor: a bare FastAPI app validating the body into a model and echoing it."""
    bare = FastAPI()

    @bare.post("/echo")
    async def echo(body: _Body) -> dict:
        return {"q": body.q}

    return bare


def _service_app() -> Callable[..., Awaitable[None]]:
    """The service's app (no lifespan: fk runs in the event loop and needs no pool)."""
    from planner_api.app import create_app
    from planner_api.settings import Settings

    return create_app(Settings(workers=1), warm_up=False)


def _time_pair(
    a: Callable[[], object], b: Callable[[], object], n: int, batch: int = 200
) -> tuple[float, float]:
    """Median per-call time of ``a`` and of ``b``, measured in alternating batches."""
    per_call: tuple[list[float], list[float]] = ([], [])
    for _ in range(max(n // batch, 5)):
        for fn, out in ((a, per_call[0]), (b, per_call[1])):
            start = time.perf_counter()
            for _ in range(batch):
                fn()
            out.append((time.perf_counter() - start) / batch)
    return statistics.median(per_call[0]), statistics.median(per_call[1])


def main() -> None:
    print_machine()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=20000, help="requests per variant")
    args = parser.parse_args()

    handler = logging.StreamHandler(io.StringIO())
    handler.setFormatter(JsonFormatter())
    handler.addFilter(RequestIdFilter())
    logging.getLogger().addHandler(handler)
    logging.getLogger("api.access").setLevel(logging.INFO)

    observed = RequestObserver(_endpoint, metrics=Metrics(lambda: None, "bench"))
    _time_asgi(_endpoint, 2000), _time_asgi(observed, 2000)  # warm up
    bare = _time_asgi(_endpoint, args.n)
    wrapped = _time_asgi(observed, args.n)

    request = FKRequest(q=[0.2, 1.0, 2.0])
    jobs.fk(request)
    plain_job, measured_job = _time_pair(
        lambda: as_json(jobs.fk, request),
        lambda: run_measured(jobs.fk, request, request_id="bench-1"),
        args.n // 10,
    )

    bare_cpu = _cpu_per_request(_bare_app(), "/echo", args.n // 4)
    app_cpu = _cpu_per_request(_service_app(), "/v1/fk", args.n // 4)

    print(f"{'layer':<34} {'without us':>11} {'with us':>9} {'added us':>9} {'ratio':>6}")
    for name, a, b in [
        ("RequestObserver (ASGI, per req)", bare, wrapped),
        ("run_measured vs as_json (fk job)", plain_job, measured_job),
        ("service POST /v1/fk vs bare (CPU)", bare_cpu, app_cpu),
    ]:
        print(f"{name:<34} {a * 1e6:>11.2f} {b * 1e6:>9.2f} {(b - a) * 1e6:>9.2f} {b / a:>6.2f}")


if __name__ == "__main__":
    main()
