"""The long jobs' memory (their results in the store's ``jobs`` table) is bounded: one result by ``PLANNER_JOB_RESULT_MAX_MB`` (a trajectory
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
from planner_api.store_access import StoreAccess


def _answer(size: int):  # type: ignore[no-untyped-def]
    async def run(deadline: float) -> bytes:
        return b"x" * size

    return run


def _jobs(path, **bounds) -> JobStore:  # type: ignore[no-untyped-def]
    """A job store on a SQLite file of the test's own (as the service's, without a pool)."""
    access = StoreAccess(
        str(path), timeout_s=5, threads=2, retry_after_s=1, job_ttl_s=bounds.get("ttl_s", 60)
    )
    return JobStore(access, running=1, timeout_s=10, **{"ttl_s": 60, **bounds})


async def _finish(store: JobStore, job_id: str) -> None:
    task = store._tasks.get(job_id)
    if task is not None:
        await task


def _held(store: JobStore) -> tuple[int, list[str]]:
    """The bytes of the results in the table, and the ids kept, in submission order."""
    with store.access._opened()._read() as con:
        (held,) = con.execute("SELECT COALESCE(SUM(length(result)), 0) FROM jobs").fetchone()
        ids = [r[0] for r in con.execute("SELECT id FROM jobs ORDER BY submitted_at, id")]
    return int(held), ids


def test_kept_results_stay_within_the_bound_and_the_oldest_go_first(tmp_path):
    async def scenario() -> None:
        store = _jobs(tmp_path / "s.db", max_jobs=100, max_result_bytes=1000, max_total_bytes=2500)
        ids = []
        for _ in range(6):
            row = await store.submit("plan", _answer(1000))
            await _finish(store, row.id)
            ids.append(row.id)
            held, _ = _held(store)
            assert held <= 2500
        assert _held(store) == (2000, ids[-2:])  # two of 1000 bytes fit in 2500
        with pytest.raises(JobNotFoundError, match="PLANNER_JOBS_MAX_MB"):
            await store.get(ids[0])
        assert (await store.get(ids[-1])).status == "done"
        store.access.close()

    asyncio.run(scenario())


def test_a_result_over_its_bound_fails_the_job_and_holds_nothing(tmp_path):
    async def scenario() -> None:
        store = _jobs(tmp_path / "s.db", max_jobs=10, max_result_bytes=1000, max_total_bytes=2000)
        row = await store.submit("regions", _answer(1001))
        await _finish(store, row.id)
        row = await store.get(row.id)
        assert row.status == "failed" and row.result is None and _held(store)[0] == 0
        assert row.error is not None and row.error.status_code == 422
        (detail,) = row.error.detail
        assert detail.type == "result_too_large"
        assert "PLANNER_JOB_RESULT_MAX_MB" in detail.msg
        store.access.close()

    asyncio.run(scenario())


def test_expired_and_count_evicted_jobs_give_their_bytes_back(tmp_path):
    async def scenario() -> None:
        store = _jobs(
            tmp_path / "s.db", max_jobs=2, ttl_s=0.5, max_result_bytes=100, max_total_bytes=1000
        )
        for _ in range(3):  # the third evicts the first by count
            await _finish(store, (await store.submit("plan", _answer(100))).id)
        held, ids = _held(store)
        assert held == 200 and len(ids) == 2
        time.sleep(0.6)
        assert await store.list() == []  # expired: no longer answered
        await store.access.jobs(lambda t: t.sweep(), write=True)
        assert _held(store) == (0, [])  # and forgotten by the next write
        store.access.close()

    asyncio.run(scenario())


def test_a_result_bound_above_the_total_is_refused_at_start(monkeypatch):
    monkeypatch.setenv("PLANNER_JOB_RESULT_MAX_MB", "64")
    monkeypatch.setenv("PLANNER_JOBS_MAX_MB", "32")
    with pytest.raises(ValidationError, match=r"PLANNER_JOB_RESULT_MAX_MB.*PLANNER_JOBS_MAX_MB"):
        Settings()
    monkeypatch.setenv("PLANNER_JOBS_MAX_MB", "0")
    with pytest.raises(ValidationError, match="jobs_max_mb"):
        Settings()
    monkeypatch.delenv("PLANNER_JOBS_MAX_MB")
    monkeypatch.delenv("PLANNER_JOB_RESULT_MAX_MB")
    monkeypatch.setenv("PLANNER_MAX_JOBS", "8")
    assert Settings().jobs_per_tenant == 4  # half of PLANNER_MAX_JOBS by default
    monkeypatch.setenv("PLANNER_JOBS_PER_TENANT", "9")
    with pytest.raises(ValidationError, match=r"PLANNER_JOBS_PER_TENANT.*PLANNER_MAX_JOBS"):
        Settings()
    monkeypatch.setenv("PLANNER_JOBS_PER_TENANT", "0")
    with pytest.raises(ValidationError, match="jobs_per_tenant"):
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
            "done",
            "failed",
        ):
            assert time.monotonic() < end, job
            time.sleep(0.02)
        assert job["status"] == "failed", job["status"]
        assert job["error"]["status_code"] == 422
        assert "sample_rate_hz" in job["error"]["detail"][0]["loc"]
