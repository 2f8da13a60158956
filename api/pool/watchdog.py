"""The watchdog of :class:`planner_api.pool.WorkerPool`: the thread that kills the worker of
a cancelled job at once and of a job past its deadline once it has spent the overrun grace of
CPU time (or the overrun maximum of wall time) there, so that no job outlives its deadline
whatever it computes. One part of the pool, in a module of its own (the pool's life cycle and
its jobs are :mod:`planner_api.pool.pool`, its shutdown :mod:`planner_api.pool.shutdown`)."""

from __future__ import annotations

import logging
import threading
import time

from planner_api.pool.handle import Job, Worker, cpu_seconds
from planner_api.pool.states import WorkerEvent, WorkerState

__all__ = ["WatchdogMixin", "default_overrun_max"]

logger = logging.getLogger("planner_api.pool")

#: Longest sleep of the watchdog thread between two looks at the busy workers, s (it wakes
#: earlier for the next job's look time and whenever a job starts or is cancelled).
WATCHDOG_IDLE_S = 5.0


def default_overrun_max(grace_s: float) -> float:
    """``PLANNER_OVERRUN_MAX_S`` when it is not set: the larger of 5 s and twice the grace."""
    return max(5.0, 2.0 * grace_s)


class WatchdogMixin:
    """The watchdog's methods of :class:`planner_api.pool.WorkerPool` (its state is the
    pool's: these annotations name what they use)."""

    kills: int
    overrun_grace_s: float
    overrun_max_s: float
    _closed: bool
    _wake: threading.Condition
    _watch_at: float
    _workers: list[Worker]

    def _watch(self) -> None:
        """The watchdog thread: kill every worker whose job is past its kill time (its
        deadline plus the overrun grace, or now once the job is cancelled), so that no job
        outlives its deadline by more than the grace whatever it computes (a native loop, a
        search without deadline checks). The event loop then sees the exit and the
        supervisor starts a replacement (warmed before it takes jobs). The pool's close
        gets one last look: a job cancelled just before a shutdown (a stopping service's
        long jobs, cancelled by its job store) has its worker killed then, where the shutdown
        would otherwise wait its whole grace for a job nobody waits for."""
        with self._wake:
            while True:
                now = time.monotonic()
                wake_at = now + WATCHDOG_IDLE_S
                for w in self._workers:
                    job = w.job
                    if w.state is not WorkerState.BUSY or job is None or job.kill_at is None:
                        continue
                    if job.kill_at <= now:
                        self._look_locked(w, job, now)
                    if job.kill_at is not None and w.state is WorkerState.BUSY:
                        wake_at = min(wake_at, job.kill_at)
                if self._closed:
                    return
                self._watch_at = wake_at
                self._wake.wait(max(wake_at - time.monotonic(), 0.001))

    def _look_locked(self, worker: Worker, job: Job, now: float) -> None:
        """The watchdog's look at a job whose look time came (the caller holds the lock): a
        cancelled job's worker is killed; one past its deadline has its CPU time read at the
        first look, and is killed once it has spent ``overrun_grace_s`` of CPU since, or at
        the deadline plus ``overrun_max_s`` whatever it spent (the next look is when the
        rest of its grace could be spent at the soonest)."""
        if job.kill_reason != "deadline" or job.deadline is None:
            self._kill_locked(worker, job.kill_reason, now - job.kill_at)  # type: ignore[operator]
            return
        hard = job.deadline + self.overrun_max_s
        pid = worker.process.pid
        cpu = None if pid is None else cpu_seconds(pid)
        if job.cpu_at_deadline is None and cpu is not None and now < hard:
            job.cpu_at_deadline = cpu
            job.kill_at = min(now + self.overrun_grace_s, hard)
            return
        used = None if cpu is None or job.cpu_at_deadline is None else cpu - job.cpu_at_deadline
        if used is None or used >= self.overrun_grace_s or now >= hard:
            self._kill_locked(worker, "deadline", now - job.deadline)
            return
        job.kill_at = min(now + self.overrun_grace_s - used, hard)

    def _kill_locked(self, worker: Worker, reason: str, late_s: float) -> None:
        """SIGKILL ``worker`` (the caller holds the lock); its exit is expected."""
        worker.change(WorkerEvent.KILL)
        worker.killed = reason
        self.kills += 1
        try:
            worker.process.kill()
        except (OSError, ValueError):  # pragma: no cover - it exited meanwhile
            pass
        if reason == "deadline":
            logger.warning(
                "worker %s stopped: its job ran past its deadline (%.2f s after it); starting "
                "a replacement",
                worker.process.pid,
                late_s,
            )
        else:
            logger.warning(
                "worker %s stopped: its job was cancelled (%.2f s after the cancel); starting "
                "a replacement",
                worker.process.pid,
                late_s,
            )
