"""The pool of worker processes that runs the CPU-bound work (kinematics, analysis, planning).

Why processes: OMPL's ``solve()`` and most numpy work hold the GIL, so threads would serialise
the requests. The event loop only parses, dispatches and answers; each job is a module-level
function (picklable) run in a ``spawn``-started worker, so requests are served on all cores.

Back-pressure: at most ``workers + queue_size`` jobs are in flight (running or waiting); a job
beyond that is refused at once with :class:`PoolSaturatedError` (HTTP 503 + Retry-After), so a
burst never builds an unbounded queue. A job that outlives the request's deadline raises
:class:`DeadlineExceededError` (HTTP 504); a job that has not started yet is cancelled, one
that is running finishes in its worker (its result is dropped) and keeps its slot until then.
A worker that dies (e.g. a crash in native code) breaks the pool: it is rebuilt and the job
raises :class:`WorkerCrashedError` (HTTP 502).

Graceful shutdown (:mod:`api.server`): on SIGTERM, :meth:`WorkerPool.drain` turns the pool to
'stopping' (``/v1/ready`` answers 503, new jobs get :class:`ShuttingDownError`, 503) and gives
the jobs in flight until the grace deadline to finish; those still waiting for their result
then are cancelled with :class:`ShuttingDownError` (a clean 503 the client may retry on
another replica). :meth:`WorkerPool.shutdown` (the lifespan's end) then stops the workers,
terminating any still busy after ``timeout_s``.
"""

from __future__ import annotations

import asyncio
import logging
import multiprocessing
import signal
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Literal, TypeVar

from api.exceptions import (
    DeadlineExceededError,
    PoolSaturatedError,
    ShuttingDownError,
    WorkerCrashedError,
)

__all__ = ["WorkerPool"]

logger = logging.getLogger(__name__)

T = TypeVar("T")


def _init_worker(log_setup: tuple[str, str] | None = None) -> None:
    """Worker start-up: leave Ctrl-C and SIGTERM to the parent, which shuts the pool down;
    log like the parent (``(level, format)``, see :func:`api.logging.configure_logging`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if log_setup is not None:
        from api.logging import configure_logging

        configure_logging(*log_setup)  # type: ignore[arg-type]


def _warm_up() -> bool:
    """Compile or load every numba kernel (:func:`planner.warmup.warm_up`), so that the first
    request's budget is not spent compiling."""
    from planner.warmup import warm_up

    warm_up()
    return True


class WorkerPool:
    """A bounded pool of ``workers`` processes.

    Parameters
    ----------
    workers : int
        Worker processes (>= 1).
    queue_size : int
        Jobs allowed to wait for a free worker (>= 0).
    retry_after_s : int
        Seconds advertised to a refused caller.
    log_setup : (level, format) or None
        How the workers log (:func:`api.logging.configure_logging`); None: Python's default.
    """

    def __init__(
        self,
        workers: int,
        queue_size: int,
        *,
        retry_after_s: int = 1,
        log_setup: tuple[str, str] | None = None,
    ) -> None:
        if workers < 1 or queue_size < 0:
            raise ValueError("workers must be >= 1 and queue_size >= 0")
        self.workers = workers
        self.capacity = workers + queue_size
        self.retry_after_s = retry_after_s
        self._lock = threading.Lock()
        self._in_flight = 0
        self._executor: ProcessPoolExecutor | None = None
        self._warm: asyncio.Task[None] | None = None
        self._state: Literal["starting", "ready", "broken", "stopping"] = "starting"
        self._log_setup = log_setup
        #: Jobs refused because the pool was full (a counter for the metrics).
        self.rejected = 0
        self._stop: asyncio.Event | None = None

    # ------------------------------------------------------------------ life cycle
    def _new_executor(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_init_worker,
            initargs=(self._log_setup,),
        )

    async def start(self) -> None:
        """Create the processes and warm them up in the background (see :attr:`state`)."""
        self._executor = self._new_executor()
        self._stop = asyncio.Event()
        self._warm = asyncio.create_task(self._warm_up())

    async def _warm_up(self) -> None:
        executor = self._executor
        assert executor is not None
        try:
            futures = [executor.submit(_warm_up) for _ in range(self.workers)]
            await asyncio.gather(*(asyncio.wrap_future(f) for f in futures))
            if self._state == "stopping":
                return
            self._state = "ready"
            logger.info("worker pool ready: %d processes", self.workers)
        except Exception:
            self._state = "broken"
            logger.exception("worker pool failed to start")

    def drain(self, grace_s: float) -> None:
        """Begin a graceful stop (call in the event loop): refuse new jobs, and after
        ``grace_s`` seconds cancel the waits of the jobs still in flight
        (:class:`ShuttingDownError`)."""
        self._state = "stopping"
        stop = self._stop
        if stop is not None:
            asyncio.get_running_loop().call_later(max(grace_s, 0.0), stop.set)

    def shutdown(self, timeout_s: float | None = None) -> None:
        """Stop the workers; jobs not started are cancelled. Running jobs may finish for
        ``timeout_s`` seconds (None: wait for them), then their workers are terminated."""
        self._state = "stopping"
        if self._warm is not None:
            self._warm.cancel()
        if self._stop is not None:
            self._stop.set()
        executor, self._executor = self._executor, None
        if executor is None:
            return
        if timeout_s is None:
            executor.shutdown(wait=True, cancel_futures=True)
            return
        processes = list((getattr(executor, "_processes", None) or {}).values())
        executor.shutdown(wait=False, cancel_futures=True)
        end = time.monotonic() + timeout_s
        for p in processes:
            p.join(max(end - time.monotonic(), 0.0))
        busy = [p for p in processes if p.is_alive()]
        if busy:
            logger.warning("terminating %d worker(s) still busy at shutdown", len(busy))
            for p in busy:
                p.terminate()
            for p in busy:
                p.join(5.0)
                if p.is_alive():  # pragma: no cover - a worker ignoring SIGTERM
                    p.kill()
                    p.join()
        executor.shutdown(wait=True)  # every worker has exited: reap the executor's thread

    @property
    def state(self) -> Literal["starting", "ready", "broken", "stopping"]:
        """'starting' until every worker answered once, then 'ready'; 'stopping' once a
        shutdown began."""
        return self._state

    @property
    def in_flight(self) -> int:
        """Jobs submitted and not finished (running or waiting)."""
        with self._lock:
            return self._in_flight

    # ------------------------------------------------------------------ jobs
    def _reserve(self, n: int) -> None:
        if self._state == "stopping":
            raise ShuttingDownError(
                "the service is shutting down; retry (another replica)", self.retry_after_s
            )
        with self._lock:
            if self._in_flight + n > self.capacity:
                self.rejected += n
                raise PoolSaturatedError(
                    f"all {self.workers} workers are busy and the queue is full "
                    f"({self._in_flight} jobs in flight, capacity {self.capacity})",
                    self.retry_after_s,
                )
            self._in_flight += n

    def _release(self, _future: Future[Any] | None = None) -> None:
        with self._lock:
            self._in_flight -= 1

    def _submit(self, fn: Callable[..., T], arg: Any) -> Future[T]:
        if self._executor is None:
            raise RuntimeError("the worker pool is not started")
        try:
            future = self._executor.submit(fn, arg)
        except BrokenProcessPool as exc:
            self._release()
            self._rebuild()
            raise WorkerCrashedError("a worker process died; the pool was restarted") from exc
        except Exception as exc:  # e.g. a worker process that cannot be started
            self._release()
            logger.exception("could not hand a job to the worker pool")
            raise WorkerCrashedError(f"could not start a worker process: {exc}") from exc
        future.add_done_callback(self._release)
        return future

    def _rebuild(self) -> None:
        logger.error("worker pool broken (a worker died); restarting it")
        old, self._executor = self._executor, self._new_executor()
        if old is not None:
            old.shutdown(wait=False, cancel_futures=True)

    async def _await(self, futures: Sequence[Future[T]], deadline: float) -> list[T]:
        remaining = deadline - time.monotonic()
        results = asyncio.gather(*(asyncio.wrap_future(f) for f in futures))
        stop = asyncio.ensure_future(self._stop.wait()) if self._stop is not None else None
        try:
            if remaining <= 0:
                raise TimeoutError
            waits = {results} if stop is None else {results, stop}
            await asyncio.wait(waits, timeout=remaining, return_when=asyncio.FIRST_COMPLETED)
            if results.done():
                return results.result()
            if stop is not None and stop.done():
                for f in futures:
                    f.cancel()
                raise ShuttingDownError(
                    "the service is shutting down and this job's grace ran out; retry "
                    "(another replica)",
                    self.retry_after_s,
                )
            raise TimeoutError
        except (TimeoutError, asyncio.CancelledError) as exc:
            for f in futures:
                f.cancel()
            if isinstance(exc, asyncio.CancelledError):
                raise
            raise DeadlineExceededError(
                "the request's time budget ran out before the work finished"
            ) from exc
        except BrokenProcessPool as exc:
            if self._executor is not None and getattr(self._executor, "_broken", False):
                self._rebuild()
            raise WorkerCrashedError("a worker process died; the pool was restarted") from exc
        finally:
            if stop is not None:
                stop.cancel()
            if not results.done():
                results.cancel()
                # the gather's outcome is dropped: retrieve it so asyncio does not warn
                results.add_done_callback(lambda r: r.cancelled() or r.exception())

    async def run(self, fn: Callable[[Any], T], arg: Any, *, deadline: float) -> T:
        """``fn(arg)`` in a worker, by ``deadline`` (a :func:`time.monotonic` value).

        ``fn`` must be a module-level function and ``arg`` picklable. Exceptions raised by
        ``fn`` are re-raised here with their attributes.
        """
        self._reserve(1)
        future = self._submit(fn, arg)
        return (await self._await([future], deadline))[0]

    async def map(self, fn: Callable[[Any], T], args: Sequence[Any], *, deadline: float) -> list[T]:
        """``[fn(a) for a in args]`` spread over the workers, results in order. All slots are
        reserved at once: either every job is accepted or none (503)."""
        self._reserve(len(args))
        futures: list[Future[T]] = []
        try:
            for a in args:
                futures.append(self._submit(fn, a))
        except WorkerCrashedError:
            for _ in range(len(args) - len(futures) - 1):
                self._release()
            for f in futures:
                f.cancel()
            raise
        return await self._await(futures, deadline)
