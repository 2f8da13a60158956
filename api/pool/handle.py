"""The parent's record of one worker process of :class:`planner_api.pool.WorkerPool`:
the process, its two pipes, its state and the job it runs; and the answers' frames
(:func:`planner_api.pool.process.send_frame`) cut out of the bytes its pipe delivers."""

from __future__ import annotations

import multiprocessing
import os
import signal
import time
from concurrent.futures import Future
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Any

from planner_api.pool.process import FRAME_HEADER
from planner_api.pool.states import WorkerEvent, WorkerState, next_state
from planner_api.pool.template import ForkedProcess

__all__ = ["RECYCLED", "Job", "Worker", "cpu_seconds", "describe_exit"]

#: :attr:`Worker.killed` of a worker told to stop because its replacement is warm (recycled,
#: over the memory bound); the other reasons are a job's ``kill_reason``.
RECYCLED = "recycled"


@dataclass(eq=False)
class Job:
    """A job sent, or to be sent, to a worker: its pickled message and its future."""

    payload: bytes
    future: Future[Any]
    #: When the watchdog looks at the worker running this job next (a :func:`time.monotonic`
    #: value: its deadline, then as its overrun grace is spent, or now for a cancelled job);
    #: None: never.
    kill_at: float | None = None
    #: Why it would be stopped: "deadline" or "cancelled".
    kill_reason: str = "deadline"
    #: Its deadline (a :func:`time.monotonic` value; None: none).
    deadline: float | None = None
    #: The worker's CPU time at the deadline, s (None: not read yet): the overrun grace is
    #: CPU time spent past the deadline, so a job starved of CPU by a busy machine gets its
    #: grace to stop by itself.
    cpu_at_deadline: float | None = None


@dataclass(eq=False)
class Worker:
    """One worker process as the pool sees it."""

    #: A spawned process, or one forked from the warm template.
    process: multiprocessing.process.BaseProcess | ForkedProcess
    #: The pipe the parent sends jobs on (blocking writes: the worker is waiting for them).
    jobs: Connection
    #: The pipe the worker answers on, read by the event loop (non-blocking).
    answers: Connection
    #: Where it is in its life; changed by :meth:`change` only (:mod:`planner_api.pool.states`).
    state: WorkerState = WorkerState.STARTING
    job: Job | None = None
    started: float = field(default_factory=time.monotonic)
    #: Bytes read from ``answers`` and not yet a whole frame.
    inbox: bytearray = field(default_factory=bytearray, repr=False)
    #: The event loop reads ``answers`` (attached, its end not yet seen).
    reading: bool = False
    #: Why the pool is ending it ("" while it is not; set as it becomes ``killing``): its job
    #: was "cancelled" or ran past its "deadline" (SIGKILL), or it was :data:`RECYCLED` (told
    #: to stop, its exit not a death to replace).
    killed: str = ""
    #: Over the memory bound: serves on until its replacement is warm, then retires.
    retiring: bool = False
    #: Its replacement is warm: it retires after the job it is running.
    retire_after_job: bool = False
    #: The retiring worker this one replaces (stopped once this one is warm).
    replaces: Worker | None = field(default=None, repr=False)
    #: Resident memory after its last job when over the bound, bytes (None: never over).
    rss: int | None = None
    #: Its exit is being handled (:meth:`planner_api.pool.WorkerPool._on_exit` runs once:
    #: a second run would wait for the same process and close the same pipes twice).
    exit_claimed: bool = False

    def change(self, event: WorkerEvent) -> WorkerState:
        """Move to the state the table gives for ``event`` (the caller holds the pool's lock);
        the state it was in. :class:`~planner_api.pool.states.IllegalTransitionError` when the
        table holds no such move (the state is then left as it was)."""
        was, self.state = self.state, next_state(self.state, event)
        return was

    @property
    def warmed(self) -> bool:
        """Warm and not told to stop: warm, busy, or killed with its exit not seen yet. What
        the pool counts as warm while workers warm up, and what a replacement may retire."""
        return self.state in (WorkerState.WARM, WorkerState.BUSY) or (
            self.state is WorkerState.KILLING and self.killed != RECYCLED
        )

    def close(self) -> None:
        """Close its pipes and, for a worker forked from the template, its pidfd (the
        process has exited and its exit was handled)."""
        self.jobs.close()
        self.answers.close()
        if isinstance(self.process, ForkedProcess):
            self.process.release()

    def take(self, chunk: bytes) -> list[bytes]:
        """The whole messages that ``chunk``, read from ``answers``, completes (in order);
        a partial frame waits in :attr:`inbox` for the next chunk."""
        inbox = self.inbox
        inbox += chunk
        head = FRAME_HEADER.size
        messages: list[bytes] = []
        while len(inbox) >= head:
            (size,) = FRAME_HEADER.unpack_from(inbox)
            if len(inbox) < head + size:
                break
            with memoryview(inbox) as view:  # one copy of the message, not two
                messages.append(bytes(view[head : head + size]))
            del inbox[: head + size]
        return messages


_CLOCK_TICKS = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def cpu_seconds(pid: int) -> float | None:
    """CPU time (user + system) the process ``pid`` has used, s (``/proc/PID/stat``); None
    where it cannot be read (gone, or no /proc)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            fields = f.read().rsplit(b")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / _CLOCK_TICKS
    except (OSError, IndexError, ValueError):
        return None


def describe_exit(exitcode: int | None) -> str:
    """A process's exit in words, e.g. "exit code 3" or "killed by SIGKILL"."""
    if exitcode is None:
        return "exit status unknown"
    if exitcode < 0:
        try:
            return f"killed by {signal.Signals(-exitcode).name}"
        except ValueError:
            return f"killed by signal {-exitcode}"
    return f"exit code {exitcode}"
