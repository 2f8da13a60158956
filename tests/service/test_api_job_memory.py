"""The long jobs' memory is bounded: one result by ``PLANNER_JOB_RESULT_MAX_MB`` (a trajectory
job's samples bounded before they exist, any other result failing its job with
``result_too_large``), all kept results by ``PLANNER_JOBS_MAX_MB`` (the oldest finished jobs
evicted first, their ids then 404 naming the bound); the two settings checked together at
start. The oracle of the held bytes is the sum of the results' lengths, counted here."""

from __future__ import annotations

import asyncio
import time

import pytest
from pydantic import ValidationError

from planner_api.exceptions import JobNotFoundError
from planner_api.job_store import JobStore
from planner_api.settings import Settings


def _answer(size: int):  # type: ignore[no-untyped-def]
    async def run(deadline: float) -> bytes:
        return b"x" * size

    return run


async def _finish(store: JobStore, job_id: str) -> None:
    entry = store.get(job_id)
    assert entry.task is not None
    await entry.task


def test_kept_results_stay_within_the_bound_and_the_oldest_go_first():
    async def scenario() -> None:
        store = JobStore(
            max_jobs=100, ttl_s=60, running=1, timeout_s=10,
            max_result_bytes=1000, max_total_bytes=2500,
        )  # fmt: skip
        ids = []
        for _ in range(6):
            entry = store.submit("plan", _answer(1000))
            await _finish(store, entry.id)
            ids.append(entry.id)
            kept = [store._jobs[k].result for k in store._jobs]
            assert store.held_bytes == sum(len(r) for r in kept if r is not None) <= 2500
        assert [k for k in store._jobs] == ids[-2:]  # two of 1000 bytes fit in 2500
        with pytest.raises(JobNotFoundError, match="PLANNER_JOBS_MAX_MB"):
            store.get(ids[0])
        assert store.get(ids[-1]).status == "done"

    asyncio.run(scenario())


def test_a_result_over_its_bound_fails_the_job_and_holds_nothing():
    async def scenario() -> None:
        store = JobStore(
            max_jobs=10, ttl_s=60, running=1, timeout_s=10,
            max_result_bytes=1000, max_total_bytes=2000,
        )  # fmt: skip
        entry = store.submit("regions", _answer(1001))
        await _finish(store, entry.id)
        assert entry.status == "failed" and entry.result is None and store.held_bytes == 0
        assert entry.error is not None and entry.error.status_code == 422
        (detail,) = entry.error.detail
        assert detail.type == "result_too_large"
        assert "PLANNER_JOB_RESULT_MAX_MB" in detail.msg

    asyncio.run(scenario())


def test_expired_and_count_evicted_jobs_give_their_bytes_back():
    async def scenario() -> None:
        store = JobStore(
            max_jobs=2, ttl_s=0.05, running=1, timeout_s=10,
            max_result_bytes=100, max_total_bytes=1000,
        )  # fmt: skip
        for _ in range(3):  # the third evicts the first by count
            await _finish(store, store.submit("plan", _answer(100)).id)
        assert store.held_bytes == 200
        time.sleep(0.06)
        store._forget_expired()
        assert store.held_bytes == 0 and not store._jobs

    asyncio.run(scenario())


def test_a_result_bound_above_the_total_is_refused_at_start(monkeypatch):
    monkeypatch.setenv("PLANNER_JOB_RESULT_MAX_MB", "64")
    monkeypatch.setenv("PLANNER_JOBS_MAX_MB", "32")
    with pytest.raises(ValidationError, match=r"PLANNER_JOB_RESULT_MAX_MB.*PLANNER_JOBS_MAX_MB"):
        Settings()
    monkeypatch.setenv("PLANNER_JOBS_MAX_MB", "0")
    with pytest.raises(ValidationError, match="jobs_max_mb"):
        Settings()


def test_a_trajectory_job_is_bounded_before_its_samples_exist(client_factory):
    """A timing job whose samples would take more than the result bound (but less than a
    request's answer) fails with the 422 a request gets, naming timing.sample_rate_hz."""
    request = {
        "waypoints": [[0.0, 2.0, 1.0], [0.6, 2.3, 1.2]],
        "method": "ruckig",
        "sample_rate_hz": 10000,
    }
    with client_factory(workers=1, warm=False, job_result_max_mb=0.25) as c:
        direct = c.post("/v1/timing", json=request)
        assert direct.status_code == 200, direct.text  # a request may carry it
        assert len(direct.content) > 0.25 * 2**20
        r = c.post("/v1/jobs", json={"kind": "timing", "request": request})
        assert r.status_code == 202, r.text
        end = time.monotonic() + 120
        while (job := c.get(f"/v1/jobs/{r.json()['id']}").json())["status"] not in (
            "done", "failed",
        ):  # fmt: skip
            assert time.monotonic() < end, job
            time.sleep(0.02)
        assert job["status"] == "failed", job["status"]
        assert job["error"]["status_code"] == 422
        assert "sample_rate_hz" in job["error"]["detail"][0]["loc"]
