"""The warm template (:mod:`planner_api.pool.template`): the pool's warm-up runs once, in the
template, and every worker (the first ones and each replacement of a killed, crashed or
recycled one) is a fork of it that carries the warm state without warming again; a template
that dies leaves its workers serving and is replaced; one whose warm-up fails leaves the pool
'broken'; and the spawn fallback still serves. No timing is asserted: the oracles are the
warm-up's own record (a file line per run) and the state a worker inherits."""

from __future__ import annotations

import asyncio
import functools
import os
import signal
import time
from pathlib import Path

import pytest

from planner_api.exceptions import JobCancelledError
from planner_api.pool import WorkerPool

STARTUP_TIMEOUT_S = 180.0  # as tests/conftest.py


def _mark_warm(path: str) -> None:
    """The warm-up: one line per run in ``path``, and a mark in this process's memory."""
    with open(path, "a") as f:
        f.write(f"{os.getpid()}\n")
    os.environ["PLANNER_TEST_WARMED_BY"] = str(os.getpid())


def _failing_warm_up() -> None:
    raise RuntimeError("this warm-up always fails")


def _inherited(_: object) -> tuple[int, int, str | None]:
    """(pid, parent pid, the warm-up's mark) of the worker that runs this job."""
    return os.getpid(), os.getppid(), os.environ.get("PLANNER_TEST_WARMED_BY")


async def _until(predicate, what: str) -> None:  # type: ignore[no-untyped-def]
    end = time.monotonic() + STARTUP_TIMEOUT_S
    while not predicate():
        assert time.monotonic() < end, what
        await asyncio.sleep(0.005)


def _runs(path: Path) -> list[int]:
    return [int(line) for line in path.read_text().split()]


def test_the_warm_up_runs_once_and_every_replacement_is_a_warm_fork(tmp_path):
    """Five running jobs cancelled in a row (each a kill): five replacements, none warms up
    again (the warm-up's file keeps one line), each carries the template's warm state and is
    the template's child."""
    record = tmp_path / "warm-ups"

    async def scenario() -> None:
        pool = WorkerPool(2, 2, warm_up=functools.partial(_mark_warm, str(record)))
        await pool.start()
        try:
            await _until(lambda: pool.state == "ready", "the pool never became ready")
            template = pool._template
            assert template is not None and template.pid == _runs(record)[0]
            seen = set(pool.pids)
            for _ in range(5):
                kills = pool.kills + 1
                job = pool.submit(time.sleep, 30.0, deadline=time.monotonic() + 60)
                await _until(lambda: any(w.state == "busy" for w in pool._workers), "no job ran")
                pool.cancel(job)
                with pytest.raises(JobCancelledError):
                    await asyncio.wrap_future(job)
                await _until(lambda k=kills: pool.kills == k, "the cancelled job was not killed")
                await _until(lambda: pool.warm_workers == 2, "the killed worker was not replaced")
                seen |= set(pool.pids)
            answers = await pool.map(_inherited, [0, 1, 2, 3], deadline=time.monotonic() + 60)
            assert _runs(record) == [template.pid], "a worker warmed up again"
            for pid, parent, mark in answers:
                assert parent == template.pid and mark == str(template.pid)
                assert pid in pool.pids
            assert len(seen) == 2 + 5 and pool.restarts == 0
        finally:
            pool.shutdown(timeout_s=5)

    asyncio.run(scenario())


def test_a_template_that_dies_leaves_its_workers_serving_and_is_replaced(tmp_path):
    """SIGKILL on the template: the workers it forked keep serving; the next replacement
    (a worker that crashed) comes from a new template, which warms up once."""
    record = tmp_path / "warm-ups"

    async def scenario() -> None:
        pool = WorkerPool(1, 1, warm_up=functools.partial(_mark_warm, str(record)))
        await pool.start()
        try:
            await _until(lambda: pool.state == "ready", "the pool never became ready")
            first = pool._template
            assert first is not None
            os.kill(first.pid, signal.SIGKILL)  # type: ignore[arg-type]
            await _until(lambda: first.state == "gone", "the template's end was not seen")
            pid, _, mark = await pool.run(_inherited, 0, deadline=time.monotonic() + 60)
            assert mark == str(first.pid) and pool.pids == [pid]  # the worker serves on
            os.kill(pid, signal.SIGKILL)  # a crash: its replacement needs a new template
            await _until(lambda: pool.restarts == 1, "the crash was not seen")
            await _until(lambda: pool.warm_workers == 1, "the worker was not replaced")
            second = pool._template
            assert second is not first and second.pid != first.pid
            _, parent, mark = await pool.run(_inherited, 0, deadline=time.monotonic() + 60)
            assert parent == second.pid and mark == str(second.pid)
            assert _runs(record) == [first.pid, second.pid]
        finally:
            pool.shutdown(timeout_s=5)

    asyncio.run(scenario())


def test_a_template_whose_warm_up_fails_leaves_the_pool_broken():
    async def scenario() -> None:
        pool = WorkerPool(1, 0, warm_up=_failing_warm_up)
        await pool.start()
        try:
            await _until(lambda: pool.state == "broken", "the failed warm-up was not reported")
            assert pool.warm_workers == 0 and pool.pids == []
            assert "this warm-up always fails" in pool._template.failure  # type: ignore[union-attr]
        finally:
            pool.shutdown(timeout_s=5)

    asyncio.run(scenario())


def test_without_a_template_each_worker_warms_up_itself(tmp_path):
    """The fallback (``template=False``, or a platform without fork and pidfds): two spawned
    workers, each warmed by itself, children of the server."""
    record = tmp_path / "warm-ups"

    async def scenario() -> None:
        pool = WorkerPool(2, 0, warm_up=functools.partial(_mark_warm, str(record)), template=False)
        await pool.start()
        try:
            await _until(lambda: pool.state == "ready", "the pool never became ready")
            assert pool._template is None
            answers = await pool.map(_inherited, [0, 1], deadline=time.monotonic() + 60)
            assert sorted(_runs(record)) == sorted(pool.pids)
            assert {parent for _, parent, _ in answers} == {os.getpid()}
            assert {mark for _, _, mark in answers} == {str(p) for p in pool.pids}
        finally:
            pool.shutdown(timeout_s=5)

    asyncio.run(scenario())


def test_a_runtime_that_refuses_pidfds_gets_spawned_workers(monkeypatch):
    """A container whose seccomp profile predates pidfds refuses ``pidfd_open`` at run time
    (EPERM): the pool must not fork workers it could neither signal nor watch, but spawn them."""
    from planner_api.pool import template

    def refused(_: int) -> int:
        raise PermissionError(1, "Operation not permitted")

    assert template.templates_work()
    monkeypatch.setattr(os, "pidfd_open", refused)
    assert not template.templates_work()

    async def scenario() -> None:
        pool = WorkerPool(1, 0, warm_up=None)
        await pool.start()
        try:
            assert pool._template is None
            await _until(lambda: pool.state == "ready", "the spawned worker never started")
            assert await pool.run(abs, -2, deadline=time.monotonic() + 60) == 2
        finally:
            pool.shutdown(timeout_s=5)

    asyncio.run(scenario())


def test_a_template_stopped_while_it_warms_up_is_killed_at_once():
    """A template still in its warm-up (a service stopped while it starts) reads no message
    until it is warm: it is killed at once, not waited for (a 60 s warm-up, a 30 s stop
    timeout: the stop returns long before either)."""
    import multiprocessing

    from planner_api.pool.template import WarmTemplate

    template = WarmTemplate(
        multiprocessing.get_context("spawn"), None, functools.partial(time.sleep, 60.0), None, 0
    )
    template.start()
    assert template.wait_warm(0.2) is False  # warming
    t0 = time.monotonic()
    template.stop(timeout_s=30.0)
    assert not template._process.is_alive()  # type: ignore[union-attr]
    assert time.monotonic() - t0 < 20.0  # a hang guard: not the 30 s join
