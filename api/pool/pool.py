"""The pool of worker processes that runs the CPU-bound work (plans, timing, analysis).

What it promises an operator (warm means ready, a crash stays with its request, no job
outlives its deadline, memory given back, no orphans, the drain) is told in
docs/operations.md, "Worker processes"; here is why it is built so.

Processes, because OMPL's ``solve()`` and most numpy work hold the GIL. Not
:class:`concurrent.futures.ProcessPoolExecutor`, because when one of its workers dies it breaks
*as a whole* and fails every job in flight: this pool is a small supervisor instead, one job
per worker at a time, so a worker that dies fails only its own job
(:class:`WorkerCrashedError`, HTTP 502 naming the exit) and is replaced. Every worker is a
fork of one warm template (:mod:`planner_api.pool.template`, which runs ``warm_up``, the
service's :func:`planner_api.warmup.start_worker`, once), so a replacement is warm in
milliseconds; where fork cannot be had each worker is ``spawn``-started and warms up itself
before it takes jobs. The template (or each spawned worker) is started by one supervisor
thread that lives as long as the pool (``PR_SET_PDEATHSIG`` fires when the thread that
spawned the process ends).

Two one-way pipes per worker. Jobs go down one, pickled; answers come back on the other in
frames (:func:`planner_api.pool.process.send_frame`) that the event loop reads itself
(``loop.add_reader``, non-blocking): no reader thread to wake, no hand-over of the GIL, no
second wake-up of the loop per job. So the pool lives in one event loop (:meth:`WorkerPool.start`
runs in it), which delivers its results: code in the loop awaits them (:meth:`WorkerPool.run`,
:meth:`WorkerPool.map`, ``asyncio.wrap_future`` of :meth:`WorkerPool.submit`); only another
thread may block on a submitted future.

A worker's life is one table (:mod:`planner_api.pool.states`: starting, warm, busy, killing,
gone): the pool moves a worker only through it, and a move it does not hold is an internal
error, not a silent change.

Bounds: at most ``workers + queue_size`` jobs in flight (beyond: :class:`PoolSaturatedError`,
503 + Retry-After, never an unbounded queue). A caller past its deadline gets
:class:`DeadlineExceededError` at once; its job, if still running ``overrun_grace_s`` later,
has its worker killed by the watchdog thread and replaced. A cancelled wait (the caller's task,
or its client gone: :data:`CLIENT_GONE`) kills its worker at once. A worker over
``max_rss_mb`` after a job is recycled, its replacement warm first. :meth:`WorkerPool.drain`
(SIGTERM, :mod:`planner_api.server`) refuses new jobs and ends the waits still open after the
grace (:class:`ShuttingDownError`); :meth:`WorkerPool.shutdown` stops the workers.
"""

from __future__ import annotations

import asyncio
import collections
import contextvars
import functools
import logging
import multiprocessing
import os
import pickle
import queue
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future
from multiprocessing.connection import Connection
from typing import Any, Literal, TypeVar

from planner_api.exceptions import (
    DeadlineExceededError,
    JobCancelledError,
    PoolSaturatedError,
    ShuttingDownError,
    WorkerCrashedError,
)
from planner_api.pool.handle import RECYCLED, Job, Worker, describe_exit
from planner_api.pool.process import worker_main
from planner_api.pool.shutdown import ShutdownMixin
from planner_api.pool.states import WorkerEvent, WorkerState
from planner_api.pool.template import (
    TemplateError,
    WarmTemplate,
    templates_work,
    widen_pipe,
)
from planner_api.pool.wait import wait_for_jobs
from planner_api.pool.watchdog import WatchdogMixin, default_overrun_max

__all__ = ["CLIENT_GONE", "PoolState", "WorkerPool", "default_overrun_max"]

logger = logging.getLogger("planner_api.pool")

T = TypeVar("T")
PoolState = Literal["starting", "ready", "recovering", "broken", "stopping"]

#: Seconds between two attempts to replace a worker whose start or warm-up failed.
RESPAWN_BACKOFF_S = 2.0
#: Seconds between two progress lines while workers warm up (a first start, compiling the
#: numba kernels, takes tens of seconds after "Uvicorn running": not in silence).
WARMING_REPORT_S = 10.0
#: Most bytes taken from a worker's answer pipe per turn of the event loop: what a pipe holds
#: (a large answer arrives over several turns, other requests are served between; a larger
#: buffer would be an mmap and munmap per read).
READ_CHUNK = 1 << 16

#: Set (by :func:`planner_api.deps.watch_client`) while a request is served: a future that
#: is resolved when its client disconnects. A job awaited under it is cancelled then (its
#: worker stopped), so that no worker keeps computing an answer nobody will read.
CLIENT_GONE: contextvars.ContextVar[asyncio.Future[None] | None] = contextvars.ContextVar(
    "planner_client_gone", default=None
)


class WorkerPool(WatchdogMixin, ShutdownMixin):
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
        passes :func:`planner_api.warmup.start_worker`: the caches sized, then the warm-up).
        None: no warm-up.
    overrun_grace_s : float
        A job that has spent this much CPU time past its deadline and still runs has its
        worker killed (SIGKILL) and replaced (``PLANNER_OVERRUN_GRACE_S``): CPU time, so that a
        job starved of CPU on a busy machine is not killed for the machine's load.
    overrun_max_s : float or None
        A job still running this long (wall time) after its deadline is killed whatever CPU
        it spent (``PLANNER_OVERRUN_MAX_S``; at least ``overrun_grace_s``; None: the larger of
        5 s and twice the grace).
    nice : int
        Added to each worker's niceness (``PLANNER_WORKER_NICE``): the event loop then runs
        when it has work instead of waiting behind a worker for the scheduler's turn.
    max_rss_mb : float or None
        A worker whose resident memory after a job exceeds this is recycled: a replacement
        is started, and once it is warm the old worker stops (``PLANNER_WORKER_MAX_RSS_MB``;
        None: never).
    template : bool
        Fork every worker from a warm template process (:mod:`planner_api.pool.template`),
        which runs ``warm_up`` once: a replacement is warm in milliseconds. False, or a
        platform without ``fork`` and pidfds: each worker is spawned and warms up itself.
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
        overrun_max_s: float | None = None,
        max_rss_mb: float | None = None,
        nice: int = 0,
        template: bool = True,
    ) -> None:
        if workers < 1 or queue_size < 0:
            raise ValueError("workers must be >= 1 and queue_size >= 0")
        if not overrun_grace_s >= 0.0 or (max_rss_mb is not None and not max_rss_mb > 0):
            raise ValueError("overrun_grace_s must be >= 0 and max_rss_mb > 0 (or None)")
        if overrun_max_s is None:
            overrun_max_s = default_overrun_max(overrun_grace_s)
        if not overrun_max_s >= overrun_grace_s:
            raise ValueError("overrun_max_s must be at least overrun_grace_s")
        self.workers = workers
        self.capacity = workers + queue_size
        self.retry_after_s = retry_after_s
        self.overrun_grace_s = overrun_grace_s
        self.overrun_max_s = overrun_max_s
        self.max_rss_bytes = None if max_rss_mb is None else int(max_rss_mb * 1024 * 1024)
        self.nice = nice
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
        #: The warm template the workers are forked from (None: each worker is spawned).
        self._template: WarmTemplate | None = None
        if template and templates_work():
            self._template = WarmTemplate(self._ctx, log_setup, warm_up, self.max_rss_bytes, nice)
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)  # the watchdog's: a kill time changed
        #: When the watchdog wakes next (monotonic): a later kill time needs no wake-up.
        self._watch_at = float("inf")  # not waiting yet: every kill time is news
        self._in_flight = 0
        self._pending: collections.deque[Job] = collections.deque()
        self._workers: list[Worker] = []
        self._spawn_requests: queue.Queue[tuple[float, Worker | None] | None] = queue.Queue()
        self._supervisor: threading.Thread | None = None
        self._watchdog: threading.Thread | None = None
        self._started = False
        self._stopping = False
        self._closed = False  # the watchdog's stop (it keeps watching during a drain)
        self._was_ready = False
        self._failed = False
        self._loop: asyncio.AbstractEventLoop | None = None
        self._loop_thread: int | None = None
        #: Resolved when the waits still in flight must end (the drain's grace ran out).
        self._stop: asyncio.Future[None] | None = None

    # ------------------------------------------------------------------ life cycle
    async def start(self) -> None:
        """Spawn the processes; they warm up in the background (see :attr:`state`). The
        pool then belongs to this event loop, which reads the workers' answers."""
        if self._started:
            return
        self._started = True
        self._loop = asyncio.get_running_loop()
        self._loop_thread = threading.get_ident()
        self._stop = self._loop.create_future()
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
                if self._loop is not None and self._loop.is_closed():
                    self._loop_gone()  # closed after a spawn handed it a worker to attach
                    return
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
                if self._stopping:
                    return
                logger.exception("could not start a worker process; retrying")
                self._failed = True
                self._spawn_requests.put((RESPAWN_BACKOFF_S, replaces))

    def _report_warming(self) -> None:
        """Log how many workers are warm while some (or their template) still warm up (every
        WARMING_REPORT_S; under the lock, so that no such line follows the one saying a worker
        is warm)."""
        template = self._template
        with self._lock:
            warming = [w.started for w in self._workers if w.state is WorkerState.STARTING]
            if template is not None and template.state == "warming":
                warming.append(template.started)
            warm = sum(w.warmed for w in self._workers)
            if warming and not self._stopping:
                since = time.monotonic() - min(warming)
                logger.info("%d of %d workers warm after %.1f s", warm, self.workers, since)

    def _spawn(self, replaces: Worker | None = None) -> None:
        """Start one worker (forked from the warm template, or spawned) and hand it to the
        event loop."""
        if self._template is not None:
            process, jobs_fd, answers_fd = self._fork()
            jobs_in = Connection(jobs_fd, readable=False, writable=True)
            answers_out = Connection(answers_fd, readable=True, writable=False)
            self._add(Worker(process, jobs=jobs_in, answers=answers_out, replaces=replaces))
            return
        jobs_out, jobs_in = self._ctx.Pipe(duplex=False)  # (reader, writer)
        answers_out, answers_in = self._ctx.Pipe(duplex=False)
        for end in (jobs_in, answers_in):
            widen_pipe(end.fileno())
        process = self._ctx.Process(
            target=worker_main,
            args=(
                jobs_out,
                answers_in,
                os.getpid(),
                self._log_setup,
                self._warm_up,
                self.max_rss_bytes,
                self.nice,
            ),
            name="planner-worker",
            daemon=True,
        )
        try:
            process.start()
        except BaseException:
            jobs_in.close()
            answers_out.close()
            raise
        finally:
            jobs_out.close()
            answers_in.close()
        self._add(Worker(process=process, jobs=jobs_in, answers=answers_out, replaces=replaces))

    def _fork(self) -> tuple[Any, int, int]:
        """A worker forked from the warm template (in the supervisor thread): the template is
        started first if it is not running (and waited for while it warms up, with progress
        lines); :class:`TemplateError` when it cannot warm up or fork."""
        template = self._template
        assert template is not None
        if self._stopping:  # no new template once a shutdown began
            raise TemplateError("the pool is stopping")
        if template.state in ("failed", "gone"):
            if template.state == "gone":
                logger.error("the worker template exited; starting a new one (it warms up)")
            template.stop()
            template = self._template = WarmTemplate(self._ctx, *template.args)
        if template.state == "new":
            template.start()
        try:
            while not template.wait_warm(WARMING_REPORT_S):
                if self._stopping:
                    raise TemplateError("the pool is stopping")
                self._report_warming()
        except TemplateError:
            self._failed = True
            raise
        return template.fork()

    def _add(self, worker: Worker) -> None:
        """Register a started worker and let the event loop read its answers."""
        with self._lock:
            closed = self._closed
            if not closed:
                self._workers.append(worker)
        if closed:  # shut down while it started: no one would stop it or close its pipes
            worker.process.kill()
            worker.process.join()
            worker.change(WorkerEvent.EXIT)
            worker.close()
            return
        os.set_blocking(worker.answers.fileno(), False)
        assert self._loop is not None
        try:
            self._loop.call_soon_threadsafe(self._attach, worker)
        except RuntimeError:  # the loop is closed: the pool is gone with it, replace no one
            self._loop_gone()

    def _loop_gone(self) -> None:
        """The event loop closed without a shutdown: nothing reads the workers any more. The
        pool stops; its workers are killed and reaped (their pipes closed), none replaced."""
        self._stopping = True
        with self._lock:
            workers = list(self._workers)
            waiting = list(self._pending)
            self._closed = True  # the watchdog stops; a spawn under way kills its worker
            self._wake.notify()
        for job in waiting:
            job.future.cancel()  # no worker will take it: a thread waiting on it is told
        for w in workers:
            w.process.kill()
        # here, in the supervisor thread (its only caller), before it ends: the template
        # dies with it (PDEATHSIG), and it reports its workers' exits, so it goes last
        for w in workers:
            self._on_exit(w)
        if self._template is not None:
            self._template.stop()

    def _in_loop(self) -> bool:
        return threading.get_ident() == self._loop_thread

    def _attach(self, worker: Worker) -> None:
        """In the event loop: read ``worker``'s answers as they come."""
        assert self._loop is not None
        if worker.answers.closed or self._closed:  # shut down before it was attached
            return
        worker.reading = True
        self._loop.add_reader(worker.answers.fileno(), self._readable, worker)

    def _readable(self, worker: Worker) -> None:
        """In the event loop, when ``worker``'s answer pipe has bytes (or is closed): take
        them, handle each whole frame; at the end of the pipe (the worker exited), detach
        and handle the exit in a thread (it waits for the process to be reaped)."""
        if self._take_answers(worker) is False:
            self._detach(worker)
            threading.Thread(
                target=self._on_exit, args=(worker,), name="worker-exit", daemon=True
            ).start()

    def _take_answers(self, worker: Worker) -> bool | None:
        """Read what ``worker``'s answer pipe holds (one chunk) and handle each whole frame:
        True when bytes came, None when there were none yet, False at the end of the pipe."""
        try:
            chunk = os.read(worker.answers.fileno(), READ_CHUNK)
        except BlockingIOError:  # a spurious wake-up, or (at shutdown) nothing more yet
            return None
        except OSError:
            chunk = b""
        if not chunk:
            return False
        for message in worker.take(chunk):
            self._handle(worker, message)
        return True

    def _detach(self, worker: Worker) -> bool:
        """Stop the event loop reading ``worker``'s answers (in the loop's thread); whether
        it was reading (its end of pipe not yet seen)."""
        if not worker.reading:
            return False
        worker.reading = False
        try:
            assert self._loop is not None
            self._loop.remove_reader(worker.answers.fileno())
        except (OSError, RuntimeError, ValueError):  # the loop is closed: nothing to remove
            pass
        return True

    def _handle(self, worker: Worker, message: bytes) -> None:
        """One message of a worker (:mod:`planner_api.pool.process`)."""
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

    def _on_ready(self, worker: Worker, seconds: float) -> None:
        with self._lock:
            worker.change(WorkerEvent.READY)
            old, worker.replaces = worker.replaces, None
            if old is not None and old.state is WorkerState.WARM:
                self._retire_locked(old)
            elif old is not None and old.warmed:  # busy, or killed with its answer to come
                old.retire_after_job = True
            warm = sum(w.warmed for w in self._workers)
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

    def _on_done(self, worker: Worker, kind: str, value: Any) -> None:
        with self._lock:
            worker.change(WorkerEvent.DONE)  # a killed one stays killing: it takes no job
            job, worker.job = worker.job, None
            self._in_flight -= 1
            if worker.retire_after_job:
                self._retire_locked(worker)
            self._dispatch_locked()
        if job is not None and not job.future.done():
            if kind == "ok":
                job.future.set_result(value)
            else:
                job.future.set_exception(value)

    def _on_rss(self, worker: Worker, rss: int) -> None:
        """A worker's memory after its job, over the bound (the worker says nothing under
        it): it is recycled (a replacement is started now; the old worker serves on until
        the replacement is warm)."""
        with self._lock:
            worker.rss = rss
            if worker.retiring or not worker.warmed:
                return
            if self._stopping:
                return
            worker.retiring = True
            self.recycles += 1
        logger.info(
            "worker %s holds %.0f MB after its job (more than PLANNER_WORKER_MAX_RSS_MB = %.0f):"
            " recycling it once a replacement is warm",
            worker.process.pid,
            rss / 2**20,
            self.max_rss_bytes / 2**20,  # type: ignore[operator]
        )
        self._spawn_requests.put((0.0, worker))

    def _retire_locked(self, worker: Worker) -> None:
        """Tell a recycled worker to stop (the caller holds the lock; it holds no job)."""
        worker.change(WorkerEvent.RETIRE)
        worker.killed = RECYCLED
        try:
            worker.jobs.send_bytes(pickle.dumps(("stop",)))
        except OSError:  # it died meanwhile: the end of its answer pipe is its exit
            pass

    def _on_exit(self, worker: Worker) -> None:
        with self._lock:
            if worker.exit_claimed:  # handled already (a shutdown and an exit thread both)
                return
            worker.exit_claimed = True
        worker.process.join(5.0)
        exit_text = describe_exit(worker.process.exitcode)
        with self._lock:
            job, worker.job = worker.job, None
            was = worker.change(WorkerEvent.EXIT)
            if worker in self._workers:
                self._workers.remove(worker)
            if job is not None:
                self._in_flight -= 1
            # a recycled worker was replaced already; one that was retiring has its
            # replacement warming, one that was killed is replaced now
            recycled = was is WorkerState.KILLING and worker.killed == RECYCLED
            replace = not self._stopping and not recycled and not worker.retiring
            if replace and not worker.killed:
                self.restarts += 1
            self._dispatch_locked()
            self._wake.notify()
        worker.close()
        if job is not None and not job.future.done():
            job.future.set_exception(self._exit_error(worker, exit_text))
        if recycled:
            logger.info("worker %d recycled (%s)", worker.process.pid, exit_text)
        elif replace and not worker.killed:
            logger.error(
                "worker %d died (%s) while %s; starting a replacement",
                worker.process.pid,
                exit_text,
                "running a job" if job is not None else was.value,
            )
        if replace:
            backoff = RESPAWN_BACKOFF_S if was is WorkerState.STARTING else 0.0
            self._spawn_requests.put((backoff, None))

    @staticmethod
    def _exit_error(worker: Worker, exit_text: str) -> Exception:
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
        for worker in [w for w in self._workers if w.state is WorkerState.WARM]:
            while self._pending:
                job = self._pending.popleft()
                if job.future.cancelled():
                    self._in_flight -= 1
                    continue
                try:
                    worker.jobs.send_bytes(job.payload)
                except OSError:  # the worker just died (its exit is seen): next one
                    self._pending.appendleft(job)
                    worker.change(WorkerEvent.LOST)
                    break
                if not job.future.set_running_or_notify_cancel():
                    # cancelled during the hand-over: nobody waits for it, stop it now
                    job.kill_at, job.kill_reason = time.monotonic(), "cancelled"
                worker.change(WorkerEvent.TAKE)
                worker.job = job
                if job.kill_at is not None and job.kill_at < self._watch_at:
                    self._wake.notify()  # due before the watchdog's next look
                break
            if not self._pending:
                return

    @property
    def state(self) -> PoolState:
        """'ready' once every configured worker was warm, and then while at least one is
        (a killed worker's replacement, forked warm, takes milliseconds: a load balancer
        should not drop a replica that can serve); 'starting' before the first time,
        'recovering' while no worker is warm after that, 'broken' when no worker is warm and
        none can be started or warmed up, 'stopping' once a shutdown began."""
        if self._stopping:
            return "stopping"
        warm = self.warm_workers
        if warm >= self.workers or (warm > 0 and self._was_ready):
            return "ready"
        if self._failed:
            return "broken"
        return "recovering" if self._was_ready else "starting"

    @property
    def warm_workers(self) -> int:
        """Worker processes alive and warm (warm or busy; not one being killed)."""
        with self._lock:
            return sum(w.state in (WorkerState.WARM, WorkerState.BUSY) for w in self._workers)

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
        job = Job(payload, future, kill_at=deadline, deadline=deadline)
        with self._lock:
            self._pending.append(job)
            self._dispatch_locked()
        future.add_done_callback(functools.partial(self._unqueue, job))
        return future

    def _unqueue(self, job: Job, future: Future[Any]) -> None:
        """A job's future is done: if it was cancelled while it waited, its slot is free at
        once (not when a worker would have taken it: with none warm, the queue would fill
        with jobs nobody waits for)."""
        if future.cancelled():
            with self._lock:
                if job in self._pending:
                    self._pending.remove(job)
                    self._in_flight -= 1

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
                if w.job is not None and w.job.future is future and w.state is WorkerState.BUSY:
                    w.job.kill_at, w.job.kill_reason = time.monotonic(), "cancelled"
                    self._wake.notify()

    async def _await(self, futures: Sequence[Future[T]], deadline: float) -> list[T]:
        return await wait_for_jobs(
            futures,
            deadline,
            gone=CLIENT_GONE.get(),
            stop=self._stop,
            cancel=self.cancel,
            retry_after_s=self.retry_after_s,
        )

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
