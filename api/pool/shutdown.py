"""The end of :class:`planner_api.pool.WorkerPool`: the drain (new jobs refused, the waits
still open ended after a grace) and the shutdown (the workers stopped, the jobs that finish in
the grace delivered, the template last). One part of the pool, in a module of its own (its
life cycle and jobs are :mod:`planner_api.pool.pool`, its watchdog
:mod:`planner_api.pool.watchdog`)."""

from __future__ import annotations

import asyncio
import collections
import logging
import pickle
import queue
import threading
import time
from multiprocessing.connection import wait as wait_for_any
from typing import Any

from planner_api.pool.handle import Job, Worker
from planner_api.pool.states import WorkerState
from planner_api.pool.template import WarmTemplate

__all__ = ["ShutdownMixin"]

logger = logging.getLogger("planner_api.pool")


class ShutdownMixin:
    """The drain and shutdown methods of :class:`planner_api.pool.WorkerPool` (its state is
    the pool's: these annotations name what they use)."""

    _closed: bool
    _stopping: bool
    _lock: threading.Lock
    _wake: threading.Condition
    _loop: asyncio.AbstractEventLoop | None
    _stop: asyncio.Future[None] | None
    _pending: collections.deque[Job]
    _workers: list[Worker]
    _spawn_requests: queue.Queue[Any]
    _supervisor: threading.Thread | None
    _watchdog: threading.Thread | None
    _template: WarmTemplate | None

    def _in_loop(self) -> bool:
        raise NotImplementedError

    def _detach(self, worker: Worker) -> bool:
        raise NotImplementedError

    def _take_answers(self, worker: Worker) -> bool | None:
        raise NotImplementedError

    def _on_exit(self, worker: Worker) -> None:
        raise NotImplementedError

    def drain(self, grace_s: float) -> None:
        """Begin a graceful stop (call in the event loop): refuse new jobs, and after
        ``grace_s`` seconds cancel the waits of the jobs still in flight
        (:class:`ShuttingDownError`)."""
        self._stopping = True
        asyncio.get_running_loop().call_later(max(grace_s, 0.0), self._end_waits)

    def _end_waits(self) -> None:
        """In the event loop: end the waits still in flight (:class:`ShuttingDownError`)."""
        if self._stop is not None and not self._stop.done():
            self._stop.set_result(None)

    def shutdown(self, timeout_s: float | None = None) -> None:
        """Stop the workers; jobs not started are cancelled. Running jobs may finish for
        ``timeout_s`` seconds (None: wait for them), then their workers are terminated.

        Called in the pool's event loop (the lifespan's end) or once that loop stopped: it
        blocks the loop, and reads the workers' answers itself meanwhile, so that a job that
        finishes during the wait is answered and a worker writing a large answer is not
        stuck on its pipe."""
        loop = self._loop
        if loop is not None and not self._in_loop() and loop.is_running():
            raise RuntimeError("WorkerPool.shutdown() must run in the pool's event loop")
        self._stopping = True
        if self._in_loop():
            self._end_waits()
        elif self._loop is not None and not self._loop.is_closed():
            self._loop.call_soon_threadsafe(self._end_waits)
        with self._lock:
            waiting = list(self._pending)
        for job in waiting:
            job.future.cancel()  # its slot is freed by _unqueue
        with self._lock:
            workers = list(self._workers)
            self._closed = True
            self._wake.notify()
        for w in workers:
            if w.state is WorkerState.STARTING:
                w.process.terminate()  # nothing to lose: no job has reached it
            else:
                try:
                    w.jobs.send_bytes(pickle.dumps(("stop",)))
                except OSError:
                    pass
        end = None if timeout_s is None else time.monotonic() + timeout_s
        self._serve_until_exit(workers, end)
        alive = [w for w in workers if w.process.is_alive()]
        busy = [w for w in alive if w.warmed and w.state is not WorkerState.WARM]
        if busy:
            logger.warning("terminating %d worker(s) still busy at shutdown", len(busy))
        elif alive:  # idle or warming, slow to exit: nothing is lost
            logger.info("stopping %d idle worker(s) that had not exited yet", len(alive))
        if alive:
            for w in alive:
                w.process.terminate()
            for w in alive:
                w.process.join(5.0)
                if w.process.is_alive():  # pragma: no cover - a worker ignoring SIGTERM
                    w.process.kill()
                    w.process.join()
        for w in workers:  # the exits not seen yet: what they wrote first, then the exit
            if self._detach(w):
                while self._take_answers(w):
                    pass
            self._on_exit(w)  # once per worker: one never attached too, a handled one not again
        if self._template is not None:  # before the supervisor ends (its PDEATHSIG)
            self._template.stop()
        self._spawn_requests.put(None)
        if self._supervisor is not None:
            self._supervisor.join(5.0)
        if self._watchdog is not None:
            self._watchdog.join(5.0)

    def _serve_until_exit(self, workers: list[Worker], end: float | None) -> None:
        """At shutdown, with the event loop blocked: wait until ``workers`` have exited or
        ``end`` (monotonic; None: no end), handling their answers and exits as they come."""
        live = [w for w in workers if w.process.is_alive()]
        while live:
            timeout = None if end is None else end - time.monotonic()
            if timeout is not None and timeout <= 0:
                return
            reading = {w.answers.fileno(): w for w in workers if w.reading}
            sentinels = [w.process.sentinel for w in live]
            for ready in wait_for_any([*sentinels, *reading], timeout):
                # waited on ints only (the fds and the sentinels), so ``ready`` is one
                worker = reading.get(ready)  # type: ignore[arg-type]
                if worker is not None and self._take_answers(worker) is False:
                    self._detach(worker)
                    self._on_exit(worker)
            live = [w for w in live if w.process.is_alive()]
