"""How a request waits for its jobs in the worker pool (:class:`planner_api.pool.WorkerPool`):
the futures of its jobs, its deadline, its client's disconnect and the pool's drain, all at
once, in the event loop that reads the workers' answers."""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future
from typing import Any, TypeVar

from planner_api.exceptions import (
    ClientDisconnectedError,
    DeadlineExceededError,
    ShuttingDownError,
)

__all__ = ["wait_for_jobs"]

T = TypeVar("T")


async def wait_for_jobs(
    futures: Sequence[Future[T]],
    deadline: float,
    *,
    gone: asyncio.Future[None] | None,
    stop: asyncio.Future[None] | None,
    cancel: Callable[[Future[Any]], None],
    retry_after_s: int,
) -> list[T]:
    """The results of ``futures`` (in order), awaited in the event loop that sets them, until
    the first of: all done (or one failed: its error is raised), the ``deadline`` (a
    :func:`time.monotonic` value; :class:`DeadlineExceededError`), ``gone`` resolved (the
    client left; :class:`ClientDisconnectedError`, the jobs stopped with ``cancel``), ``stop``
    resolved (the drain's grace is over; :class:`ShuttingDownError`). A cancelled wait stops
    its jobs with ``cancel``. One loop future, callbacks and one timer: no task per wait,
    since the cheapest requests pay for every object made here."""
    loop = asyncio.get_running_loop()
    loop_thread = threading.get_ident()
    waiter: asyncio.Future[None] = loop.create_future()

    def wake(_: object = None) -> None:
        if not waiter.done():
            waiter.set_result(None)

    def job_done(_: Future[T]) -> None:
        # (a concurrent future's callbacks cannot be removed: this one outlives the wait
        # harmlessly, waking a future nobody awaits any more)
        if threading.get_ident() == loop_thread:
            wake()
        else:  # failed by the watchdog's kill, seen by an exit thread
            try:
                loop.call_soon_threadsafe(wake)
            except RuntimeError:  # pragma: no cover - the loop is closed
                pass

    watched = [w for w in (gone, stop) if w is not None]
    expired = False

    def expire() -> None:  # the deadline: a loop's timer may fire a little early
        nonlocal expired
        expired = True
        wake()

    timer = loop.call_at(loop.time() + (deadline - time.monotonic()), expire)
    for w in watched:
        w.add_done_callback(wake)
    for f in futures:
        f.add_done_callback(job_done)
    try:
        while True:
            if any(f.cancelled() for f in futures):  # dropped by a shutdown
                raise ShuttingDownError(
                    "the service is shutting down; retry (another replica)",
                    retry_after_s,
                )
            failed = next((f for f in futures if f.done() and f.exception() is not None), None)
            if failed is not None:  # the others run on; their answers are dropped
                raise failed.exception()  # type: ignore[misc]
            if all(f.done() for f in futures):
                return [f.result() for f in futures]
            if expired or time.monotonic() >= deadline:
                raise TimeoutError
            if gone is not None and gone.done():
                for f in futures:
                    cancel(f)
                raise ClientDisconnectedError("the client disconnected; its job was cancelled")
            if stop is not None and stop.done():
                for f in futures:
                    f.cancel()
                raise ShuttingDownError(
                    "the service is shutting down and this job's grace ran out; retry "
                    "(another replica)",
                    retry_after_s,
                )
            await waiter
            waiter = loop.create_future()
    except asyncio.CancelledError:
        for f in futures:  # nobody waits for these any more: free their workers now
            cancel(f)
        raise
    except TimeoutError as exc:
        # a job still running stops itself at its deadline; else its worker is
        # killed at the deadline plus the overrun grace (the watchdog)
        for f in futures:
            f.cancel()
        raise DeadlineExceededError(
            "the request's time budget ran out before the work finished"
        ) from exc
    finally:
        timer.cancel()
        for w in watched:
            w.remove_done_callback(wake)
