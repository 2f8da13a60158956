"""The worker pool in its event loop, on both loops the service runs on: asyncio's and uvloop's
(what ``planner serve`` uses: uvicorn picks it when installed). The answers are read by the
loop itself, so what a blocked or closed loop means is checked here: a deadline is kept even
when the loop's timer fires early (uvloop rounds timers to milliseconds), a shutdown (which
blocks the loop) still delivers the jobs that finish during its grace, small and large, a
pool whose loop is gone replaces no worker (and stops the one it had started), and a worker
started while a shutdown runs is stopped with its pipes."""

from __future__ import annotations

import asyncio
import functools
import time
from multiprocessing.connection import Connection

import pytest
import uvloop

from planner_api.exceptions import DeadlineExceededError
from planner_api.pool import WorkerPool
from planner_api.pool import pool as pool_module
from planner_api.pool.handle import Worker
from planner_api.pool.template import TemplateError

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


@pytest.mark.parametrize("loop", LOOPS)
def test_a_job_cancelled_just_before_a_shutdown_has_its_worker_killed_not_awaited(loop):
    """A stopping service's job store cancels its long jobs, then the pool shuts down with
    a long grace: the cancelled job's worker is killed (the watchdog's last look), not left
    running for the grace (a race the shutdown used to win: it waited the whole grace)."""
    from planner_api.exceptions import JobCancelledError

    async def scenario() -> None:
        pool = WorkerPool(1, 1, warm_up=None)
        await pool.start()
        await _ready(pool)
        future = pool.submit(_answer_after, (120.0, 10))
        while not future.running():
            await asyncio.sleep(0.01)
        t0 = time.monotonic()
        pool.cancel(future)
        pool.shutdown(timeout_s=120.0)
        took = time.monotonic() - t0
        assert pool.kills == 1 and pool.pids == []
        with pytest.raises(JobCancelledError):
            future.result(timeout=0)
        assert took < 60.0, took  # a hang guard: it did not wait for the 120 s job

    _run(loop, scenario)


def test_a_pool_whose_loop_is_gone_replaces_no_worker():
    """The loop ends (without a shutdown) before the first worker is spawned: the pool
    stops, it does not spawn and kill a replacement every few seconds."""

    async def scenario() -> WorkerPool:
        pool = WorkerPool(1, 0, warm_up=None)
        await pool.start()
        return pool  # the loop closes at once, before the supervisor can attach a worker

    pool = asyncio.run(scenario())
    _until(lambda: pool.state == "stopping", "the pool never noticed its loop was gone")
    time.sleep(3.0)  # a respawn loop would have spawned again by now
    assert pool.restarts == 0
    pool.shutdown(timeout_s=1)


def test_a_pool_whose_loop_closes_after_a_spawn_stops_its_worker(monkeypatch):
    """The loop closes (without a shutdown) after the supervisor handed it a worker to
    attach: no callback of that loop will ever run, so the supervisor, at its next look,
    stops the pool and kills and reaps the worker, whose answers no one would read."""
    monkeypatch.setattr(pool_module, "WARMING_REPORT_S", 0.2)

    async def scenario() -> tuple[WorkerPool, Worker]:
        pool = WorkerPool(1, 0, warm_up=None)
        await pool.start()
        end = time.monotonic() + STARTUP_TIMEOUT_S
        while not (pool._workers and pool._workers[0].reading):  # attached: the loop's part
            assert time.monotonic() < end, "no worker was attached"
            await asyncio.sleep(0.01)
        return pool, pool._workers[0]

    pool, worker = asyncio.run(scenario())
    _until(lambda: pool.state == "stopping", "the pool never noticed its loop was gone")
    _until(lambda: worker.answers.closed, "the worker's exit was not handled")
    assert worker.process.exitcode == -9 and worker.jobs.closed
    assert pool.pids == [] and pool.restarts == 0
    pool.shutdown(timeout_s=1)


def _until(condition, message: str) -> None:  # type: ignore[no-untyped-def]
    end = time.monotonic() + STARTUP_TIMEOUT_S
    while not condition():
        assert time.monotonic() < end, message
        time.sleep(0.05)


def test_a_worker_started_during_a_shutdown_is_stopped_with_its_pipes(monkeypatch):
    """The supervisor may be inside ``_spawn`` when a shutdown takes its list of workers (the
    race cannot be timed from outside, so the spawn is called after the shutdown, as the
    supervisor's would land): the late worker is not added to a pool nobody will stop again;
    it is killed and reaped and its pipes are closed, not left to the garbage collector."""

    async def scenario() -> None:
        pool = WorkerPool(1, 0, warm_up=None, template=False)
        await pool.start()
        await _ready(pool)
        pool.shutdown(timeout_s=5)
        opened: list = []
        started: list = []
        real_pipe, real_process = pool._ctx.Pipe, pool._ctx.Process

        def pipe(duplex: bool = True):  # type: ignore[no-untyped-def]
            ends = real_pipe(duplex=duplex)
            opened.extend(ends)
            return ends

        def process(*args, **kwargs):  # type: ignore[no-untyped-def]
            started.append(real_process(*args, **kwargs))
            return started[-1]

        monkeypatch.setattr(pool._ctx, "Pipe", pipe, raising=False)
        monkeypatch.setattr(pool._ctx, "Process", process, raising=False)
        pool._spawn()
        monkeypatch.undo()
        for name in ("Pipe", "Process"):  # undo leaves the class's attribute on the instance
            vars(pool._ctx).pop(name, None)
        assert pool.pids == []
        assert len(started) == 1 and started[0].exitcode == -9, "the late worker was not killed"
        assert len(opened) == 4 and all(end.closed for end in opened)

    _run("asyncio", scenario)


def test_a_worker_forked_during_a_shutdown_is_stopped_with_its_pipes():
    """The same race with the warm template: the supervisor has a worker forked (``fork``
    returned) when the shutdown takes its list; the late worker is killed and its pipes and
    pidfd closed; and no new template or worker is started once the shutdown began."""

    async def scenario() -> None:
        pool = WorkerPool(1, 0, warm_up=None)
        await pool.start()
        await _ready(pool)
        template = pool._template
        assert template is not None
        process, jobs_fd, answers_fd = template.fork()  # as the supervisor's _spawn would
        assert process.is_alive()
        pool.shutdown(timeout_s=5)
        jobs = Connection(jobs_fd, readable=False, writable=True)
        answers = Connection(answers_fd, readable=True, writable=False)
        pool._add(Worker(process, jobs=jobs, answers=answers))
        assert pool.pids == []
        assert not process.is_alive(), "the late worker was not stopped"
        assert jobs.closed and answers.closed and process._pidfd is None
        with pytest.raises(TemplateError):
            pool._spawn()  # after the shutdown: no template is started again
        assert template.state == "gone" and pool._template is template

    _run("asyncio", scenario)


def test_a_shutdown_reaps_a_worker_whose_attach_never_ran():
    """A worker spawned just before a shutdown has its ``_attach`` queued in the loop, which
    the shutdown blocks: it is stopped all the same, taken off the pool and its pipes closed
    (the spawn is called from the loop itself, so that its attach cannot run first)."""

    async def scenario() -> None:
        pool = WorkerPool(2, 0, warm_up=None)
        await pool.start()
        await _ready(pool)
        pool._spawn()  # as the supervisor would: its attach now waits for the loop
        late = pool._workers[-1]
        assert not late.reading
        pool.shutdown(timeout_s=5)
        assert pool.pids == []
        assert late.jobs.closed and late.answers.closed
        assert late.process.exitcode is not None  # stopped and reaped

    _run("asyncio", scenario)


def test_a_workers_exit_is_handled_once():
    """Two paths can reach a worker's exit (the exit thread the loop starts, and a shutdown
    that finds the worker unread): the second does nothing, so the process is not waited for
    twice and its pipes are not closed twice from two threads (which could close a reused
    descriptor number or raise EBADF out of the shutdown)."""

    async def scenario() -> None:
        pool = WorkerPool(1, 0, warm_up=None)
        await pool.start()
        await _ready(pool)
        worker = pool._workers[0]
        pool.shutdown(timeout_s=5)
        assert worker.answers.closed
        waits: list[object] = []
        join = worker.process.join
        worker.process.join = lambda *a: waits.append(a) or join(*a)  # type: ignore[method-assign]
        pool._on_exit(worker)
        assert waits == []

    _run("asyncio", scenario)
