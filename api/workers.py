"""The pool of worker processes that runs the CPU-bound work (kinematics, analysis, planning).

Why processes: OMPL's ``solve()`` and most numpy work hold the GIL, so threads would serialise
the requests. The event loop only parses, dispatches and answers; each job is a module-level
function (picklable) run in a ``spawn``-started worker, so requests are served on all cores.

Why not :class:`concurrent.futures.ProcessPoolExecutor`: when one of its workers dies it
breaks *as a whole* and fails every job in flight, also those on healthy workers. This pool
is a small supervisor instead: one duplex pipe per worker, one job per worker at a time, so
a worker that dies (a crash in native code, the OOM killer, SIGKILL) fails only the job it
was running (:class:`WorkerCrashedError`, HTTP 502 naming the exit); the others keep running
and a replacement is spawned and warmed in the background.

Warm means ready: a worker announces itself only after its ``warm_up`` function (the
service's :func:`planner_api.warmup.warm_up_worker`) has imported and run everything its jobs use, so
the first job on it costs what any later one costs. :attr:`WorkerPool.state` is ``"ready"`` (``/v1/ready`` 200)
only while every configured worker is warm; ``"starting"`` before the first time,
``"recovering"`` while a replacement warms up, ``"broken"`` when warm-up itself fails.

Workers die with their parent: each one asks the kernel for SIGKILL when the thread that
spawned it ends (``prctl(PR_SET_PDEATHSIG)``, Linux; all workers are spawned by one
supervisor thread that lives as long as the pool) and also watches its parent's pid, so no
worker outlives a killed server by more than a second.

Back-pressure: at most ``workers + queue_size`` jobs are in flight (running or waiting); a job
beyond that is refused at once with :class:`PoolSaturatedError` (HTTP 503 + Retry-After), so a
burst never builds an unbounded queue. A job that outlives the request's deadline raises
:class:`DeadlineExceededError` (HTTP 504); a job that has not started yet is cancelled, one
that is running finishes in its worker (its result is dropped) and keeps its slot until then.

Graceful shutdown (:mod:`planner_api.server`): on SIGTERM, :meth:`WorkerPool.drain` turns the pool to
'stopping' (``/v1/ready`` answers 503, new jobs get :class:`ShuttingDownError`, 503) and gives
the jobs in flight until the grace deadline to finish; those still waiting for their result
then are cancelled with :class:`ShuttingDownError` (a clean 503 the client may retry on
another replica). :meth:`WorkerPool.shutdown` (the lifespan's end) then stops the workers,
terminating any still busy after ``timeout_s``.
"""

from __future__ import annotations

import asyncio
import collections
import ctypes
import logging
import multiprocessing
import os
import pickle
import queue
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import Future
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Any, Literal, TypeVar

from planner_api.exceptions import (
    DeadlineExceededError,
    PoolSaturatedError,
    ShuttingDownError,
    WorkerCrashedError,
)

__all__ = ["PoolState", "WorkerPool"]

logger = logging.getLogger(__name__)

T = TypeVar("T")
PoolState = Literal["starting", "ready", "recovering", "broken", "stopping"]

#: Seconds between two attempts to replace a worker whose start or warm-up failed.
RESPAWN_BACKOFF_S = 2.0
#: Seconds between two progress lines while workers warm up (a first start, compiling the
#: numba kernels, takes tens of seconds after "Uvicorn running": not in silence).
WARMING_REPORT_S = 10.0
#: Seconds between two checks of a worker that its parent is still alive (the portable
#: fallback of ``PR_SET_PDEATHSIG``).
PARENT_WATCH_S = 0.5
_PR_SET_PDEATHSIG = 1


# ---------------------------------------------------------------------- the worker side
def _die_with_parent(parent_pid: int) -> None:
    """Exit when the parent does: SIGKILL from the kernel when the spawning thread ends
    (Linux), and a watcher thread that polls the parent's pid (everywhere)."""
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):  # pragma: no cover - no prctl in this libc
            pass
    if os.getppid() != parent_pid:  # the parent died before the prctl took effect
        os._exit(1)

    def watch() -> None:
        while True:
            time.sleep(PARENT_WATCH_S)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def _worker_main(
    conn: Connection,
    parent_pid: int,
    log_setup: tuple[str, str] | None,
    warm_up: Callable[[], object] | None,
) -> None:
    """A worker process: warm up, say so, then run one job at a time until told to stop
    (or until the pipe closes: the parent is gone)."""
    _die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C and SIGTERM are the parent's
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if log_setup is not None:
        from planner_api.logging import configure_logging

        configure_logging(*log_setup)  # type: ignore[arg-type]
    try:
        t0 = time.perf_counter()
        if warm_up is not None:
            warm_up()
        conn.send_bytes(pickle.dumps(("ready", time.perf_counter() - t0)))
    except BaseException:
        conn.send_bytes(pickle.dumps(("warm_failed", traceback.format_exc())))
        return
    while True:
        try:
            message = pickle.loads(conn.recv_bytes())
        except (EOFError, OSError):
            return
        if message[0] == "stop":
            # nothing to clean up (no job, no file): skip the interpreter's teardown of
            # numba, OMPL and matplotlib, which takes seconds on a loaded machine
            for stream in (sys.stdout, sys.stderr):
                stream.flush()
            os._exit(0)
        _, fn, arg = message
        try:
            outcome: tuple[str, Any] = ("ok", fn(arg))
        except BaseException as exc:
            outcome = ("error", exc)
        try:
            data = pickle.dumps(outcome)
        except Exception as exc:  # an unpicklable result or exception
            data = pickle.dumps(
                ("error", RuntimeError(f"the job's {outcome[0]} could not be sent: {exc!r}"))
            )
        conn.send_bytes(data)


# ---------------------------------------------------------------------- the parent side
@dataclass(eq=False)
class _Job:
    payload: bytes
    future: Future[Any]


@dataclass(eq=False)
class _Worker:
    process: multiprocessing.process.BaseProcess
    conn: Connection
    state: Literal["warming", "idle", "busy", "dead"] = "warming"
    job: _Job | None = None
    started: float = field(default_factory=time.monotonic)
    reader: threading.Thread | None = field(default=None, repr=False)


def _describe_exit(exitcode: int | None) -> str:
    if exitcode is None:
        return "exit status unknown"
    if exitcode < 0:
        try:
            return f"killed by {signal.Signals(-exitcode).name}"
        except ValueError:
            return f"killed by signal {-exitcode}"
    return f"exit code {exitcode}"


class WorkerPool:
    """A bounded pool of ``workers`` processes, one job per process at a time.

    Parameters
    ----------
    workers : int
        Worker processes (>= 1).
    queue_size : int
        Jobs allowed to wait for a free worker (>= 0).
    retry_after_s : int
        Seconds advertised to a refused caller.
    log_setup : (level, format) or None
        How the workers log (:func:`planner_api.logging.configure_logging`); None: Python's default.
    warm_up : callable or None
        Run in each new worker before it takes jobs (module-level, picklable; the service
        passes :func:`planner_api.warmup.warm_up_worker`). None: no warm-up.
    """

    def __init__(
        self,
        workers: int,
        queue_size: int,
        *,
        retry_after_s: int = 1,
        log_setup: tuple[str, str] | None = None,
        warm_up: Callable[[], object] | None = None,
    ) -> None:
        if workers < 1 or queue_size < 0:
            raise ValueError("workers must be >= 1 and queue_size >= 0")
        self.workers = workers
        self.capacity = workers + queue_size
        self.retry_after_s = retry_after_s
        #: Jobs refused because the pool was full (a counter for the metrics).
        self.rejected = 0
        #: Workers that died and were replaced (a counter for the metrics).
        self.restarts = 0
        self._log_setup = log_setup
        self._warm_up = warm_up
        self._ctx = multiprocessing.get_context("spawn")
        self._lock = threading.Lock()
        self._in_flight = 0
        self._pending: collections.deque[_Job] = collections.deque()
        self._workers: list[_Worker] = []
        self._spawn_requests: queue.Queue[float | None] = queue.Queue()
        self._supervisor: threading.Thread | None = None
        self._started = False
        self._stopping = False
        self._was_ready = False
        self._failed = False
        self._stop: asyncio.Event | None = None

    # ------------------------------------------------------------------ life cycle
    async def start(self) -> None:
        """Spawn the processes; they warm up in the background (see :attr:`state`)."""
        self.start_workers()
        self._stop = asyncio.Event()

    def start_workers(self) -> None:
        """Spawn the processes (from any thread; :meth:`start` in an event loop)."""
        if self._started:
            return
        self._started = True
        self._supervisor = threading.Thread(
            target=self._supervise, name="worker-supervisor", daemon=True
        )
        self._supervisor.start()
        for _ in range(self.workers):
            self._spawn_requests.put(0.0)

    def _supervise(self) -> None:
        """Spawn every worker, from this one long-lived thread (``PR_SET_PDEATHSIG`` fires
        when the *thread* that spawned a process ends)."""
        while True:
            try:
                delay = self._spawn_requests.get(timeout=WARMING_REPORT_S)
            except queue.Empty:
                self._report_warming()
                continue
            if delay is None or self._stopping:
                return
            if delay > 0:
                time.sleep(delay)
                if self._stopping:
                    return
            try:
                self._spawn()
            except Exception:
                logger.exception("could not start a worker process; retrying")
                self._failed = True
                self._spawn_requests.put(RESPAWN_BACKOFF_S)

    def _report_warming(self) -> None:
        """Log how many workers are warm while some still warm up (every WARMING_REPORT_S;
        under the lock, so that no such line follows the one saying a worker is warm)."""
        with self._lock:
            warming = [w.started for w in self._workers if w.state == "warming"]
            warm = sum(w.state in ("idle", "busy") for w in self._workers)
            if warming and not self._stopping:
                since = time.monotonic() - min(warming)
                logger.info("%d of %d workers warm after %.1f s", warm, self.workers, since)

    def _spawn(self) -> None:
        parent_conn, child_conn = self._ctx.Pipe(duplex=True)
        process = self._ctx.Process(
            target=_worker_main,
            args=(child_conn, os.getpid(), self._log_setup, self._warm_up),
            name="planner-worker",
            daemon=True,
        )
        process.start()
        child_conn.close()
        worker = _Worker(process=process, conn=parent_conn)
        worker.reader = threading.Thread(
            target=self._read, args=(worker,), name=f"worker-reader-{process.pid}", daemon=True
        )
        with self._lock:
            self._workers.append(worker)
        worker.reader.start()

    def _read(self, worker: _Worker) -> None:
        """Receive a worker's messages until its pipe closes (the worker exited)."""
        try:
            while True:
                message = worker.conn.recv_bytes()
                try:
                    kind, value = pickle.loads(message)
                except Exception as exc:  # e.g. an exception class the parent cannot import
                    kind, value = "error", RuntimeError(f"a job's answer was unreadable: {exc!r}")
                if kind == "ready":
                    self._on_ready(worker, value)
                elif kind == "warm_failed":
                    logger.error("a worker failed to warm up:\n%s", value)
                    self._failed = True
                else:
                    self._on_done(worker, kind, value)
        except (EOFError, OSError):
            pass
        self._on_exit(worker)

    def _on_ready(self, worker: _Worker, seconds: float) -> None:
        with self._lock:
            worker.state = "idle"
            warm = sum(w.state in ("idle", "busy") for w in self._workers)
            if warm >= self.workers:
                self._was_ready = True
                self._failed = False
            self._dispatch_locked()
        logger.info(
            "worker %d warm in %.1f s (%d of %d warm)",
            worker.process.pid,
            seconds,
            warm,
            self.workers,
        )

    def _on_done(self, worker: _Worker, kind: str, value: Any) -> None:
        with self._lock:
            job, worker.job = worker.job, None
            worker.state = "idle"
            self._in_flight -= 1
            self._dispatch_locked()
        if job is not None and not job.future.done():
            if kind == "ok":
                job.future.set_result(value)
            else:
                job.future.set_exception(value)

    def _on_exit(self, worker: _Worker) -> None:
        worker.process.join(5.0)
        exit_text = _describe_exit(worker.process.exitcode)
        with self._lock:
            job, worker.job = worker.job, None
            was = worker.state
            worker.state = "dead"
            if worker in self._workers:
                self._workers.remove(worker)
            if job is not None:
                self._in_flight -= 1
            replace = not self._stopping
            if replace:
                self.restarts += 1
            self._dispatch_locked()
        worker.conn.close()
        if job is not None and not job.future.done():
            job.future.set_exception(
                WorkerCrashedError(
                    f"the worker process running this job died ({exit_text}); "
                    "a new worker is starting"
                )
            )
        if replace:
            logger.error(
                "worker %d died (%s) while %s; starting a replacement",
                worker.process.pid,
                exit_text,
                "running a job" if job is not None else was,
            )
            self._spawn_requests.put(RESPAWN_BACKOFF_S if was == "warming" else 0.0)

    def _dispatch_locked(self) -> None:
        """Hand waiting jobs to idle workers (the caller holds the lock). A job cancelled
        while it waited is dropped; one cancelled during the hand-over still runs, and its
        result is dropped."""
        for worker in [w for w in self._workers if w.state == "idle"]:
            while self._pending:
                job = self._pending.popleft()
                if job.future.cancelled():
                    self._in_flight -= 1
                    continue
                try:
                    worker.conn.send_bytes(job.payload)
                except OSError:  # the worker just died (its reader will see it): next one
                    self._pending.appendleft(job)
                    worker.state = "dead"
                    break
                job.future.set_running_or_notify_cancel()
                worker.state, worker.job = "busy", job
                break
            if not self._pending:
                return

    def drain(self, grace_s: float) -> None:
        """Begin a graceful stop (call in the event loop): refuse new jobs, and after
        ``grace_s`` seconds cancel the waits of the jobs still in flight
        (:class:`ShuttingDownError`)."""
        self._stopping = True
        stop = self._stop
        if stop is not None:
            asyncio.get_running_loop().call_later(max(grace_s, 0.0), stop.set)

    def shutdown(self, timeout_s: float | None = None) -> None:
        """Stop the workers; jobs not started are cancelled. Running jobs may finish for
        ``timeout_s`` seconds (None: wait for them), then their workers are terminated."""
        self._stopping = True
        if self._stop is not None:
            self._stop.set()
        with self._lock:
            while self._pending:
                job = self._pending.popleft()
                if job.future.cancel():
                    self._in_flight -= 1
            workers = list(self._workers)
        for w in workers:
            if w.state == "warming":
                w.process.terminate()  # nothing to lose: no job has reached it
            else:
                try:
                    w.conn.send_bytes(pickle.dumps(("stop",)))
                except OSError:
                    pass
        end = None if timeout_s is None else time.monotonic() + timeout_s
        for w in workers:
            w.process.join(None if end is None else max(end - time.monotonic(), 0.0))
        alive = [w for w in workers if w.process.is_alive()]
        busy = [w for w in alive if w.state == "busy"]
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
        for w in workers:
            if w.reader is not None:
                w.reader.join(5.0)
        self._spawn_requests.put(None)
        if self._supervisor is not None:
            self._supervisor.join(5.0)

    @property
    def state(self) -> PoolState:
        """'ready' while every configured worker is warm; 'starting' before the first
        time, 'recovering' while a replacement warms up, 'broken' when a worker cannot be
        started or warmed up, 'stopping' once a shutdown began."""
        if self._stopping:
            return "stopping"
        if self.warm_workers >= self.workers:
            return "ready"
        if self._failed:
            return "broken"
        return "recovering" if self._was_ready else "starting"

    @property
    def warm_workers(self) -> int:
        """Worker processes alive and warm (idle or busy)."""
        with self._lock:
            return sum(w.state in ("idle", "busy") for w in self._workers)

    @property
    def pids(self) -> list[int]:
        """Process ids of the worker processes alive now (warm or warming)."""
        with self._lock:
            return [w.process.pid for w in self._workers if w.process.pid is not None]

    @property
    def in_flight(self) -> int:
        """Jobs submitted and not finished (running or waiting)."""
        with self._lock:
            return self._in_flight

    # ------------------------------------------------------------------ jobs
    def _reserve(self, n: int) -> None:
        if self._stopping:
            raise ShuttingDownError(
                "the service is shutting down; retry (another replica)", self.retry_after_s
            )
        if not self._started:
            raise RuntimeError("the worker pool is not started")
        with self._lock:
            if self._in_flight + n > self.capacity:
                self.rejected += n
                raise PoolSaturatedError(
                    f"all {self.workers} workers are busy and the queue is full "
                    f"({self._in_flight} jobs in flight, capacity {self.capacity})",
                    self.retry_after_s,
                )
            self._in_flight += n

    def _enqueue(self, fn: Callable[..., T], arg: Any) -> Future[T]:
        """Queue a job whose slot is reserved; the slot is freed if it cannot be queued."""
        try:
            payload = pickle.dumps(("job", fn, arg))
        except Exception:
            with self._lock:
                self._in_flight -= 1
            raise
        future: Future[T] = Future()
        with self._lock:
            self._pending.append(_Job(payload, future))
            self._dispatch_locked()
        return future

    def submit(self, fn: Callable[[Any], T], arg: Any) -> Future[T]:
        """``fn(arg)`` in a worker, as a :class:`concurrent.futures.Future` (from any
        thread). Raises :class:`PoolSaturatedError` when the pool is full."""
        self._reserve(1)
        return self._enqueue(fn, arg)

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
        future = self.submit(fn, arg)
        return (await self._await([future], deadline))[0]

    async def map(self, fn: Callable[[Any], T], args: Sequence[Any], *, deadline: float) -> list[T]:
        """``[fn(a) for a in args]`` spread over the workers, results in order. All slots are
        reserved at once: either every job is accepted or none (503)."""
        self._reserve(len(args))
        futures: list[Future[T]] = []
        try:
            for a in args:
                futures.append(self._enqueue(fn, a))
        except Exception:
            with self._lock:
                self._in_flight -= len(args) - len(futures) - 1
            for f in futures:
                f.cancel()
            raise
        return await self._await(futures, deadline)
