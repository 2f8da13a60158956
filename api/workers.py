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
burst never builds an unbounded queue.

No job outlives its deadline: a caller whose deadline passes gets
:class:`DeadlineExceededError` (HTTP 504) at once; a job that has not started yet is dropped,
one that is running stops itself (the jobs check their deadline in every long loop) or, if it
is still running ``overrun_grace_s`` after its deadline, the watchdog thread kills its worker
(SIGKILL) and a replacement is started, warmed before it takes jobs. A cancelled wait (the
caller's task cancelled, or its client disconnected: :data:`CLIENT_GONE`) kills the worker of
its running job at once (:meth:`WorkerPool.cancel`): a worker never computes an answer nobody
will read.

Memory given back: after each job a worker reports its resident memory; above ``max_rss_mb``
it is recycled: a replacement is started and warmed while the old worker still serves, then
the old one stops (after its current job). Python and numpy keep the memory of large answers
in their allocators; a new process is the one sure way to return it to the machine.

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
import contextvars
import logging
import multiprocessing
import os
import pickle
import queue
import signal
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Any, Literal, TypeVar

from planner_api.exceptions import (
    ClientDisconnectedError,
    DeadlineExceededError,
    JobCancelledError,
    PoolSaturatedError,
    ShuttingDownError,
    WorkerCrashedError,
)
from planner_api.worker_process import worker_main

__all__ = ["CLIENT_GONE", "PoolState", "WorkerPool"]

logger = logging.getLogger(__name__)

T = TypeVar("T")
PoolState = Literal["starting", "ready", "recovering", "broken", "stopping"]

#: Seconds between two attempts to replace a worker whose start or warm-up failed.
RESPAWN_BACKOFF_S = 2.0
#: Seconds between two progress lines while workers warm up (a first start, compiling the
#: numba kernels, takes tens of seconds after "Uvicorn running": not in silence).
WARMING_REPORT_S = 10.0
#: Longest sleep of the watchdog thread between two looks at the busy workers, s (it wakes
#: earlier for the next job's kill time and whenever a job starts or is cancelled).
WATCHDOG_IDLE_S = 5.0

#: Set (by :func:`planner_api.deps.watch_client`) while a request is served: an event that
#: is set when its client disconnects. A job awaited under it is cancelled then (its worker
#: stopped), so that no worker keeps computing an answer nobody will read.
CLIENT_GONE: contextvars.ContextVar[asyncio.Event | None] = contextvars.ContextVar(
    "planner_client_gone", default=None
)


# ---------------------------------------------------------------------- the parent side
@dataclass(eq=False)
class _Job:
    payload: bytes
    future: Future[Any]
    #: When the watchdog stops the worker still running this job (a :func:`time.monotonic`
    #: value: the deadline plus the overrun grace, or now for a cancelled job); None: never.
    kill_at: float | None = None
    #: Why it would be stopped: "deadline" or "cancelled".
    kill_reason: str = "deadline"


@dataclass(eq=False)
class _Worker:
    process: multiprocessing.process.BaseProcess
    conn: Connection
    #: "retired": told to stop (recycled), its exit is not a death to replace.
    state: Literal["warming", "idle", "busy", "retired", "dead"] = "warming"
    job: _Job | None = None
    started: float = field(default_factory=time.monotonic)
    reader: threading.Thread | None = field(default=None, repr=False)
    #: Why the pool killed it ("" while it was not killed): its exit is then expected.
    killed: str = ""
    #: Over the memory bound: serves on until its replacement is warm, then retires.
    retiring: bool = False
    #: Its replacement is warm: it retires after the job it is running.
    retire_after_job: bool = False
    #: The retiring worker this one replaces (stopped once this one is warm).
    replaces: _Worker | None = field(default=None, repr=False)
    #: Resident memory after its last job, bytes (None: not known yet).
    rss: int | None = None


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
    overrun_grace_s : float
        A job still running this long after its deadline has its worker killed (SIGKILL)
        and replaced (``PLANNER_OVERRUN_GRACE_S``).
    max_rss_mb : float or None
        A worker whose resident memory after a job exceeds this is recycled: a replacement
        is started, and once it is warm the old worker stops (``PLANNER_WORKER_MAX_RSS_MB``;
        None: never).
    """

    def __init__(
        self,
        workers: int,
        queue_size: int,
        *,
        retry_after_s: int = 1,
        log_setup: tuple[str, str] | None = None,
        warm_up: Callable[[], object] | None = None,
        overrun_grace_s: float = 0.5,
        max_rss_mb: float | None = None,
    ) -> None:
        if workers < 1 or queue_size < 0:
            raise ValueError("workers must be >= 1 and queue_size >= 0")
        if not overrun_grace_s >= 0.0 or (max_rss_mb is not None and not max_rss_mb > 0):
            raise ValueError("overrun_grace_s must be >= 0 and max_rss_mb > 0 (or None)")
        self.workers = workers
        self.capacity = workers + queue_size
        self.retry_after_s = retry_after_s
        self.overrun_grace_s = overrun_grace_s
        self.max_rss_bytes = None if max_rss_mb is None else int(max_rss_mb * 1024 * 1024)
        #: Jobs refused because the pool was full (a counter for the metrics).
        self.rejected = 0
        #: Workers that died and were replaced (a counter for the metrics).
        self.restarts = 0
        #: Workers killed because their job overran its deadline or was cancelled.
        self.kills = 0
        #: Workers recycled because their memory exceeded ``max_rss_mb``.
        self.recycles = 0
        self._log_setup = log_setup
        self._warm_up = warm_up
        self._ctx = multiprocessing.get_context("spawn")
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)  # the watchdog's: a kill time changed
        #: When the watchdog wakes next (monotonic): a job whose kill time is later needs no
        #: wake-up, which spares the server a thread switch per job.
        self._watch_at = float("inf")  # not waiting yet: every kill time is news
        self._in_flight = 0
        self._pending: collections.deque[_Job] = collections.deque()
        self._workers: list[_Worker] = []
        self._spawn_requests: queue.Queue[tuple[float, _Worker | None] | None] = queue.Queue()
        self._supervisor: threading.Thread | None = None
        self._watchdog: threading.Thread | None = None
        self._started = False
        self._stopping = False
        self._closed = False  # the watchdog's stop (it keeps watching during a drain)
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
        self._watchdog = threading.Thread(target=self._watch, name="job-watchdog", daemon=True)
        self._watchdog.start()
        for _ in range(self.workers):
            self._spawn_requests.put((0.0, None))

    def _supervise(self) -> None:
        """Spawn every worker, from this one long-lived thread (``PR_SET_PDEATHSIG`` fires
        when the *thread* that spawned a process ends)."""
        while True:
            try:
                request = self._spawn_requests.get(timeout=WARMING_REPORT_S)
            except queue.Empty:
                self._report_warming()
                continue
            if request is None or self._stopping:
                return
            delay, replaces = request
            if delay > 0:
                time.sleep(delay)
                if self._stopping:
                    return
            try:
                self._spawn(replaces)
            except Exception:
                logger.exception("could not start a worker process; retrying")
                self._failed = True
                self._spawn_requests.put((RESPAWN_BACKOFF_S, replaces))

    def _watch(self) -> None:
        """The watchdog thread: kill every worker whose job is past its kill time (its
        deadline plus the overrun grace, or now once the job is cancelled), so that no job
        outlives its deadline by more than the grace whatever it computes (a native loop, a
        search without deadline checks). The reader thread then sees the exit and the
        supervisor starts a replacement (warmed before it takes jobs)."""
        with self._wake:
            while not self._closed:
                now = time.monotonic()
                wake_at = now + WATCHDOG_IDLE_S
                for w in self._workers:
                    job = w.job
                    if w.state != "busy" or job is None or job.kill_at is None or w.killed:
                        continue
                    if job.kill_at <= now:
                        self._kill_locked(w, job.kill_reason, now - job.kill_at)
                    else:
                        wake_at = min(wake_at, job.kill_at)
                self._watch_at = wake_at
                self._wake.wait(max(wake_at - time.monotonic(), 0.001))

    def _kill_locked(self, worker: _Worker, reason: str, late_s: float) -> None:
        """SIGKILL ``worker`` (the caller holds the lock); its exit is expected."""
        worker.killed = reason
        self.kills += 1
        try:
            worker.process.kill()
        except (OSError, ValueError):  # pragma: no cover - it exited meanwhile
            pass
        what = "ran past its deadline" if reason == "deadline" else "was cancelled"
        logger.warning(
            "worker %s stopped: its job %s (%.2f s after its kill time); starting a replacement",
            worker.process.pid, what, late_s,
        )  # fmt: skip

    def _report_warming(self) -> None:
        """Log how many workers are warm while some still warm up (every WARMING_REPORT_S;
        under the lock, so that no such line follows the one saying a worker is warm)."""
        with self._lock:
            warming = [w.started for w in self._workers if w.state == "warming"]
            warm = sum(w.state in ("idle", "busy") for w in self._workers)
            if warming and not self._stopping:
                since = time.monotonic() - min(warming)
                logger.info("%d of %d workers warm after %.1f s", warm, self.workers, since)

    def _spawn(self, replaces: _Worker | None = None) -> None:
        parent_conn, child_conn = self._ctx.Pipe(duplex=True)
        process = self._ctx.Process(
            target=worker_main,
            args=(child_conn, os.getpid(), self._log_setup, self._warm_up),
            name="planner-worker",
            daemon=True,
        )
        process.start()
        child_conn.close()
        worker = _Worker(process=process, conn=parent_conn, replaces=replaces)
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
                elif kind == "rss":
                    self._on_rss(worker, value)
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
            old, worker.replaces = worker.replaces, None
            if old is not None and old.state == "idle":
                self._retire_locked(old)
            elif old is not None and old.state == "busy":
                old.retire_after_job = True
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
            self._in_flight -= 1
            if worker.retire_after_job:
                self._retire_locked(worker)
            elif worker.state == "busy":
                worker.state = "idle"
            self._dispatch_locked()
        if job is not None and not job.future.done():
            if kind == "ok":
                job.future.set_result(value)
            else:
                job.future.set_exception(value)

    def _on_rss(self, worker: _Worker, rss: int | None) -> None:
        """A worker's memory after its job: over the bound, it is recycled (a replacement
        is started now; the old worker serves on until the replacement is warm)."""
        with self._lock:
            worker.rss = rss
            over = self.max_rss_bytes is not None and rss is not None and rss > self.max_rss_bytes
            if not over or worker.retiring or worker.state not in ("idle", "busy"):
                return
            if self._stopping:
                return
            worker.retiring = True
            self.recycles += 1
        logger.info(
            "worker %s holds %.0f MB after its job (more than PLANNER_WORKER_MAX_RSS_MB = %.0f):"
            " recycling it once a replacement is warm",
            worker.process.pid, rss / 2**20, self.max_rss_bytes / 2**20,  # type: ignore[operator]
        )  # fmt: skip
        self._spawn_requests.put((0.0, worker))

    def _retire_locked(self, worker: _Worker) -> None:
        """Tell a recycled worker to stop (the caller holds the lock; it holds no job)."""
        worker.state = "retired"
        try:
            worker.conn.send_bytes(pickle.dumps(("stop",)))
        except OSError:  # it died meanwhile: its reader handles the exit
            pass

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
            # a recycled worker was replaced already; one that was retiring has its
            # replacement warming, one that was killed is replaced now
            replace = not self._stopping and was != "retired" and not worker.retiring
            if replace and not worker.killed:
                self.restarts += 1
            self._dispatch_locked()
            self._wake.notify()
        worker.conn.close()
        if job is not None and not job.future.done():
            job.future.set_exception(self._exit_error(worker, exit_text))
        if was == "retired":
            logger.info("worker %d recycled (%s)", worker.process.pid, exit_text)
        elif replace and not worker.killed:
            logger.error(
                "worker %d died (%s) while %s; starting a replacement",
                worker.process.pid,
                exit_text,
                "running a job" if job is not None else was,
            )
        if replace:
            self._spawn_requests.put((RESPAWN_BACKOFF_S if was == "warming" else 0.0, None))

    @staticmethod
    def _exit_error(worker: _Worker, exit_text: str) -> Exception:
        """What the job of a worker that exited fails with."""
        if worker.killed == "deadline":
            return DeadlineExceededError("the job ran past its deadline and its worker was stopped")
        if worker.killed:
            return JobCancelledError("the job was cancelled and its worker stopped")
        return WorkerCrashedError(
            f"the worker process running this job died ({exit_text}); a new worker is starting"
        )

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
                if not job.future.set_running_or_notify_cancel():
                    # cancelled during the hand-over: nobody waits for it, stop it now
                    job.kill_at, job.kill_reason = time.monotonic(), "cancelled"
                worker.state, worker.job = "busy", job
                if job.kill_at is not None and job.kill_at < self._watch_at:
                    self._wake.notify()  # due before the watchdog's next look
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
            self._closed = True
            self._wake.notify()
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
        if self._watchdog is not None:
            self._watchdog.join(5.0)

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
        """Worker processes alive and warm (idle or busy; not one being killed)."""
        with self._lock:
            return sum(w.state in ("idle", "busy") and not w.killed for w in self._workers)

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

    def _enqueue(self, fn: Callable[..., T], arg: Any, deadline: float | None) -> Future[T]:
        """Queue a job whose slot is reserved; the slot is freed if it cannot be queued."""
        try:
            payload = pickle.dumps(("job", fn, arg))
        except Exception:
            with self._lock:
                self._in_flight -= 1
            raise
        future: Future[T] = Future()
        kill_at = None if deadline is None else deadline + self.overrun_grace_s
        with self._lock:
            self._pending.append(_Job(payload, future, kill_at))
            self._dispatch_locked()
        return future

    def submit(
        self, fn: Callable[[Any], T], arg: Any, *, deadline: float | None = None
    ) -> Future[T]:
        """``fn(arg)`` in a worker, as a :class:`concurrent.futures.Future` (from any
        thread). Raises :class:`PoolSaturatedError` when the pool is full. With a
        ``deadline`` (a :func:`time.monotonic` value), a job still running
        ``overrun_grace_s`` after it has its worker killed (the future then fails with
        :class:`DeadlineExceededError`) and replaced."""
        self._reserve(1)
        return self._enqueue(fn, arg, deadline)

    def cancel(self, future: Future[Any]) -> None:
        """Cancel a job: one still waiting is dropped, one running has its worker killed
        now (the future fails with :class:`JobCancelledError`) and replaced."""
        if future.cancel():
            return
        with self._lock:
            for w in self._workers:
                if w.job is not None and w.job.future is future and w.state == "busy":
                    w.job.kill_at, w.job.kill_reason = time.monotonic(), "cancelled"
                    self._wake.notify()

    async def _await(self, futures: Sequence[Future[T]], deadline: float) -> list[T]:
        remaining = deadline - time.monotonic()
        results = asyncio.gather(*(asyncio.wrap_future(f) for f in futures))
        waits: set[asyncio.Future[Any]] = {results}
        stop = asyncio.ensure_future(self._stop.wait()) if self._stop is not None else None
        gone_event = CLIENT_GONE.get()
        gone = asyncio.ensure_future(gone_event.wait()) if gone_event is not None else None
        waits |= {w for w in (stop, gone) if w is not None}
        try:
            if remaining <= 0:
                raise TimeoutError
            await asyncio.wait(waits, timeout=remaining, return_when=asyncio.FIRST_COMPLETED)
            if results.done():
                return results.result()
            if gone is not None and gone.done():
                for f in futures:
                    self.cancel(f)
                raise ClientDisconnectedError("the client disconnected; its job was cancelled")
            if stop is not None and stop.done():
                for f in futures:
                    f.cancel()
                raise ShuttingDownError(
                    "the service is shutting down and this job's grace ran out; retry "
                    "(another replica)",
                    self.retry_after_s,
                )
            raise TimeoutError
        except asyncio.CancelledError:
            for f in futures:  # nobody waits for these any more: free their workers now
                self.cancel(f)
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
            for w in (stop, gone):
                if w is not None:
                    w.cancel()
            if not results.done():
                results.cancel()
                # the gather's outcome is dropped: retrieve it so asyncio does not warn
                results.add_done_callback(lambda r: r.cancelled() or r.exception())

    async def run(self, fn: Callable[[Any], T], arg: Any, *, deadline: float) -> T:
        """``fn(arg)`` in a worker, by ``deadline`` (a :func:`time.monotonic` value).

        ``fn`` must be a module-level function and ``arg`` picklable. Exceptions raised by
        ``fn`` are re-raised here with their attributes. Past the deadline the caller gets
        :class:`DeadlineExceededError` at once; the job, if it is still running
        ``overrun_grace_s`` later, has its worker killed. A cancelled wait (the caller's task
        cancelled, or its client gone: :data:`CLIENT_GONE`) kills its worker at once.
        """
        future = self.submit(fn, arg, deadline=deadline)
        return (await self._await([future], deadline))[0]

    async def map(self, fn: Callable[[Any], T], args: Sequence[Any], *, deadline: float) -> list[T]:
        """``[fn(a) for a in args]`` spread over the workers, results in order. All slots are
        reserved at once: either every job is accepted or none (503). Deadlines and
        cancellation as in :meth:`run`."""
        self._reserve(len(args))
        futures: list[Future[T]] = []
        try:
            for a in args:
                futures.append(self._enqueue(fn, a, deadline))
        except Exception:
            with self._lock:
                self._in_flight -= len(args) - len(futures) - 1
            for f in futures:
                f.cancel()
            raise
        return await self._await(futures, deadline)
