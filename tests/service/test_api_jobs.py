"""Long jobs: ``POST /v1/jobs`` (202 with ``id`` and ``status``), ``GET /v1/jobs/{id}``
(``result`` = the endpoint's own answer), ``DELETE /v1/jobs/{id}`` (the worker freed within a
second), bounded keeping (time and count, then 404 naming the bounds), validation located
under ``body.request``, a failing job's error as the endpoint's error answer, and the typed
client's ``submit_job`` / ``job`` / ``jobs`` / ``cancel_job``.

The oracle of a result is the endpoint itself, called directly on the same service. One
in-process service for the module (real worker processes, no warm-up: the jobs are cheap or
sleep), its plan job replaced by one that sleeps ``planner.time_budget_s`` and answers its
worker's pid.
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import httpx
import pytest

from planner.client import PlannerClient
from planner.endpoints import UNBOUNDED, JobBudget
from planner.wire import PlanRequest, PlanResponse, RegionsResponse, SequenceResponse
from planner_api.routes.plan import get_plan_function

START = {"q": [0.0, 1.0, 2.0], "assembly_mode": "+"}
PLAN = {"start": START, "goal": {"p": [0.3, 0.1, 0.2]}}
TTL_S = 3.0
SLACK_S = 5.0  # on top of a bound: a kill and a reader thread on a loaded machine


def _sleep_pid(request: PlanRequest, budget: JobBudget = UNBOUNDED) -> PlanResponse:
    time.sleep(request.planner.time_budget_s)
    return PlanResponse(status="timeout", message=str(os.getpid()))


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


@pytest.fixture(scope="module")
def svc(client_factory, tmp_path_factory):
    """The module's service, its jobs in a store of its own (the bounds count its jobs only;
    one tenant may fill them all)."""
    store = str(tmp_path_factory.mktemp("jobs") / "store.db")
    client = client_factory(
        workers=2,
        jobs_running=1,
        max_jobs=3,
        jobs_per_tenant=3,
        job_ttl_s=TTL_S,
        scene_store=store,
        warm=False,
    )
    client.app.dependency_overrides[get_plan_function] = lambda: _sleep_pid
    with client as c:
        yield c


def _wait(c, job_id: str, statuses: set[str], timeout_s: float = 120.0) -> dict:
    end = time.monotonic() + timeout_s
    while True:
        r = c.get(f"/v1/jobs/{job_id}")
        assert r.status_code == 200, r.text
        if r.json()["status"] in statuses:
            return r.json()
        assert time.monotonic() < end, r.json()
        time.sleep(0.02)


def _sleeper(seconds: float) -> dict:
    return {"kind": "plan", "request": {**PLAN, "planner": {"time_budget_s": seconds}}}


def test_a_job_answers_202_and_its_result_is_the_endpoints_answer(svc):
    request = {"design": {"L0": 0.3, "L1": 0.5, "L2": 0.6}, "resolution": 32}
    r = svc.post("/v1/jobs", json={"kind": "regions", "request": request})
    assert r.status_code == 202, r.text
    submitted = r.json()
    assert submitted["status"] in ("queued", "running") and submitted["result"] is None
    assert r.headers["location"] == f"/v1/jobs/{submitted['id']}"
    done = _wait(svc, submitted["id"], {"done", "failed"})
    assert done["status"] == "done", done
    direct = svc.post("/v1/design/regions", json=request)
    assert direct.status_code == 200
    got = RegionsResponse.model_validate(done["result"]).model_dump(exclude={"diagnostics"})
    want = RegionsResponse.model_validate(direct.json()).model_dump(exclude={"diagnostics"})
    got.pop("computation_time_s", None), want.pop("computation_time_s", None)
    assert got == want
    assert done["submitted_at"] <= done["started_at"] <= done["finished_at"] < done["expires_at"]


def test_a_bad_job_request_is_a_422_under_body_request(svc):
    r = svc.post("/v1/jobs", json={"kind": "regions", "request": {"resolution": 3}})
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "request", "resolution"]
    r = svc.post("/v1/jobs", json={"kind": "dance", "request": {}})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "kind"]
    too_long = _sleeper(1e6)
    r = svc.post("/v1/jobs", json=too_long)
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "request", "planner", "time_budget_s"]


def test_a_job_that_fails_keeps_the_endpoints_error_answer(svc):
    # reach null without L1_bounds: the job's own rule (not the schema's), found in the worker
    request = {"objective": "volume", "reach": None, "L2_bounds": [0.1, 0.5]}
    r = svc.post("/v1/jobs", json={"kind": "design_optimize", "request": request})
    assert r.status_code == 202, r.text
    failed = _wait(svc, r.json()["id"], {"done", "failed"})
    direct = svc.post("/v1/design/optimize", json=request)
    assert failed["status"] == "failed" and direct.status_code == 422
    assert failed["error"] == {"status_code": 422, "detail": direct.json()["detail"]}


def test_cancelling_a_running_job_frees_its_worker_within_a_second(svc):
    first = svc.post("/v1/jobs", json=_sleeper(30.0)).json()
    second = svc.post("/v1/jobs", json=_sleeper(30.0)).json()  # waits: one job at a time
    _wait(svc, first["id"], {"running"})
    time.sleep(0.2)
    assert svc.get(f"/v1/jobs/{second['id']}").json()["status"] == "queued"
    pool = svc.app.state.pool
    end = time.monotonic() + 30
    while not any(w.state == "busy" for w in pool._workers):  # the job reached its worker
        assert time.monotonic() < end
        time.sleep(0.02)
    busy = next(w.process.pid for w in pool._workers if w.state == "busy")
    t0 = time.monotonic()
    r = svc.delete(f"/v1/jobs/{first['id']}")
    assert r.status_code == 200 and r.json()["status"] == "cancelled"
    while _alive(busy):
        assert time.monotonic() - t0 < 1.0 + SLACK_S, "the cancelled job's worker still runs"
        time.sleep(0.02)
    assert svc.delete(f"/v1/jobs/{second['id']}").json()["status"] == "cancelled"  # queued
    assert svc.get(f"/v1/jobs/{first['id']}").json()["status"] == "cancelled"


def test_jobs_are_kept_a_bounded_time_and_count_then_404(svc):
    quick = _sleeper(0.01)
    ids = []
    for _ in range(3):
        r = svc.post("/v1/jobs", json=quick)
        assert r.status_code == 202, r.text
        ids.append(r.json()["id"])
        _wait(svc, ids[-1], {"done"})
    r = svc.post("/v1/jobs", json=quick)  # a fourth: the oldest finished one is evicted
    assert r.status_code == 202
    gone = svc.get(f"/v1/jobs/{ids[0]}")
    assert gone.status_code == 404
    detail = gone.json()["detail"][0]
    assert detail["type"] == "job_not_found"
    assert "PLANNER_JOB_TTL_S" in detail["msg"] and "PLANNER_MAX_JOBS" in detail["msg"]
    newest = r.json()["id"]
    finished = _wait(svc, newest, {"done"})
    assert finished["result"]["status"] == "timeout"  # the sleeping job's own answer
    time.sleep(max(finished["expires_at"] - time.time(), 0.0) + 0.1)
    assert svc.get(f"/v1/jobs/{newest}").status_code == 404  # past its time to live


def test_a_full_job_list_of_unfinished_jobs_refuses_with_503(svc):
    ids = [svc.post("/v1/jobs", json=_sleeper(30.0)).json()["id"] for _ in range(3)]
    try:
        r = svc.post("/v1/jobs", json=_sleeper(0.01))
        assert r.status_code == 503 and r.json()["detail"][0]["type"] == "too_many_jobs"
        assert "retry-after" in r.headers
    finally:
        for job_id in ids:
            svc.delete(f"/v1/jobs/{job_id}")


def test_a_method_the_job_path_does_not_take_is_405_naming_both_it_takes(svc):
    r = svc.request("PUT", "/v1/jobs/abc", json={})
    assert r.status_code == 405 and r.headers["allow"] == "DELETE, GET"


def _forwarding(c) -> httpx.MockTransport:
    def handle(request: httpx.Request) -> httpx.Response:
        r = c.request(
            request.method,
            request.url.path,
            content=request.content,
            headers={"content-type": "application/json"},
        )
        return httpx.Response(r.status_code, content=r.content, headers=r.headers)

    return httpx.MockTransport(handle)


def test_the_client_submits_polls_and_cancels(svc):
    with PlannerClient("http://planner.test", transport=_forwarding(svc)) as client:
        submitted = client.submit_job("plan", PlanRequest.model_validate(_sleeper(0.01)["request"]))
        assert submitted.status in ("queued", "running")
        end = time.monotonic() + 120
        while (status := client.job(submitted.id)).status != "done":
            assert time.monotonic() < end, status
            time.sleep(0.02)
        assert PlanResponse.model_validate(status.result).status == "timeout"
        long = client.submit_job("plan", _sleeper(30.0)["request"])
        listed = client.jobs().root  # the listing, oldest first
        assert [j.id for j in listed[-2:]] == [submitted.id, long.id]
        assert listed[-2].status == "done" and listed[-1].status in ("queued", "running")
        assert client.cancel_job(long.id).status == "cancelled"


#: A small sequence: two stops near the start and back (a few planned legs, timed).
SEQUENCE = {
    "start": {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"},
    "targets": [
        {"goal": {"p": [0.35, -0.1, -0.4]}, "stop": True},
        {"goal": {"p": [0.35, 0.2, -0.4]}, "stop": True},
    ],
    "cycle": True,
    "planner": {"seed": 3},
    "timing": {"sample_rate_hz": 50},
}


def _without_durations(answer: dict) -> dict:
    """A sequence answer without what varies from run to run (computation times)."""
    model = SequenceResponse.model_validate(answer).model_dump()
    model.pop("diagnostics", None)
    for leg in model.get("legs") or []:
        if isinstance(leg, dict):
            leg.pop("diagnostics", None)
    return model


def test_a_sequence_job_answers_what_the_endpoint_answers(svc):
    r = svc.post("/v1/jobs", json={"kind": "sequence", "request": SEQUENCE})
    assert r.status_code == 202, r.text
    done = _wait(svc, r.json()["id"], {"done", "failed"})
    assert done["status"] == "done", done
    direct = svc.post("/v1/sequence", json=SEQUENCE)
    assert direct.status_code == 200, direct.text
    assert done["result"]["status"] == direct.json()["status"]
    assert _without_durations(done["result"]) == _without_durations(direct.json())


def test_a_sequence_job_is_held_to_the_endpoints_limits(svc):
    many = {**SEQUENCE, "targets": SEQUENCE["targets"] * 40}
    r = svc.post("/v1/jobs", json={"kind": "sequence", "request": many})
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "request", "targets"]
    r = svc.post("/v1/jobs", json={"kind": "sequence", "request": {**SEQUENCE, "targets": []}})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"][:3] == [
        "body",
        "request",
        "targets",
    ]


def test_a_job_submitted_to_a_saturated_pool_waits_queued_then_runs(client_factory):
    """One worker, no queue: an interactive request holds the pool (a second one would be a
    503). A long job submitted meanwhile is accepted (202), stays ``queued`` while the pool is
    full, and runs when the worker frees: it does not fail with the pool's 503."""
    client = client_factory(workers=1, queue_size=0, jobs_running=1, max_jobs=3, warm=False)
    client.app.dependency_overrides[get_plan_function] = lambda: _sleep_pid
    with client as c:
        held = {}
        body = {**PLAN, "planner": {"time_budget_s": 3.0}}
        holder = threading.Thread(target=lambda: held.update(r=c.post("/v1/plan", json=body)))
        t_hold = time.time()
        holder.start()
        pool = c.app.state.pool
        end = time.monotonic() + 60
        while pool.in_flight < pool.capacity:  # the interactive request holds the worker
            assert time.monotonic() < end
            time.sleep(0.02)
        assert c.post("/v1/plan", json=body).status_code == 503  # the pool is full indeed
        r = c.post("/v1/jobs", json=_sleeper(0.01))
        assert r.status_code == 202, r.text
        job_id = r.json()["id"]
        time.sleep(0.5)
        assert c.get(f"/v1/jobs/{job_id}").json()["status"] == "queued"
        done = _wait(c, job_id, {"done", "failed"})
        holder.join()
        assert held["r"].status_code == 200
        assert done["status"] == "done", done
        assert done["result"]["status"] == "timeout"  # the sleeping job's own answer
        # it ran once the worker was free: after the interactive job's 3 s of sleep
        assert done["started_at"] >= t_hold + 2.9
