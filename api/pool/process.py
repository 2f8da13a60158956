"""The worker side of :mod:`planner_api.pool.pool`: the loop of one worker process.

A worker warms up, says so, then runs one job at a time until told to stop (or until its pipe
closes: the parent is gone). After each job it measures its resident memory (RSS, once the
job's answer is sent and released) and, when that exceeds the pool's bound
(``PLANNER_WORKER_MAX_RSS_MB``), says so, and the pool recycles it: a worker that keeps memory
it no longer uses is replaced. Under the bound it says nothing: one message per job.

Two one-way pipes. Parent to worker, :class:`multiprocessing.connection.Connection` messages
(pickled tuples): ``("job", fn, arg)`` and ``("stop",)``. Worker to parent, frames of
:func:`send_frame` (an 8-byte big-endian length, then a pickled tuple), which the parent's
event loop reads without blocking (:mod:`planner_api.pool.pool`): ``("ready", warm_up_s)``,
``("warm_failed", traceback)``, ``("ok", value)`` or ``("error", exception)`` (one per job),
and ``("rss", bytes)`` after a job that left the worker over the bound.
"""

from __future__ import annotations

import ctypes
import os
import pickle
import select
import signal
import struct
import sys
import threading
import time
import traceback
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

__all__ = [
    "FRAME_HEADER",
    "PARENT_WATCH_S",
    "die_with_parent",
    "forked_main",
    "resident_bytes",
    "send_frame",
    "serve_jobs",
    "set_up_child",
    "worker_main",
]

#: Seconds between two checks of a worker that its parent is still alive (the portable
#: fallback of ``PR_SET_PDEATHSIG``).
PARENT_WATCH_S = 0.5
_PR_SET_PDEATHSIG = 1
#: The header of a frame, worker to parent: the length of the pickled message that follows.
FRAME_HEADER = struct.Struct("!Q")


def send_frame(fd: int, data: bytes) -> None:
    """Write ``data`` (a pickled message) as one frame to the pipe ``fd``, blocking until all
    of it is written (the parent reads as the bytes come)."""
    header = FRAME_HEADER.pack(len(data))
    # a small answer in one write (one wake-up of the parent); a large one without a copy
    for part in (header + data,) if len(data) < 65536 else (header, data):
        view = memoryview(part)
        while view:
            view = view[os.write(fd, view) :]


#: (pid, descriptor) of this process's ``/proc/self/statm``, opened on first use: a worker
#: reads it after every job, and a ``pread`` of an open file costs ~2 us against ~18 us for an
#: open, read and close (measured on an AMD EPYC VM). The pid tells a forked child's copy.
_STATM: tuple[int, int] | None = None


def resident_bytes() -> int | None:
    """This process's resident memory now, bytes (``/proc/self/statm``; None where there is
    no such file). Not ``ru_maxrss``: that is the peak, which never comes down."""
    global _STATM
    for _ in range(2):  # a descriptor gone bad (closed by someone) is opened again, once
        try:
            if _STATM is None or _STATM[0] != os.getpid():
                if _STATM is not None:  # a forked child's copy reads its parent's file
                    os.close(_STATM[1])
                _STATM = (os.getpid(), os.open("/proc/self/statm", os.O_RDONLY | os.O_CLOEXEC))
            return int(os.pread(_STATM[1], 256, 0).split()[1]) * os.sysconf("SC_PAGE_SIZE")
        except OSError:
            _STATM = None
        except (ValueError, IndexError):  # pragma: no cover - not Linux's format
            return None
    return None  # pragma: no cover - no /proc here


def die_with_parent(parent_pid: int, *, watch: bool = True) -> None:
    """Exit when the parent does: SIGKILL from the kernel when the spawning thread ends
    (Linux), and (``watch``) a watcher thread that polls the parent's pid (everywhere; the
    warm template polls in its own loop instead: it forks, and forks from one thread)."""
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):  # pragma: no cover - no prctl in this libc
            pass
    if os.getppid() != parent_pid:  # the parent died before the prctl took effect
        os._exit(1)
    if not watch:
        return

    def poll_parent() -> None:
        while True:
            time.sleep(PARENT_WATCH_S)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=poll_parent, name="parent-watch", daemon=True).start()


def worker_main(
    jobs: Connection,
    answers: Connection,
    parent_pid: int,
    log_setup: tuple[str, str] | None,
    warm_up: Callable[[], object] | None,
    max_rss_bytes: int | None = None,
    nice: int = 0,
) -> None:
    """A worker process started on its own (``spawn``): warm up, say so, then run one job at
    a time until told to stop (or until the pipe closes: the parent is gone). ``jobs`` brings
    the jobs, ``answers`` (its file descriptor, written with :func:`send_frame`) takes the
    answers back; after a job that leaves the worker above ``max_rss_bytes`` (None: no bound)
    it says so. ``nice`` lowers the priority of the thread that runs the jobs once the worker
    is warm: it warms at the server's priority, so that a start on a busy machine is not
    slowed further."""
    out = answers.fileno()
    set_up_child(parent_pid, log_setup)
    try:
        t0 = time.perf_counter()
        if warm_up is not None:
            warm_up()
        if nice > 0:
            os.nice(nice)
        send_frame(out, pickle.dumps(("ready", time.perf_counter() - t0)))
    except BaseException:
        send_frame(out, pickle.dumps(("warm_failed", traceback.format_exc())))
        return
    serve_jobs(jobs, out, max_rss_bytes)


def set_up_child(
    parent_pid: int, log_setup: tuple[str, str] | None, *, watch_parent: bool = True
) -> None:
    """What a process the pool starts (a worker, or the warm template) does first: die with
    its parent (:func:`die_with_parent`), leave Ctrl-C and SIGTERM to the parent (it ignores
    SIGINT and dies of SIGTERM, the pool's last resort at shutdown), and log as the server
    does (``log_setup``; None: Python's default)."""
    die_with_parent(parent_pid, watch=watch_parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if log_setup is not None:
        from planner_api.logging import configure_logging

        configure_logging(*log_setup)  # type: ignore[arg-type]


def forked_main(jobs_fd: int, answers_fd: int, max_rss_bytes: int | None, nice: int) -> None:
    """A worker forked from the warm template (:mod:`planner_api.pool.template`): it is warm
    already (the template's memory is its own), so it says so at once and serves. It dies
    with the server, not with the template: a thread waits for the hang-up of the jobs pipe,
    whose only writer is the server (a template that dies leaves its workers serving)."""
    t0 = time.perf_counter()
    jobs = Connection(jobs_fd, readable=True, writable=False)
    _exit_on_hang_up(jobs_fd)
    if nice > 0:
        os.nice(nice)
    send_frame(answers_fd, pickle.dumps(("ready", time.perf_counter() - t0)))
    serve_jobs(jobs, answers_fd, max_rss_bytes)
    os._exit(0)


def _exit_on_hang_up(fd: int) -> None:
    """Exit the moment the write end of the pipe ``fd`` is closed everywhere (the server died:
    ``poll`` reports ``POLLHUP`` whatever events are asked, so an empty mask waits for it
    alone), even in the middle of a job."""

    def watch() -> None:
        poller = select.poll()
        poller.register(fd, 0)
        while True:
            for _, event in poller.poll():
                if event & (select.POLLHUP | select.POLLERR | select.POLLNVAL):
                    os._exit(1)

    threading.Thread(target=watch, name="server-watch", daemon=True).start()


def serve_jobs(jobs: Connection, out: int, max_rss_bytes: int | None) -> None:
    """Run one job at a time from ``jobs`` and answer each on the pipe ``out``, until told to
    stop (which exits the process) or until ``jobs`` closes (which returns)."""
    while True:
        try:
            message = pickle.loads(jobs.recv_bytes())
        except (EOFError, OSError):
            return
        if message[0] == "stop":
            # nothing to clean up (no job, no file): skip the interpreter's teardown of
            # numba, OMPL and matplotlib, which takes seconds on a loaded machine
            for stream in (sys.stdout, sys.stderr):
                stream.flush()
            os._exit(0)
        _, fn, arg = message
        del message
        try:
            outcome: tuple[str, Any] = ("ok", fn(arg))
        except BaseException as exc:
            outcome = ("error", exc)
        del arg
        try:
            data = pickle.dumps(outcome)
        except Exception as exc:  # an unpicklable result or exception
            data = pickle.dumps(
                ("error", RuntimeError(f"the job's {outcome[0]} could not be sent: {exc!r}"))
            )
        del outcome
        try:
            send_frame(out, data)
        except OSError:  # the parent is gone
            return
        del data  # the answer's memory is released before it is measured
        if max_rss_bytes is not None:
            rss = resident_bytes()
            if rss is not None and rss > max_rss_bytes:
                try:
                    send_frame(out, pickle.dumps(("rss", rss)))
                except OSError:  # the parent is gone
                    return
