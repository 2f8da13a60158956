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

from api.exceptions import DeadlineExceededError, PoolSaturatedError, WorkerCrashedError

__all__ = ["WorkerPool"]

logger = logging.getLogger(__name__)

T = TypeVar("T")


def _init_worker() -> None:
    """Worker start-up: leave Ctrl-C to the parent, which shuts the pool down."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


#: ``(module, function)`` pairs a worker calls at start-up when the module exists, so that
#: numba kernels are compiled (or loaded from cache) before the first request, not during it.
WARM_UPS: tuple[tuple[str, str], ...] = (("planner.validity", "warm_up"),)


def _warm_up() -> bool:
    """Import the library, run one forward-kinematics call and every :data:`WARM_UPS`."""
    import importlib

    import numpy as np

    from planner import Design, forward_batch

    forward_batch(Design.default(), np.zeros((1, 3)), "+")
    for module_name, function in WARM_UPS:
        try:
            module = importlib.import_module(module_name)
        except ImportError:
            continue
        getattr(module, function)()
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
    """

    def __init__(self, workers: int, queue_size: int, *, retry_after_s: int = 1) -> None:
        if workers < 1 or queue_size < 0:
            raise ValueError("workers must be >= 1 and queue_size >= 0")
        self.workers = workers
        self.capacity = workers + queue_size
        self.retry_after_s = retry_after_s
        self._lock = threading.Lock()
        self._in_flight = 0
        self._executor: ProcessPoolExecutor | None = None
        self._warm: asyncio.Task[None] | None = None
        self._state: Literal["starting", "ready", "broken"] = "starting"

    # ------------------------------------------------------------------ life cycle
    def _new_executor(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_init_worker,
        )

    async def start(self) -> None:
        """Create the processes and warm them up in the background (see :attr:`state`)."""
        self._executor = self._new_executor()
        self._warm = asyncio.create_task(self._warm_up())

    async def _warm_up(self) -> None:
        executor = self._executor
        assert executor is not None
        try:
            futures = [executor.submit(_warm_up) for _ in range(self.workers)]
            await asyncio.gather(*(asyncio.wrap_future(f) for f in futures))
            self._state = "ready"
            logger.info("worker pool ready: %d processes", self.workers)
        except Exception:
            self._state = "broken"
            logger.exception("worker pool failed to start")

    def shutdown(self) -> None:
        """Stop the workers; jobs not started are cancelled."""
        if self._warm is not None:
            self._warm.cancel()
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)
            self._executor = None

    @property
    def state(self) -> Literal["starting", "ready", "broken"]:
        """'starting' until every worker answered once, then 'ready'."""
        return self._state

    @property
    def in_flight(self) -> int:
        """Jobs submitted and not finished (running or waiting)."""
        with self._lock:
            return self._in_flight

    # ------------------------------------------------------------------ jobs
    def _reserve(self, n: int) -> None:
        with self._lock:
            if self._in_flight + n > self.capacity:
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
        try:
            if remaining <= 0:
                raise TimeoutError
            return await asyncio.wait_for(
                asyncio.gather(*(asyncio.wrap_future(f) for f in futures)), remaining
            )
        except TimeoutError as exc:
            for f in futures:
                f.cancel()
            raise DeadlineExceededError(
                "the request's time budget ran out before the work finished"
            ) from exc
        except BrokenProcessPool as exc:
            if self._executor is not None and getattr(self._executor, "_broken", False):
                self._rebuild()
            raise WorkerCrashedError("a worker process died; the pool was restarted") from exc

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
