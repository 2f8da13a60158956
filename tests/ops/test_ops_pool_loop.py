"""The worker pool in its event loop, on both loops the service runs on: asyncio's and uvloop's
(what ``planner serve`` uses: uvicorn picks it when installed). The answers are read by the
loop itself, so what a blocked or closed loop means is checked here: a deadline is kept even
when the loop's timer fires early (uvloop rounds timers to milliseconds), a shutdown (which
blocks the loop) still delivers the jobs that finish during its grace, small and large, and
a pool whose loop is gone replaces no worker."""

from __future__ import annotations

import asyncio
import functools
import multiprocessing
import time

import pytest
import uvloop

from planner_api.exceptions import DeadlineExceededError
from planner_api.workers import WorkerPool

STARTUP_TIMEOUT_S = 180.0  # as tests/conftest.py
SLACK_S = 5.0

LOOPS = {"asyncio": asyncio.new_event_loop, "uvloop": uvloop.new_event_loop}


def _run(loop: str, scenario) -> None:  # type: ignore[no-untyped-def]
    with asyncio.Runner(loop_factory=LOOPS[loop]) as runner:
        runner.run(scenario())


async def _ready(pool: WorkerPool) -> None:
    end = time.monotonic() + STARTUP_TIMEOUT_S
    while pool.state != "ready":
        assert time.monotonic() < end, "the pool never became ready"
        await asyncio.sleep(0.02)


def _answer_after(seconds_and_size: tuple[float, int]) -> bytes:
    seconds, size = seconds_and_size
    time.sleep(seconds)
    return b"a" * size


@pytest.mark.parametrize("loop", LOOPS)
def test_a_deadline_is_kept_though_the_loop_timer_fires_early(loop):
    """No worker ever gets warm (a 60 s warm-up), so every job waits in the queue: each wait
    must end with DeadlineExceededError at its deadline (10-20 ms, in 0.1 ms steps, to meet
    the timer's rounding), none may hang."""

    async def scenario() -> None:
        pool = WorkerPool(1, 64, warm_up=functools.partial(time.sleep, 60.0))
        await pool.start()
        try:
            for i in range(100):
                t0 = time.monotonic()
                budget = 0.01 + 0.0001 * i
                with pytest.raises(DeadlineExceededError):
                    await asyncio.wait_for(pool.run(abs, -1, deadline=t0 + budget), SLACK_S)
                assert time.monotonic() - t0 >= budget - 0.002
        finally:
            pool.shutdown(timeout_s=1)

    _run(loop, scenario)


@pytest.mark.parametrize("loop", LOOPS)
@pytest.mark.parametrize("size", [100, 2 * 2**20])
def test_a_shutdown_delivers_the_jobs_that_finish_in_its_grace(loop, size):
    """A job that ends 0.5 s into a 10 s shutdown is answered (not failed as a crash), also
    when its answer is larger than a pipe holds, and the shutdown ends when the workers do."""

    async def scenario() -> None:
        pool = WorkerPool(1, 1, warm_up=None)
        await pool.start()
        await _ready(pool)
        future = pool.submit(_answer_after, (0.5, size))
        await asyncio.sleep(0.1)  # it runs
        t0 = time.monotonic()
        pool.shutdown(timeout_s=10.0)
        took = time.monotonic() - t0
        assert future.done() and future.result() == b"a" * size
        assert took < 5.0, took  # the worker exited after its job, not at the timeout
        assert pool.pids == []

    _run(loop, scenario)


def test_a_pool_whose_loop_is_gone_replaces_no_worker():
    """The loop ends (without a shutdown) before the first worker is spawned: the pool
    stops, it does not spawn and kill a replacement every few seconds."""

    async def scenario() -> WorkerPool:
        pool = WorkerPool(1, 0, warm_up=None)
        await pool.start()
        return pool  # the loop closes at once, before the supervisor can attach a worker

    pool = asyncio.run(scenario())
    time.sleep(3.0)
    assert pool.restarts == 0
    assert pool.state == "stopping"
    pool.shutdown(timeout_s=1)


def test_a_worker_started_during_a_shutdown_is_stopped_with_its_pipes():
    """The supervisor may be inside ``_spawn`` when a shutdown takes its list of workers (the
    race cannot be timed from outside, so the spawn is called after the shutdown, as the
    supervisor's would land): the late worker is not added to a pool nobody will stop again;
    it is killed and reaped and its pipes are closed, not left to the garbage collector."""

    async def scenario() -> None:
        pool = WorkerPool(1, 0, warm_up=None)
        await pool.start()
        await _ready(pool)
        pool.shutdown(timeout_s=5)
        before = set(multiprocessing.active_children())
        opened: list = []
        real_pipe = pool._ctx.Pipe

        def pipe(duplex: bool = True):  # type: ignore[no-untyped-def]
            ends = real_pipe(duplex=duplex)
            opened.extend(ends)
            return ends

        pool._ctx.Pipe = pipe  # type: ignore[method-assign]
        try:
            pool._spawn()
        finally:
            pool._ctx.Pipe = real_pipe  # type: ignore[method-assign]
        assert pool.pids == []
        late = set(multiprocessing.active_children()) - before
        assert not [p for p in late if p.is_alive()], "the late worker still runs"
        assert len(opened) == 4 and all(end.closed for end in opened)

    _run("asyncio", scenario)
