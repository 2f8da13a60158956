"""No job outlives its request: the worker pool's watchdog kills the worker of a job that has
computed for the overrun grace (CPU time) past its deadline, or that is still running the
overrun maximum (wall time) after it, a cancelled job (its caller's task cancelled, or its client
disconnected) has its worker killed at once, a worker holding too much memory after a job is
recycled (its replacement warm first), and a replacement serves the next job.

Real worker processes (the property is about processes); the jobs sleep or hold memory, so
nothing here depends on the machine's speed: every bound is the property's own (deadline +
grace) plus a generous slack, far below what the job would take if it were not stopped.
"""

from __future__ import annotations

import asyncio
import os
import socket
import time
from pathlib import Path

import httpx
import pytest

from planner_api.exceptions import DeadlineExceededError, JobCancelledError
from planner_api.pool import WorkerPool

STARTUP_TIMEOUT_S = 180.0  # as tests/conftest.py
#: Slack on top of a bound, s: a kill, a pipe's end and the event loop on a loaded machine.
SLACK_S = 5.0
#: What a job would take if nothing stopped it, s (far beyond every bound below).
LONG_S = 120.0

_HELD: list[bytearray] = []


def _hold(mb: int) -> tuple[int, int]:
    """Keep ``mb`` MB alive in this worker (touched, so resident); (pid, RSS bytes)."""
    from planner_api.pool.process import resident_bytes

    if mb:
        block = bytearray(mb * 1024 * 1024)
        block[::4096] = b"x" * len(block[::4096])
        _HELD.append(block)
    return os.getpid(), resident_bytes() or 0


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


async def _until(predicate, timeout_s: float, what: str) -> float:
    """Poll ``predicate`` every 20 ms; the time it became true (monotonic)."""
    end = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < end, what
        await asyncio.sleep(0.02)
    return time.monotonic()


async def _started_pool(**options: object) -> WorkerPool:
    pool = WorkerPool(1, 1, warm_up=None, **options)  # type: ignore[arg-type]
    await pool.start()
    await _until(lambda: pool.state == "ready", STARTUP_TIMEOUT_S, "the worker never started")
    return pool


def _spin(seconds: float) -> None:
    """Compute (no sleep) for ``seconds``: a job that spends CPU past its deadline."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        pass


def test_a_job_past_its_deadline_has_its_worker_killed_and_replaced():
    grace = 0.3

    async def scenario() -> None:
        pool = await _started_pool(overrun_grace_s=grace, overrun_max_s=2.0)
        try:
            (old,) = pool.pids
            start = time.monotonic()
            with pytest.raises(DeadlineExceededError):
                await pool.run(_spin, LONG_S, deadline=start + 1.0)
            # the caller is answered at the deadline; the worker is killed at deadline + grace
            gone = await _until(lambda: not _alive(old), 1.0 + grace + SLACK_S, "still alive")
            assert gone - start >= 1.0 + grace - 0.05  # not before its grace
            await _until(
                lambda: old not in pool.pids and pool.state == "ready",
                STARTUP_TIMEOUT_S,
                "no replacement",
            )
            assert pool.kills == 1 and pool.restarts == 0
            assert await pool.run(abs, -3, deadline=time.monotonic() + 60) == 3
            # a job submitted with a deadline and never awaited fails the same way
            # (awaited: the pool's event loop delivers it)
            future = pool.submit(time.sleep, LONG_S, deadline=time.monotonic() + 0.2)
            with pytest.raises(DeadlineExceededError):
                await asyncio.wait_for(asyncio.wrap_future(future), 0.2 + grace + SLACK_S)
        finally:
            pool.shutdown(timeout_s=5)

    asyncio.run(scenario())


def test_the_grace_is_cpu_time_and_the_maximum_wall_time():
    """A job that waits past its deadline (sleeps: it spends no CPU, as a job starved by a
    busy machine) is not killed when the wall-clock grace has passed, only at the deadline
    plus the overrun maximum."""
    grace, most = 0.2, 2.0

    async def scenario() -> None:
        pool = await _started_pool(overrun_grace_s=grace, overrun_max_s=most)
        try:
            (old,) = pool.pids
            start = time.monotonic()
            with pytest.raises(DeadlineExceededError):
                await pool.run(time.sleep, LONG_S, deadline=start + 0.5)
            await asyncio.sleep(max(0.0, start + 0.5 + grace + 0.8 - time.monotonic()))
            assert _alive(old), "killed for wall time within its CPU grace"
            gone = await _until(lambda: not _alive(old), 0.5 + most + SLACK_S, "still alive")
            assert gone - start >= 0.5 + most - 0.05  # not before the maximum
            assert pool.kills == 1
        finally:
            pool.shutdown(timeout_s=5)

    asyncio.run(scenario())


def test_a_cancelled_job_frees_its_worker_within_a_second():
    """Cancelling the caller's task (what a DELETE of a long job does) and cancelling the
    future (:meth:`WorkerPool.cancel`) each kill the running job's worker at once."""

    async def scenario() -> None:
        pool = await _started_pool(overrun_grace_s=30.0)  # the grace plays no part
        try:
            for how in ("task", "future"):
                (old,) = pool.pids
                if how == "task":
                    task = asyncio.ensure_future(
                        pool.run(time.sleep, LONG_S, deadline=time.monotonic() + LONG_S)
                    )
                else:
                    future = pool.submit(time.sleep, LONG_S)
                await _until(lambda: pool.in_flight == 1 and _busy(pool), 30, "never ran")
                t0 = time.monotonic()
                if how == "task":
                    task.cancel()
                    with pytest.raises(asyncio.CancelledError):
                        await task
                else:
                    pool.cancel(future)
                    with pytest.raises(JobCancelledError):
                        await asyncio.wait_for(asyncio.wrap_future(future), 1.0 + SLACK_S)
                gone = await _until(lambda o=old: not _alive(o), 1.0 + SLACK_S, "still alive")
                assert gone - t0 < 1.0 + SLACK_S
                await _until(
                    lambda o=old: o not in pool.pids and pool.state == "ready",
                    STARTUP_TIMEOUT_S,
                    "no replacement",
                )
                assert pool.in_flight == 0
            assert pool.kills == 2 and pool.restarts == 0
            assert await pool.run(abs, -4, deadline=time.monotonic() + 60) == 4
        finally:
            pool.shutdown(timeout_s=5)

    asyncio.run(scenario())


def _busy(pool: WorkerPool) -> bool:
    with pool._lock:  # the pool's own view: the job is running in a worker
        return any(w.state == "busy" for w in pool._workers)


def test_a_worker_over_its_memory_bound_is_recycled_warm_first():
    """A job leaves 320 MB held in its worker, over the bound of 256 MB: the next answer comes
    from a new process, the old one has exited, and at no moment was there no warm worker
    (the replacement warmed up while the old one still served)."""

    async def scenario() -> None:
        pool = await _started_pool(max_rss_mb=256)
        try:
            pid, rss = await pool.run(_hold, 0, deadline=time.monotonic() + 60)
            assert rss < 256 * 2**20, rss  # the bound is above a fresh worker's own memory
            assert pool.recycles == 0
            warm: list[int] = []
            held_pid, held_rss = await pool.run(_hold, 320, deadline=time.monotonic() + 60)
            assert held_pid == pid and held_rss > 320 * 2**20
            end = time.monotonic() + STARTUP_TIMEOUT_S
            while _alive(pid) or pool.pids == [pid]:
                warm.append(pool.warm_workers)
                assert time.monotonic() < end, "the worker was never recycled"
                await asyncio.sleep(0.01)
            assert min(warm) >= 1, warm  # the old one served until the new one was warm
            await _until(lambda: pool.state == "ready", STARTUP_TIMEOUT_S, "not ready")
            new_pid, new_rss = await pool.run(_hold, 0, deadline=time.monotonic() + 60)
            assert new_pid != pid and new_rss < 256 * 2**20
            assert pool.recycles == 1 and pool.restarts == 0 and pool.kills == 0
        finally:
            pool.shutdown(timeout_s=5)

    asyncio.run(scenario())


def _niceness(_: object) -> int:
    """The niceness of the thread that runs the jobs (Linux: niceness is per thread)."""
    return os.nice(0)


def test_workers_run_at_the_configured_niceness_above_the_server():
    """``nice=5``: once warm, the worker process (its main thread, which runs the jobs) is 5
    nicer than the server (capped at 19); the server keeps its own priority."""

    async def scenario() -> None:
        server = os.nice(0)
        pool = await _started_pool(nice=5)
        try:
            (first,) = pool.pids
            assert os.getpriority(os.PRIO_PROCESS, first) == min(server + 5, 19)
            job_thread = await pool.run(_niceness, 0, deadline=time.monotonic() + 60)
            assert job_thread == min(server + 5, 19)
            assert os.nice(0) == server  # the server itself is untouched
        finally:
            pool.shutdown(timeout_s=5)

    asyncio.run(scenario())


def test_a_client_that_disconnects_has_its_job_cancelled(tmp_path, unused_port):
    """A real server: a plan request whose job would sleep 20 s, its connection closed once
    the job runs: the worker is killed within a second (not at the 30 s deadline), a warm
    replacement serves the next request, and the access log records 499."""
    import json

    from test_ops_shutdown import PLAN, _start, _wait_started

    process, log = _start(tmp_path, unused_port)
    url = f"http://127.0.0.1:{unused_port}"
    try:
        body = json.dumps({**PLAN, "planner": {"time_budget_s": 20.0}}).encode()
        sock = socket.create_connection(("127.0.0.1", unused_port), timeout=10)
        sock.sendall(
            b"POST /v1/plan HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
            b"X-Request-ID: gone-1\r\nContent-Length: "
            + str(len(body)).encode()
            + b"\r\n\r\n"
            + body
        )
        worker = _wait_started(tmp_path / "worker.pid")
        t0 = time.monotonic()
        sock.close()
        while _alive(worker):
            assert time.monotonic() - t0 < 1.0 + SLACK_S, "the worker still runs the job"
            time.sleep(0.02)
        end = time.monotonic() + STARTUP_TIMEOUT_S
        while httpx.get(f"{url}/v1/ready").status_code != 200:
            assert time.monotonic() < end, log.read_text()[-3000:]
            time.sleep(0.05)
        quick = {**PLAN, "planner": {"time_budget_s": 0.01}}
        r = httpx.post(f"{url}/v1/plan", json=quick, timeout=60)
        assert r.status_code == 200 and r.json()["message"] not in ("", str(worker))
        lines = [json.loads(x) for x in log.read_text().splitlines() if x.startswith("{")]
        access = [x for x in lines if x["logger"] == "api.access" and x["path"] == "/v1/plan"]
        assert ("gone-1", 499) in [(x["request_id"], x["status"]) for x in access]
    finally:
        process.terminate()
        process.wait(timeout=30)
