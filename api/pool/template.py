"""The warm template of :class:`planner_api.pool.WorkerPool`: one process that warms up once
and forks every worker, so that a replacement worker is warm the moment it exists.

Why: a worker is stopped by a kill (a cancelled job, a client gone, a job past its deadline,
a memory recycle) and a new one spawned from nothing needs the whole warm-up (the numba
kernels, OMPL's, toppra's and the service's first calls: 4-28 s measured on a loaded 2-core
machine), so one submit-and-cancel pair a second kept the pool cold. A fork of a warm process
costs milliseconds and shares its memory copy-on-write (``gc.freeze`` after the warm-up keeps
the collector from touching, and so copying, the template's objects in every worker).

Why a template of our own, not :mod:`multiprocessing`'s ``forkserver``: the forkserver is one
per interpreter, warmed only by importing modules (a warm-up would be an import's side
effect), and says nothing of its children's exits; here each pool has its template, which
runs the pool's own ``warm_up`` and reports each worker's exit status.

Why a kill stays the way a job is stopped (not a cooperative cancel): the library's deadline
checks compare a fixed deadline, and an exception raised into a running job could land in an
OMPL callback or half-way through a cache's update, leaving a reused worker in a state that
no test covers. A fresh fork of the template is both simpler to trust and now cheap.

The protocol, over one ``AF_UNIX`` ``SOCK_SEQPACKET`` pair (message boundaries kept, file
descriptors passed with the message): the server sends ``("fork", token)`` with the child's two
pipe ends (jobs to read, answers to write) or ``("stop",)``; the template answers ``("ready",
seconds)`` or ``("warm_failed", traceback)`` once, ``("forked", token, pid)`` or
``("fork_failed", token, error)`` per fork, and ``("exit", pid, wait_status)`` when a worker it
forked has exited (it reaps them, woken by ``SIGCHLD``). A worker forked so is a grandchild
of the server: :class:`ForkedProcess` gives the pool what it uses of a
:class:`multiprocessing.Process` through a pidfd (Linux >= 5.3), and the worker dies with the
server through its jobs pipe (:func:`planner_api.pool.process.forked_main`), not with the
template, so a template that dies leaves its workers serving (the pool starts a new one).
Where ``os.pidfd_open`` or ``os.fork`` is missing, the pool spawns every worker as before.
"""

from __future__ import annotations

import fcntl
import gc
import itertools
import logging
import os
import pickle
import select
import signal
import socket
import threading
import time
import traceback
from collections.abc import Callable
from multiprocessing.context import BaseContext
from typing import Any, Literal

from planner_api.pool.process import PARENT_WATCH_S, forked_main, set_up_child

__all__ = [
    "ForkedProcess",
    "TemplateError",
    "WarmTemplate",
    "template_main",
    "templates_work",
    "widen_pipe",
]

logger = logging.getLogger(__name__)

#: The largest control message, bytes (a warm-up's traceback is cut to fit).
MAX_MESSAGE = 1 << 16
#: How long a fork may take before the server gives up on the template, s.
FORK_TIMEOUT_S = 10.0
#: How long ``join`` waits for the template's report once the worker is known to be gone, s.
REPORT_WAIT_S = 2.0


#: The capacity asked for each worker pipe, bytes (Linux's default is 64 KiB; an unprivileged
#: process may ask up to ``/proc/sys/fs/pipe-max-size``, 1 MiB by default).
PIPE_BYTES = 1 << 20


def widen_pipe(fd: int) -> None:
    """Ask for a pipe of :data:`PIPE_BYTES` (where the system allows it): a job's body of
    megabytes is written in a few large steps instead of a hundred 64 KiB ones, each of which
    waits for the reader in the event loop's thread."""
    try:
        fcntl.fcntl(fd, fcntl.F_SETPIPE_SZ, PIPE_BYTES)
    except (OSError, AttributeError):  # not Linux, or above the system's bound: as it is
        pass


def templates_work() -> bool:
    """Whether this platform can fork workers from a template (``fork``, pidfds, fd passing),
    tried, not only looked up: a container runtime whose seccomp profile predates pidfds
    (Linux 5.3) refuses ``pidfd_open`` at run time, and the pool then spawns its workers."""
    names = ((os, "fork"), (os, "pidfd_open"), (signal, "pidfd_send_signal"),
             (socket, "send_fds"), (socket, "AF_UNIX"), (socket, "SOCK_SEQPACKET"))  # fmt: skip
    if not all(hasattr(m, name) for m, name in names):
        return False
    try:
        os.close(os.pidfd_open(os.getpid()))
        for end in socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET):
            end.close()
    except OSError:
        return False
    return True


class TemplateError(RuntimeError):
    """The template could not be started, warmed or asked to fork."""


# --------------------------------------------------------------------- the template process
def template_main(
    control: socket.socket,
    parent_pid: int,
    log_setup: tuple[str, str] | None,
    warm_up: Callable[[], object] | None,
    max_rss_bytes: int | None,
    nice: int,
) -> None:
    """The template process: warm up, say so, then fork a worker for each request and report
    the exits of the workers it forked, until told to stop or the server is gone."""
    set_up_child(parent_pid, log_setup, watch_parent=False)  # its loop polls the parent
    try:
        t0 = time.perf_counter()
        if warm_up is not None:
            warm_up()
        gc.collect()
        gc.freeze()  # the warm state is shared by every worker: never scanned, never copied
        _send(control, ("ready", time.perf_counter() - t0))
    except BaseException:
        _send(control, ("warm_failed", traceback.format_exc()[-(MAX_MESSAGE // 2) :]))
        return
    wake_r, wake_w = os.pipe()
    os.set_blocking(wake_r, False)
    os.set_blocking(wake_w, False)
    signal.set_wakeup_fd(wake_w)
    signal.signal(signal.SIGCHLD, lambda *_: None)  # a handler, so that SIGCHLD wakes the loop
    worker_args = (max_rss_bytes, nice)
    watched: list[socket.socket | int] = [control, wake_r]
    while True:
        ready, _, _ = select.select(watched, [], [], PARENT_WATCH_S)
        if os.getppid() != parent_pid:
            os._exit(1)
        if wake_r in ready:
            while True:
                try:
                    if not os.read(wake_r, 4096):
                        break
                except BlockingIOError:
                    break
        _reap(control)
        if control not in ready:
            continue
        try:
            data, fds, _, _ = socket.recv_fds(control, MAX_MESSAGE, 2)
        except OSError:
            os._exit(0)
        if not data:  # the server closed its end
            os._exit(0)
        message = pickle.loads(data)
        if message[0] == "stop":
            os._exit(0)
        if message[0] == "fork" and len(fds) == 2:
            _fork_worker(control, message[1], fds, (wake_r, wake_w), worker_args)
        else:
            for fd in fds:
                os.close(fd)


def _fork_worker(
    control: socket.socket,
    token: int,
    fds: list[int],
    wake: tuple[int, int],
    worker_args: tuple[int | None, int],
) -> None:
    """Fork one worker that serves on ``fds`` (jobs to read, answers to write); tell the server
    its pid (or why there is none)."""
    try:
        pid = os.fork()
    except OSError as exc:
        for fd in fds:
            os.close(fd)
        _send(control, ("fork_failed", token, repr(exc)))
        return
    if pid == 0:  # the worker: none of the template's own descriptors or handlers
        try:
            signal.set_wakeup_fd(-1)
            signal.signal(signal.SIGCHLD, signal.SIG_DFL)
            for fd in wake:
                os.close(fd)
            control.close()
            forked_main(fds[0], fds[1], *worker_args)
        finally:
            os._exit(1)
    for fd in fds:
        os.close(fd)
    _send(control, ("forked", token, pid))


def _reap(control: socket.socket) -> None:
    """Report every worker that has exited (and reap it)."""
    while True:
        try:
            pid, status = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            return
        _send(control, ("exit", pid, status))


def _send(control: socket.socket, message: tuple[Any, ...]) -> None:
    try:
        control.sendmsg([pickle.dumps(message)])
    except OSError:  # the server is gone
        os._exit(1)


# --------------------------------------------------------------------- the server's side
class ForkedProcess:
    """A worker forked by the template, as the pool sees it: the parts of
    :class:`multiprocessing.Process` the pool uses (``pid``, ``sentinel``, ``exitcode``,
    ``is_alive``, ``join``, ``kill``, ``terminate``), through a pidfd (signals never reach a
    recycled pid) and the template's exit report (a grandchild cannot be waited for)."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self._exitcode: int | None = None
        self._done = threading.Event()
        try:
            self._pidfd: int | None = os.pidfd_open(pid)
        except ProcessLookupError:  # it exited and was reaped already: its report is on its way
            self._pidfd = None

    @property
    def sentinel(self) -> int:
        """A descriptor that is readable once the worker has exited (its pidfd)."""
        if self._pidfd is None:
            raise ValueError("the worker has exited and was reaped already")
        return self._pidfd

    @property
    def exitcode(self) -> int | None:
        """As :attr:`multiprocessing.Process.exitcode` (negative: the signal); None while it
        runs, or when its exit was never reported (its template died first)."""
        return self._exitcode

    def is_alive(self) -> bool:
        if self._done.is_set() or self._pidfd is None:
            return False
        readable, _, _ = select.select([self._pidfd], [], [], 0)
        return not readable

    def join(self, timeout: float | None = None) -> None:
        """Wait until the worker has exited and its exit is reported, for ``timeout`` s."""
        end = None if timeout is None else time.monotonic() + timeout
        if self._pidfd is not None and not self._done.is_set():
            select.select([self._pidfd], [], [], timeout)
        left = REPORT_WAIT_S if end is None else min(REPORT_WAIT_S, end - time.monotonic())
        self._done.wait(max(left, 0.0))

    def kill(self) -> None:
        self._signal(signal.SIGKILL)

    def terminate(self) -> None:
        self._signal(signal.SIGTERM)

    def _signal(self, signum: int) -> None:
        if self._pidfd is None or self._done.is_set():
            return
        try:
            signal.pidfd_send_signal(self._pidfd, signum)
        except (ProcessLookupError, OSError):  # exited meanwhile
            pass

    def exited(self, status: int | None) -> None:
        """The template reported the exit (``status`` as from ``waitpid``; None: unknown)."""
        if status is not None:
            self._exitcode = os.waitstatus_to_exitcode(status)
        self._done.set()

    def release(self) -> None:
        """Close the pidfd (the pool is done with this worker)."""
        fd, self._pidfd = self._pidfd, None
        if fd is not None:
            os.close(fd)

    def __del__(self) -> None:  # a safety net: the pool releases it
        fd = getattr(self, "_pidfd", None)
        if fd is not None:
            try:
                os.close(fd)
            except OSError:
                pass


class WarmTemplate:
    """The server's handle of the template process: start it (``spawn``), wait until it is
    warm, fork workers from it, stop it. Its messages are read by one thread of its own."""

    def __init__(
        self,
        ctx: BaseContext,
        log_setup: tuple[str, str] | None,
        warm_up: Callable[[], object] | None,
        max_rss_bytes: int | None,
        nice: int,
    ) -> None:
        self._ctx = ctx
        #: What it was made with (a new template after this one is made the same).
        self.args = (log_setup, warm_up, max_rss_bytes, nice)
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self.state: Literal["new", "warming", "warm", "failed", "gone"] = "new"
        #: The warm-up's traceback, once it failed.
        self.failure = ""
        #: Seconds the warm-up took.
        self.warm_s = 0.0
        self.started = 0.0
        self._tokens = itertools.count()
        self._replies: dict[int, tuple[str, Any]] = {}
        self._children: dict[int, ForkedProcess] = {}
        self._process: Any = None
        self._sock: socket.socket | None = None

    @property
    def pid(self) -> int | None:
        return None if self._process is None else self._process.pid

    def start(self) -> None:
        """Spawn the template (it warms up in the background: :meth:`wait_warm`)."""
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        process = self._ctx.Process(  # type: ignore[attr-defined]
            target=template_main,
            args=(theirs, os.getpid(), *self.args),
            name="planner-template",
            daemon=True,
        )
        try:
            process.start()
        except BaseException:
            ours.close()
            raise
        finally:
            theirs.close()
        self._sock, self._process = ours, process
        self.state, self.started = "warming", time.monotonic()
        threading.Thread(target=self._read, name="template-reader", daemon=True).start()

    def wait_warm(self, timeout: float) -> bool:
        """Whether the template is warm, waiting up to ``timeout`` s; :class:`TemplateError`
        when its warm-up failed or it is gone."""
        with self._changed:
            self._changed.wait_for(lambda: self.state != "warming", timeout)
            if self.state == "failed":
                raise TemplateError(f"the worker template failed to warm up:\n{self.failure}")
            if self.state == "gone":
                raise TemplateError("the worker template exited")
            return self.state == "warm"

    def fork(self) -> tuple[ForkedProcess, int, int]:
        """A new warm worker: (its process, the write end of its jobs pipe, the read end of
        its answers pipe). :class:`TemplateError` when the template cannot fork."""
        if self.state != "warm" or self._sock is None:
            raise TemplateError(f"the worker template is not warm ({self.state})")
        token = next(self._tokens)
        jobs_r, jobs_w = os.pipe()
        answers_r, answers_w = os.pipe()
        for fd in (jobs_w, answers_w):
            widen_pipe(fd)
        try:
            try:
                socket.send_fds(self._sock, [pickle.dumps(("fork", token))], [jobs_r, answers_w])
            finally:
                os.close(jobs_r)
                os.close(answers_w)
            with self._changed:
                if not self._changed.wait_for(
                    lambda: token in self._replies or self.state != "warm", FORK_TIMEOUT_S
                ):
                    raise TemplateError(f"the worker template did not fork in {FORK_TIMEOUT_S} s")
                kind, value = self._replies.pop(token, ("fork_failed", self.state))
            if kind != "forked":
                raise TemplateError(f"the worker template could not fork: {value}")
            return value, jobs_w, answers_r
        except BaseException:
            os.close(jobs_w)
            os.close(answers_r)
            raise

    def _read(self) -> None:
        """The reader thread: the template's messages, until it is gone."""
        sock = self._sock
        assert sock is not None
        while True:
            try:
                data = sock.recv(MAX_MESSAGE)
            except OSError:
                data = b""
            if not data:
                break
            message = pickle.loads(data)
            with self._changed:
                kind = message[0]
                if kind == "ready":
                    self.state, self.warm_s = "warm", message[1]
                elif kind == "warm_failed":
                    self.state, self.failure = "failed", message[1]
                elif kind == "forked":  # registered here, before its exit can be read
                    child = ForkedProcess(message[2])
                    self._children[child.pid] = child
                    self._replies[message[1]] = ("forked", child)
                elif kind == "fork_failed":
                    self._replies[message[1]] = ("fork_failed", message[2])
                elif kind == "exit":
                    done = self._children.pop(message[1], None)
                    if done is not None:
                        done.exited(message[2])
                self._changed.notify_all()
        with self._changed:
            if self.state != "failed":
                self.state = "gone"
            orphans, self._children = list(self._children.values()), {}
            self._changed.notify_all()
        for child in orphans:  # their exits will never be reported: not waited for
            child.exited(None)

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop the template (its workers are the pool's to stop). One still warming up
        reads no message until its warm-up ends and has nothing to lose: killed at once (a
        service stopped while it starts stops at once, not after ``timeout_s``)."""
        sock, process = self._sock, self._process
        if process is not None and self.state == "warming":
            process.kill()
        elif sock is not None:
            try:
                sock.sendmsg([pickle.dumps(("stop",))])
            except OSError:
                pass
        if process is not None:
            process.join(timeout_s)
            if process.is_alive():
                process.kill()
                process.join(timeout_s)
        if sock is not None:
            sock.close()
