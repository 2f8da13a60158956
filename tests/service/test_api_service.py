"""The service machinery: settings, API key, readiness, the worker pool (saturation -> 503,
deadline -> 504, crashed worker -> 502 and recovery, fan-out over processes), the plan routes'
wiring, and the OpenAPI document."""

from __future__ import annotations

import asyncio
import math
import os
import threading
import time

import pytest
from pydantic import ValidationError

from planner.endpoints import UNBOUNDED, JobBudget
from planner.wire import PlanRequest, PlanResponse
from planner_api.exceptions import PoolSaturatedError
from planner_api.pool import WorkerPool
from planner_api.routes.plan import get_plan_function
from planner_api.settings import Settings

START = {"q": [0.0, 1.0, 2.0], "assembly_mode": "+"}
STARTUP_TIMEOUT_S = 180.0  # as tests/conftest.py: imports on a fresh, loaded machine
PLAN = {"start": START, "goal": {"p": [0.3, 0.1, 0.2]}}


# ---------------------------------------------------------------- jobs run in worker processes
def _echo_seed(request: PlanRequest, budget: JobBudget = UNBOUNDED) -> PlanResponse:
    return PlanResponse(status="no_path", message=str(request.planner.seed))


def _hold_until(flag: str, limit_s: float = 60.0) -> None:
    """Keep a worker busy until the file ``flag`` exists (at most ``limit_s``): a job that
    stays busy however slowly the test reaches its next request."""
    end = time.monotonic() + limit_s
    while not os.path.exists(flag) and time.monotonic() < end:
        time.sleep(0.01)


def _sleep_pid(request: PlanRequest, budget: JobBudget = UNBOUNDED) -> PlanResponse:
    time.sleep(request.planner.time_budget_s)
    return PlanResponse(status="timeout", message=str(os.getpid()))


def _die(_request: PlanRequest, _budget: JobBudget = UNBOUNDED) -> PlanResponse:
    os._exit(3)


def _sleep_then_pid(seconds: float) -> int:
    time.sleep(seconds)
    return os.getpid()


def _wait_ready(client, timeout_s: float = 180.0) -> None:
    end = time.monotonic() + timeout_s
    while client.get("/v1/ready").status_code != 200:
        assert time.monotonic() < end, "workers never became ready"
        time.sleep(0.05)


def _wait_idle(pool: WorkerPool, timeout_s: float = 30.0) -> None:
    end = time.monotonic() + timeout_s
    while pool.in_flight:
        assert time.monotonic() < end, "jobs never finished"
        time.sleep(0.01)


# ---------------------------------------------------------------- settings
def test_settings_from_environment(monkeypatch):
    monkeypatch.setenv("PLANNER_WORKERS", "3")
    monkeypatch.setenv("PLANNER_MAX_BATCH", "7")
    monkeypatch.setenv("PLANNER_API_KEY", "")
    s = Settings()
    assert (s.workers, s.max_batch, s.queue_size, s.api_key) == (3, 7, 12, None)
    monkeypatch.setenv("PLANNER_API_KEY", "k")
    assert Settings().api_key.get_secret_value() == "k"
    monkeypatch.setenv("PLANNER_WORKERS", "0")
    with pytest.raises(ValidationError, match="workers"):
        Settings()
    monkeypatch.setenv("PLANNER_WORKERS", "1")
    monkeypatch.setenv("PLANNER_REQUEST_TIMEOUT_S", "nan")
    with pytest.raises(ValidationError, match="request_timeout_s"):
        Settings()


# ---------------------------------------------------------------- API key
def test_api_key_guards_every_v1_route_but_the_probes(client_factory):
    with client_factory(api_key="s3cret", warm=False) as c:  # the key is the gate's
        assert c.get("/v1/health").status_code == 200
        assert c.get("/v1/ready").status_code == 200  # probes need no key
        for method, path, body in [
            ("GET", "/v1/version", None),
            ("GET", "/v1/designs", None),
            ("POST", "/v1/fk", {"q": [0, 1, 2]}),
            ("POST", "/v1/plan", PLAN),
        ]:
            r = c.request(method, path, json=body)
            assert r.status_code == 401, path
            assert r.headers["www-authenticate"] == "Bearer"
            assert r.json()["detail"][0]["type"] == "unauthorized"
            r = c.request(method, path, json=body, headers={"X-API-Key": "wrong"})
            assert r.status_code == 401, path
        assert c.get("/v1/designs", headers={"X-API-Key": "s3cret"}).status_code == 200
        r = c.post("/v1/fk", json={"q": [0, 1, 2]}, headers={"Authorization": "Bearer s3cret"})
        assert r.status_code == 200
        r = c.post("/v1/fk", json={"q": [0, 1, 2]}, headers={"Authorization": "Basic s3cret"})
        assert r.status_code == 401


def test_app_without_its_lifespan_answers_503_not_500(client_factory):
    c = client_factory()  # not entered: the worker pool never starts
    r = c.post("/v1/plan", json=PLAN)  # (fk, run in the event loop, needs no pool)
    assert r.status_code == 503
    assert r.json()["detail"][0]["type"] == "not_running"
    assert c.get("/v1/health").status_code == 200


def test_no_key_configured_means_open(api):
    assert api.get("/v1/designs").status_code == 200


# ---------------------------------------------------------------- readiness and saturation
def test_ready_turns_200_once_workers_answer(client_factory):
    """'starting' (503, Retry-After) until the worker has announced itself, then 'ready'.
    The worker is not warmed: that ready waits for the warm-up is guarded by
    test_ops_workers.py (the first plan on a just-ready server is cheap) and by the dead
    worker's warm replacement below."""
    with client_factory(wait_ready=False, warm=False) as c:
        r = c.get("/v1/ready")
        if r.status_code == 503:  # the usual case: spawning and warming take a while
            assert r.json()["status"] == "starting" and r.headers["retry-after"] == "1"
            assert r.json()["warm"] == 0
        _wait_ready(c)
        assert c.get("/v1/ready").json() == {
            "status": "ready",
            "workers": 1,
            "warm": 1,
            "store": "ok",
        }


def test_saturated_pool_answers_503_with_retry_after_then_recovers(client_factory, tmp_path):
    with client_factory(workers=1, queue_size=0, retry_after_s=2, warm=False) as c:
        _wait_ready(c)
        pool: WorkerPool = c.app.state.pool
        c.app.dependency_overrides[get_plan_function] = lambda: _echo_seed
        # the only worker held until the 503 is seen (a fixed sleep of 0.5 s once ended
        # before a loaded machine's request arrived, which then found the worker free)
        flag = tmp_path / "release"
        busy = pool.submit(_hold_until, str(flag))
        r = c.post("/v1/plan", json=PLAN)  # (fk runs in the event loop: no worker needed)
        flag.touch()
        assert r.status_code == 503
        assert r.headers["retry-after"] == "2"
        assert r.json()["detail"][0]["type"] == "saturated"
        busy.result(timeout=90)
        _wait_idle(pool)
        assert c.post("/v1/plan", json=PLAN).status_code == 200
        c.app.dependency_overrides.clear()


def test_request_over_its_time_budget_is_504(client_factory):
    # a budget that a cheap plan job keeps even on a loaded machine, and a job twice as long;
    # the last plan must not pay its imports within those 3 s: the worker runs the job once
    # first, without a deadline (what the whole warm-up would do for it, and no more)
    with client_factory(workers=1, queue_size=2, request_timeout_s=3.0, warm=False) as c:
        _wait_ready(c)
        pool: WorkerPool = c.app.state.pool
        c.app.dependency_overrides[get_plan_function] = lambda: _echo_seed
        once = pool.submit(_echo_seed, PlanRequest.model_validate(PLAN))
        assert once.result(timeout=STARTUP_TIMEOUT_S).status == "no_path"
        busy = pool.submit(time.sleep, 6.0)  # the plan job waits behind it past its deadline
        r = c.post("/v1/plan", json=PLAN)
        assert r.status_code == 504
        assert r.json()["detail"][0]["type"] == "deadline_exceeded"
        busy.result(timeout=30)
        _wait_idle(pool)
        assert c.post("/v1/plan", json=PLAN).status_code == 200
        c.app.dependency_overrides.clear()


def test_pool_reserves_a_batch_all_or_nothing():
    async def scenario() -> None:
        pool = WorkerPool(1, 1, warm_up=None)
        await pool.start()
        try:
            with pytest.raises(PoolSaturatedError):
                await pool.map(abs, [-1, -2, -3], deadline=time.monotonic() + 30)
            assert pool.in_flight == 0
            assert await pool.map(abs, [-1, -2], deadline=time.monotonic() + 30) == [1, 2]
        finally:
            pool.shutdown()

    asyncio.run(scenario())


# ---------------------------------------------------------------- plan routes, fan-out, crashes
@pytest.fixture(scope="module")
def two_workers(client_factory):
    with client_factory(workers=2) as c:
        _wait_ready(c)
        yield c
        c.app.dependency_overrides.clear()


def test_plan_route_runs_the_planner(two_workers):
    """PLAN's goal P = (0.3, 0.1, 0.2) is 0.39 m from B = (0, 0.25, 0), inside leg B's inner
    shell |BP| >= L2 - L1 = 0.4 m of the default robot: the planner must say unreachable."""
    x, y, z = PLAN["goal"]["p"]
    assert math.dist((x, y, z), (0.0, 0.25, 0.0)) < 0.6 - 0.2
    r = two_workers.post("/v1/plan", json={**PLAN, "planner": {"seed": 1}})
    assert r.status_code == 200, r.text
    assert r.json()["status"] == "unreachable", r.json()["message"]


def test_batch_answers_in_request_order(two_workers):
    two_workers.app.dependency_overrides[get_plan_function] = lambda: _echo_seed
    seeds = [4, 8, 3, 1, 2, 7, 5, 6]
    body = {"requests": [{**PLAN, "planner": {"seed": s}} for s in seeds]}
    r = two_workers.post("/v1/plan/batch", json=body)
    assert r.status_code == 200, r.text
    results = r.json()["results"]
    assert [int(x["message"]) for x in results] == seeds
    assert {x["status"] for x in results} == {"no_path"}
    r = two_workers.post("/v1/plan", json={**PLAN, "planner": {"seed": 9}})
    assert r.status_code == 200 and r.json()["message"] == "9"


def test_batch_larger_than_the_pool_capacity_is_served_in_rounds(client_factory):
    """workers=1, queue_size=1: capacity 2, yet an idle service answers a batch of 5."""
    with client_factory(workers=1, queue_size=1, warm=False) as c:
        _wait_ready(c)
        c.app.dependency_overrides[get_plan_function] = lambda: _echo_seed
        seeds = [5, 3, 9, 1, 7]
        body = {"requests": [{**PLAN, "planner": {"seed": s}} for s in seeds]}
        r = c.post("/v1/plan/batch", json=body)
        assert r.status_code == 200, r.text
        assert [int(x["message"]) for x in r.json()["results"]] == seeds


def test_batch_runs_on_several_processes_without_blocking_the_loop(two_workers):
    two_workers.app.dependency_overrides[get_plan_function] = lambda: _sleep_pid
    body = {"requests": [{**PLAN, "planner": {"time_budget_s": 3.0}}] * 2}
    answer: dict = {}
    thread = threading.Thread(
        target=lambda: answer.update(r=two_workers.post("/v1/plan/batch", json=body))
    )
    thread.start()
    time.sleep(0.2)
    assert two_workers.get("/v1/health").status_code == 200
    assert thread.is_alive(), "health had to wait for the batch: the event loop was blocked"
    thread.join(30)
    pids = {int(x["message"]) for x in answer["r"].json()["results"]}
    assert len(pids) == 2 and os.getpid() not in pids


def test_a_dead_worker_fails_only_its_own_job_and_is_replaced_warm(two_workers):
    """One worker dies mid-job while the other runs a job: only the dead one's request gets
    the 502 (naming the exit), the other job completes, readiness stays 200 'ready' while a
    worker is warm (the survivor serves; a load balancer must not drop the replica), the
    replacement is forked warm from the template, and the next request succeeds."""
    pool: WorkerPool = two_workers.app.state.pool
    before, restarts = set(pool.pids), pool.restarts
    healthy = pool.submit(_sleep_then_pid, 1.0)  # occupies one worker
    two_workers.app.dependency_overrides[get_plan_function] = lambda: _die
    r = two_workers.post("/v1/plan", json=PLAN)  # lands on the other one, which dies
    assert r.status_code == 502
    assert r.json()["detail"][0]["type"] == "worker_crashed"
    assert "exit code 3" in r.json()["detail"][0]["msg"]
    ready = two_workers.get("/v1/ready")
    assert ready.status_code == 200 and ready.json()["status"] == "ready", ready.text
    assert ready.json()["warm"] >= 1
    assert healthy.result(timeout=60) in before  # the job on the healthy worker finished
    two_workers.app.dependency_overrides.clear()
    end = time.monotonic() + 60
    while pool.warm_workers < 2:
        assert time.monotonic() < end, "the dead worker was not replaced"
        time.sleep(0.01)
    assert len(set(pool.pids) - before) == 1 and len(pool.pids) == 2
    assert pool.restarts == restarts + 1
    r = two_workers.post("/v1/fk", json={"q": [0, 1, 2]})
    assert r.status_code == 200 and len(r.json()["postures"]) == 2


# ---------------------------------------------------------------- documentation
def test_openapi_lists_every_route_with_its_models(api):
    spec = api.get("/openapi.json").json()
    paths = spec["paths"]
    for path in [
        "/v1/health",
        "/v1/ready",
        "/v1/version",
        "/v1/designs",
        "/v1/fk",
        "/v1/ik",
        "/v1/analyze",
        "/v1/plan",
        "/v1/plan/batch",
    ]:
        assert path in paths, path
    schemas = spec["components"]["schemas"]
    assert {"PlanRequest", "PlanResponse", "DesignModel", "ErrorResponse"} <= set(schemas)
    assert "503" in paths["/v1/plan"]["post"]["responses"]
    assert api.get("/docs").status_code == 200
