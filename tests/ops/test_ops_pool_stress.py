"""The worker pool under a seeded storm of what goes wrong in service: workers SIGKILLed from
outside, jobs cancelled (the caller's task, or :meth:`WorkerPool.cancel` of a submitted job),
clients gone mid-request (:data:`planner_api.pool.CLIENT_GONE`, as
:func:`planner_api.deps.watch_client` sets it), deadlines that kill, and shutdowns while a
worker is being spawned or forked, on asyncio's loop and on uvloop's, with the warm template
and with spawned workers.

The storm is random for a fixed seed and bounded by a count of operations, not by time. At
the end nothing may be left: every answer that came is the answer of its own job, the pool
has no job in flight and serves again, no process the pool started is alive (found by a mark
in their environment, so that a worker orphaned by its template is found too), the pool
closed every pipe, pidfd and socket it held itself, no other descriptor is left open, no
thread of the pool runs, and no worker ever made a move its state table refuses.

One tolerance, and why: :mod:`multiprocessing` keeps two pipe ends of each process it spawns
(the template, or a spawned worker: its sentinel and its launch pipe) until the ``Process``
object is finalised. The pool drops those objects, and when a cycle holds one (an exception's
traceback, a finished task) the collector closes them later; so the count of descriptors is
taken after :func:`gc.collect`, which frees only what nothing references: a descriptor the
pool still holds stays counted. The pool's own pipes, pidfds and sockets are checked before
that, each closed by the pool, not by a finaliser."""

from __future__ import annotations

import asyncio
import contextlib
import gc
import logging
import os
import random
import signal
import socket
import threading
import time
import uuid
from collections.abc import Callable
from concurrent.futures import CancelledError as FutureCancelledError
from concurrent.futures import Future
from pathlib import Path
from typing import Any

import pytest
import uvloop

from planner_api.exceptions import (
    ClientDisconnectedError,
    DeadlineExceededError,
    JobCancelledError,
    PoolSaturatedError,
    WorkerCrashedError,
)
from planner_api.pool import CLIENT_GONE, WorkerPool
from planner_api.pool.handle import Worker
from planner_api.pool.template import ForkedProcess, WarmTemplate

pytestmark = pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="needs /proc")

SEED = 38
#: Operations of each round's storm (the bound of the test: a count, never a time).
OPERATIONS = 70
#: The rounds: (event loop, whether the workers are forked from the warm template).
ROUNDS = (("asyncio", True), ("uvloop", True), ("asyncio", False))
LOOPS: dict[str, Callable[[], asyncio.AbstractEventLoop]] = {
    "asyncio": asyncio.new_event_loop,
    "uvloop": uvloop.new_event_loop,
}
#: How long anything may take to settle before the test calls it a hang (a bound against a
#: stuck test, generous for a loaded CI machine: never a claim about speed).
SETTLE_S = 120.0
#: The threads of a pool (:mod:`planner_api.pool.pool`, ``.template``): none may outlive it.
POOL_THREADS = ("worker-supervisor", "job-watchdog", "worker-exit", "template-reader")
#: The environment variable that marks every process the pools of this test start.
MARK = "PLANNER_STRESS_MARK"

#: What a plain job's wait may end with besides its answer: its deadline (a job that sleeps
#: past it is killed), its worker SIGKILLed by the storm, or a full pool.
PLAIN = (DeadlineExceededError, WorkerCrashedError, PoolSaturatedError)


def _nap(arg: tuple[float, int]) -> int:
    """The job: sleep ``arg[0]`` s, answer ``arg[1]`` (the token of the job that asked)."""
    time.sleep(arg[0])
    return arg[1]


def _fds() -> set[str]:
    return set(os.listdir("/proc/self/fd"))


def _marked(mark: str) -> list[int]:
    """Pids of the live processes whose environment carries ``MARK=mark``."""
    needle = f"{MARK}={mark}".encode()
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/environ", "rb") as f:
                if needle in f.read().split(b"\0"):
                    found.append(int(entry))
        except OSError:  # gone meanwhile, or not ours to read
            pass
    return found


def _zombie_children() -> list[int]:
    """Children of this process that exited and were never reaped."""
    found = []
    for entry in os.listdir("/proc"):
        try:
            with open(f"/proc/{entry}/stat", "rb") as f:
                fields = f.read().rsplit(b")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(fields[1]) == os.getpid() and fields[0] == b"Z":
            found.append(int(entry))
    return found


#: The threads of pools that other tests of this process keep running (a fixture's app): not
#: this test's to wait for.
_OTHERS: set[threading.Thread] = set()


def _pool_threads() -> list[str]:
    """The threads of this test's pools still running."""
    threads = threading.enumerate()
    return [t.name for t in threads if t.name in POOL_THREADS and t not in _OTHERS]


def _settle(condition: Callable[[], bool]) -> bool:
    end = time.monotonic() + SETTLE_S
    while not condition():
        if time.monotonic() > end:
            return False
        time.sleep(0.01)
    return True


class Storm:
    """One round's storm on one pool: the operations, and every outcome they had."""

    def __init__(self, pool: WorkerPool, rng: random.Random) -> None:
        self.pool = pool
        self.rng = rng
        self.tokens = iter(range(1, 1 << 30))
        #: (kind, token, task) of every job awaited through ``run``.
        self.waits: list[tuple[str, int, asyncio.Task[int]]] = []
        #: (token, future) of every job submitted (and maybe cancelled with ``pool.cancel``).
        self.submitted: list[tuple[int, Future[int]]] = []
        #: The CLIENT_GONE futures of the requests whose client has not left yet.
        self.clients: list[asyncio.Future[None]] = []

    def _run(self, kind: str, gone: asyncio.Future[None] | None = None) -> None:
        token = next(self.tokens)
        nap = self.rng.uniform(0.0, 0.15)
        deadline = time.monotonic() + self.rng.uniform(0.05, 1.0)

        async def wait() -> int:
            if gone is not None:
                CLIENT_GONE.set(gone)  # this task's context only, as watch_client does
            return await self.pool.run(_nap, (nap, token), deadline=deadline)

        self.waits.append((kind, token, asyncio.get_running_loop().create_task(wait())))

    async def step(self) -> None:
        """One operation, drawn by the seeded generator."""
        rng, pool = self.rng, self.pool
        roll = rng.random()
        if roll < 0.30:
            self._run("plain")
        elif roll < 0.40:
            gone = asyncio.get_running_loop().create_future()
            self.clients.append(gone)
            self._run("client", gone)
        elif roll < 0.48 and self.clients:  # a client leaves mid-request
            gone = self.clients.pop(rng.randrange(len(self.clients)))
            gone.set_result(None)
        elif roll < 0.56:
            running = [w for w in self.waits if w[0] == "plain" and not w[2].done()]
            if running:  # the caller's task is cancelled (its request abandoned)
                kind, token, task = running[rng.randrange(len(running))]
                task.cancel()
                self.waits[self.waits.index((kind, token, task))] = ("cancelled", token, task)
        elif roll < 0.64:
            token = next(self.tokens)
            with contextlib.suppress(PoolSaturatedError):
                future = pool.submit(_nap, (rng.uniform(0.0, 0.2), token))
                self.submitted.append((token, future))
        elif roll < 0.70 and self.submitted:
            pool.cancel(self.submitted[rng.randrange(len(self.submitted))][1])
        elif roll < 0.80:
            pids = pool.pids
            if pids:  # a worker dies from outside (the OOM killer, an operator)
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pids[rng.randrange(len(pids))], signal.SIGKILL)
        else:
            await asyncio.sleep(rng.uniform(0.0, 0.05))

    async def settle(self) -> None:
        """Every client still connected leaves, and every wait ends."""
        for gone in self.clients:
            gone.set_result(None)
        tasks = [task for _, _, task in self.waits]
        futures = [asyncio.wrap_future(f) for _, f in self.submitted]
        if tasks or futures:
            await asyncio.wait([*tasks, *futures], timeout=SETTLE_S)
        for f in futures:  # read here (checked on the submitted futures themselves)
            if f.done() and not f.cancelled():
                f.exception()

    def check(self) -> dict[str, int]:
        """Each wait ended as its kind allows, an answer is its own job's; the count of
        each outcome (so that a storm that exercised nothing is seen)."""
        seen: dict[str, int] = {}
        for kind, token, task in self.waits:
            assert task.done(), f"a {kind} wait never ended"
            if task.cancelled():
                outcome: Any = asyncio.CancelledError()
            else:
                outcome = task.exception() or task.result()
            allowed: tuple[type[BaseException], ...] = PLAIN
            if kind == "cancelled":
                allowed = (*PLAIN, asyncio.CancelledError)
            elif kind == "client":
                allowed = (*PLAIN, ClientDisconnectedError)
            if isinstance(outcome, int):
                assert outcome == token, f"job {token} was answered with job {outcome}'s answer"
            else:
                assert isinstance(outcome, allowed), (kind, repr(outcome))
            name = type(outcome).__name__
            seen[name] = seen.get(name, 0) + 1
        for token, future in self.submitted:
            assert future.done(), "a submitted job never ended"
            try:
                assert future.result() == token, "a submitted job got another's answer"
                seen["submitted ok"] = seen.get("submitted ok", 0) + 1
            except (FutureCancelledError, JobCancelledError, WorkerCrashedError) as exc:
                seen[type(exc).__name__] = seen.get(type(exc).__name__, 0) + 1
        return seen


async def _storm_round(
    loop_name: str, template: bool, rng: random.Random, seen: dict[str, int]
) -> None:
    """One round on one loop: a pool shut down during its first spawn, then a pool under
    the storm, drained, and shut down the moment a replacement for a killed worker is being
    started."""
    early = WorkerPool(1, 0, warm_up=None, template=template)
    await early.start()
    await asyncio.sleep(rng.uniform(0.0, 0.05))  # the first spawn (or fork) under way
    early.shutdown(timeout_s=1.0)
    assert early.pids == [] and early.in_flight == 0

    pool = WorkerPool(
        2, 3, warm_up=None, overrun_grace_s=0.05, overrun_max_s=0.2, template=template
    )
    await pool.start()
    storm = Storm(pool, rng)
    try:
        await _until_ready(pool)
        for _ in range(OPERATIONS):
            await storm.step()
        await storm.settle()
        end = time.monotonic() + SETTLE_S
        while pool.in_flight and time.monotonic() < end:  # killed jobs' exits still to come
            await asyncio.sleep(0.01)
        assert pool.in_flight == 0, "a job stayed in flight after every wait had ended"
        assert not pool._pending
        for name, n in storm.check().items():
            seen[name] = seen.get(name, 0) + n
        await _until_ready(pool)  # the killed workers were replaced: it serves again
        assert await pool.run(_nap, (0.0, -1), deadline=time.monotonic() + SETTLE_S) == -1
        pids = pool.pids
        if pids:  # a kill whose replacement is being forked (or spawned) as the pool stops
            os.kill(pids[0], signal.SIGKILL)
            await asyncio.sleep(rng.uniform(0.0, 0.02))
    finally:
        pool.shutdown(timeout_s=1.0)
    assert pool.pids == [] and pool.in_flight == 0 and not pool._pending
    assert pool._workers == [], "a worker record outlived the shutdown"


async def _until_ready(pool: WorkerPool) -> None:
    end = time.monotonic() + SETTLE_S
    while pool.warm_workers < pool.workers:
        assert time.monotonic() < end, "the pool never had every worker warm"
        await asyncio.sleep(0.01)


def test_the_pool_leaks_nothing_under_a_storm_of_kills_cancels_and_shutdowns(monkeypatch, caplog):
    rng = random.Random(SEED)
    thread_errors: list[BaseException | None] = []
    monkeypatch.setattr(threading, "excepthook", lambda a: thread_errors.append(a.exc_value))
    held: list[Any] = []  # what the pool must close itself: workers' pipes and pidfds, templates'
    add = WorkerPool._add

    def recorded_add(self: WorkerPool, worker: Worker) -> None:
        held.extend([worker.jobs, worker.answers])
        if isinstance(worker.process, ForkedProcess):  # not a spawned one: see the docstring
            held.append(worker.process)
        add(self, worker)

    monkeypatch.setattr(WorkerPool, "_add", recorded_add)
    start = WarmTemplate.start

    def recorded_start(self: WarmTemplate) -> None:
        start(self)
        held.append(self._sock)  # its control socket (the process: see the docstring)

    monkeypatch.setattr(WarmTemplate, "start", recorded_start)

    def run(loop_name: str, scenario: Callable[[], Any]) -> None:
        with asyncio.Runner(loop_factory=LOOPS[loop_name]) as runner:
            runner.run(scenario())

    # what a first pool and a first loop open for good, before the count: multiprocessing's
    # resource tracker (its first spawn) and libuv's process-wide signal pipe (its first loop)
    async def warm_once() -> None:
        pool = WorkerPool(1, 0, warm_up=None, template=False)
        await pool.start()
        while pool.state != "ready":
            await asyncio.sleep(0.01)
        pool.shutdown(timeout_s=1.0)

    _OTHERS.update(t for t in threading.enumerate() if t.name in POOL_THREADS)
    for loop_name in LOOPS:
        run(loop_name, warm_once)
    assert _settle(lambda: not _pool_threads())
    gc.collect()
    mark = uuid.uuid4().hex
    monkeypatch.setenv(MARK, mark)
    fds = _fds()
    seen: dict[str, int] = {}
    with caplog.at_level(logging.ERROR):
        for loop_name, template in ROUNDS:
            run(loop_name, lambda n=loop_name, t=template: _storm_round(n, t, rng, seen))

    assert _settle(lambda: not _pool_threads()), f"pool threads still run: {_pool_threads()}"
    assert _settle(lambda: not _marked(mark)), f"processes left behind: {_marked(mark)}"
    assert _zombie_children() == []
    assert thread_errors == []
    unclosed = [h for h in held if isinstance(h, ForkedProcess) and h._pidfd is not None]
    unclosed += [h for h in held if isinstance(h, socket.socket) and h.fileno() != -1]
    unclosed += [h for h in held if getattr(h, "closed", True) is False]  # a Connection
    assert held and unclosed == [], "the pool left a pipe, pidfd or socket to a finaliser"
    gc.collect()  # the spawned processes' launch pipes: the docstring's one tolerance
    left = {fd: os.readlink(f"/proc/self/fd/{fd}") for fd in _fds() - fds}
    assert left == {}, "descriptors left open"
    illegal = [r.getMessage() for r in caplog.records if "illegal" in r.getMessage()]
    assert illegal == [] and not [r for r in caplog.records if r.name == "asyncio"]
    # the storm did exercise what it is about (how often each came depends on the timing)
    for outcome in ("CancelledError", "WorkerCrashedError", "ClientDisconnectedError"):
        assert seen.get(outcome, 0) > 0, (outcome, seen)
