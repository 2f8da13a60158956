"""Long jobs in the store: shared by replicas (two in-process apps on one PostgreSQL server
the test starts: a job submitted through one is polled, listed and cancelled through the
other, which kills its worker in the first; another tenant's job is a 404 on either), kept
over a restart (SQLite: a job running when the app stops is ``failed`` ``lost_on_restart``
in the next app on the same file, a finished one keeps its result), a row whose owner's
heartbeat is stale answers ``lost_on_restart``, and one tenant cannot pass
``PLANNER_JOBS_PER_TENANT`` (429).

The oracle of "the other replica ran it" is the worker's pid in the job's answer and the
running app's own task list; of "cancelled across replicas", the first app's worker process
gone. Real worker pools (warm=False), the plan job replaced by a sleep.
"""

from __future__ import annotations

import json
import os
import sqlite3
import time
import uuid
from pathlib import Path

import pytest

from planner.endpoints import UNBOUNDED, JobBudget
from planner.wire import PlanRequest, PlanResponse
from planner_api.routes.plan import get_plan_function

ALICE = {"X-API-Key": "alice-key"}
BOB = {"X-API-Key": "bob-key"}
KEYS = "alice:alice-key,bob:bob-key"
START = {"q": [0.0, 1.0, 2.0], "assembly_mode": "+"}
WAIT_S = 60.0  # the longest a loop waits for what it expects (never a timing assertion)


def _sleep_pid(request: PlanRequest, budget: JobBudget = UNBOUNDED) -> PlanResponse:
    time.sleep(request.planner.time_budget_s)
    return PlanResponse(status="timeout", message=str(os.getpid()))


def _sleeper(seconds: float) -> dict:
    request = {
        "start": START,
        "goal": {"p": [0.3, 0.1, 0.2]},
        "planner": {"time_budget_s": seconds},
    }
    return {"kind": "plan", "request": request}


def _app(client_factory, store: str, **settings):  # type: ignore[no-untyped-def]
    client = client_factory(scene_store=store, workers=1, warm=False, **settings)
    client.app.dependency_overrides[get_plan_function] = lambda: _sleep_pid
    return client


def _until(check, what: str):  # type: ignore[no-untyped-def]
    end = time.monotonic() + WAIT_S
    while not (got := check()):
        assert time.monotonic() < end, what
        time.sleep(0.02)
    return got


def _status(c, job_id: str, headers=None) -> dict:  # type: ignore[no-untyped-def]
    r = c.get(f"/v1/jobs/{job_id}", headers=headers or {})
    assert r.status_code == 200, r.text
    return r.json()


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


def test_two_replicas_on_postgresql_share_poll_list_and_cancel(client_factory, postgres_factory):
    with postgres_factory() as server:
        a_app = _app(client_factory, server.url, api_keys=KEYS)
        b_app = _app(client_factory, server.url, api_keys=KEYS)
        with a_app as a, b_app as b:
            quick = a.post("/v1/jobs", json=_sleeper(0.01), headers=ALICE)
            assert quick.status_code == 202, quick.text
            done = _until(
                lambda: (s := _status(b, quick.json()["id"], ALICE))["status"] == "done" and s,
                "the job submitted through A never answered done through B",
            )
            a_worker = a.app.state.pool._workers[0].process.pid
            assert done["result"]["message"] == str(a_worker)  # A's worker ran it

            long = a.post("/v1/jobs", json=_sleeper(30.0), headers=ALICE).json()
            _until(lambda: _status(b, long["id"], ALICE)["status"] == "running", "never running")
            listed = b.get("/v1/jobs", headers=ALICE).json()
            assert [j["id"] for j in listed] == [quick.json()["id"], long["id"]]
            assert [j["status"] for j in listed] == ["done", "running"]
            # another tenant: a 404 on either replica, an empty list
            for c in (a, b):
                r = c.get(f"/v1/jobs/{long['id']}", headers=BOB)
                assert r.status_code == 404 and r.json()["detail"][0]["type"] == "job_not_found"
                assert c.delete(f"/v1/jobs/{long['id']}", headers=BOB).status_code == 404
                assert c.get("/v1/jobs", headers=BOB).json() == []
            busy = _until(
                lambda: next(
                    (w.process.pid for w in a.app.state.pool._workers if w.state == "busy"), None
                ),
                "the job never reached A's worker",
            )
            r = b.delete(f"/v1/jobs/{long['id']}", headers=ALICE)
            assert r.status_code == 200 and r.json()["status"] == "cancelled"
            assert _status(a, long["id"], ALICE)["status"] == "cancelled"
            _until(lambda: not a.app.state.jobs._tasks, "A never stopped the job cancelled by B")
            _until(lambda: not _alive(busy), "the cancelled job's worker still runs in A")
            assert _status(b, long["id"], ALICE)["status"] == "cancelled"  # it stays so


def test_sqlite_a_restart_fails_unfinished_jobs_and_keeps_finished_ones(client_factory, tmp_path):
    store = str(tmp_path / "store.db")
    with _app(client_factory, store) as first:
        quick = first.post("/v1/jobs", json=_sleeper(0.01)).json()
        done = _until(
            lambda: (s := _status(first, quick["id"]))["status"] == "done" and s,
            "the quick job never finished",
        )
        long = first.post("/v1/jobs", json=_sleeper(30.0)).json()
        _until(lambda: _status(first, long["id"])["status"] == "running", "never running")
    with _app(client_factory, store) as second:
        lost = _status(second, long["id"])
        assert lost["status"] == "failed" and lost["finished_at"] is not None
        assert lost["error"]["status_code"] == 503
        (item,) = lost["error"]["detail"]
        assert item["type"] == "lost_on_restart"
        assert "restarted" in item["msg"] and "submit it again" in item["msg"]
        kept = _status(second, quick["id"])
        assert kept["status"] == "done" and kept["result"] == done["result"]
        listed = second.get("/v1/jobs").json()
        assert [(j["id"], j["status"]) for j in listed] == [
            (quick["id"], "done"),
            (long["id"], "failed"),
        ]


def test_a_running_row_whose_owner_stopped_heartbeating_is_lost(client_factory, tmp_path):
    """A row left ``running`` by a replica that died (its owner's heartbeat a minute old):
    answered ``failed`` / ``lost_on_restart``, and no longer counted as unfinished."""
    store = str(tmp_path / "store.db")
    with _app(client_factory, store, max_jobs=3, jobs_per_tenant=1) as c:
        first = c.post("/v1/jobs", json=_sleeper(0.01)).json()  # creates the table
        _until(lambda: _status(c, first["id"])["status"] == "done", "never done")
        dead, old = uuid.uuid4().hex, time.time() - 60
        with sqlite3.connect(store) as con:
            con.execute(
                "INSERT INTO jobs (id, tenant, kind, status, submitted_at, started_at, owner, "
                "heartbeat_at) VALUES (?, 'default', 'plan', 'running', ?, ?, 'gone', ?)",
                (dead, old, old, old),
            )
        got = _status(c, dead)
        assert got["status"] == "failed" and got["error"]["status_code"] == 503
        (item,) = got["error"]["detail"]
        assert item["type"] == "lost_on_restart" and "heartbeat" in item["msg"]
        # the tenant's one unfinished job would be the dead row's: the bound does not count it
        r = c.post("/v1/jobs", json=_sleeper(0.01))
        assert r.status_code == 202, r.text
        with sqlite3.connect(store) as con:
            (status,) = con.execute("SELECT status FROM jobs WHERE id = ?", (dead,)).fetchone()
        assert status == "failed"  # marked so in the table by that submit


def test_one_tenant_cannot_pass_its_share_of_the_jobs(client_factory, tmp_path):
    store = str(tmp_path / "store.db")
    with _app(client_factory, store, api_keys=KEYS, max_jobs=4, jobs_per_tenant=2) as c:
        mine = [c.post("/v1/jobs", json=_sleeper(30.0), headers=ALICE) for _ in range(2)]
        assert [r.status_code for r in mine] == [202, 202]
        try:
            r = c.post("/v1/jobs", json=_sleeper(0.01), headers=ALICE)
            assert r.status_code == 429, r.text
            (item,) = r.json()["detail"]
            assert item["type"] == "too_many_jobs" and "PLANNER_JOBS_PER_TENANT" in item["msg"]
            assert int(r.headers["retry-after"]) >= 1
            theirs = c.post("/v1/jobs", json=_sleeper(0.01), headers=BOB)
            assert theirs.status_code == 202, theirs.text  # the other tenant is not refused
        finally:
            for r in mine:
                c.delete(f"/v1/jobs/{r.json()['id']}", headers=ALICE)
        assert c.post("/v1/jobs", json=_sleeper(0.01), headers=ALICE).status_code == 202


@pytest.mark.parametrize("value", ["0", "9"])
def test_the_per_tenant_bound_is_checked_at_start(monkeypatch, value):
    from pydantic import ValidationError

    from planner_api.settings import Settings

    monkeypatch.setenv("PLANNER_MAX_JOBS", "8")
    monkeypatch.setenv("PLANNER_JOBS_PER_TENANT", value)
    with pytest.raises(ValidationError, match=r"jobs_per_tenant|PLANNER_JOBS_PER_TENANT"):
        Settings()


def test_the_cli_submits_polls_lists_and_cancels(client_factory, tmp_path, monkeypatch):
    """``planner job submit|status|list|cancel`` against an in-process service (the CLI's
    client given a transport to it), and the error naming the URL when nothing answers."""
    import httpx
    from typer.testing import CliRunner

    from planner.client import PlannerClient
    from planner_cli import service
    from planner_cli.app import app

    runner = CliRunner()
    request = tmp_path / "plan.json"
    request.write_text(json.dumps(_sleeper(0.01)["request"]))
    long_request = tmp_path / "long.json"
    long_request.write_text(json.dumps(_sleeper(30.0)["request"]))
    with _app(client_factory, str(tmp_path / "store.db")) as c:

        def forward(r: httpx.Request) -> httpx.Response:
            answer = c.request(
                r.method,
                r.url.path,
                content=r.content,
                headers={"content-type": "application/json"},
            )
            return httpx.Response(answer.status_code, content=answer.content)

        monkeypatch.setattr(
            service,
            "make_client",
            lambda url, key: PlannerClient(
                "http://localhost", transport=httpx.MockTransport(forward)
            ),
        )
        r = runner.invoke(app, ["job", "submit", "plan", str(request)])
        assert r.exit_code == 0, r.output
        job_id = r.stdout.strip()
        _until(lambda: _status(c, job_id)["status"] == "done", "never done")
        out = tmp_path / "result.json"
        r = runner.invoke(app, ["job", "status", job_id, "--out", str(out)])
        assert r.exit_code == 0 and f"{job_id}\tplan\tdone" in r.stdout, r.output
        assert json.loads(out.read_text()) == _status(c, job_id)["result"]
        long = runner.invoke(app, ["job", "submit", "plan", str(long_request)]).stdout.strip()
        r = runner.invoke(app, ["job", "list"])
        assert r.exit_code == 0 and [line.split("\t")[0] for line in r.stdout.splitlines()] == [
            job_id,
            long,
        ]
        r = runner.invoke(app, ["job", "cancel", long])
        assert r.exit_code == 0 and f"{long}\tplan\tcancelled" in r.stdout, r.output
        r = runner.invoke(app, ["job", "status", "0" * 32])
        assert r.exit_code == 1 and "no job" in r.output
        r = runner.invoke(app, ["job", "submit", "dance", str(request)])
        assert r.exit_code == 2 and "kind" in r.output
    monkeypatch.undo()
    monkeypatch.setenv("PLANNER_URL", "http://127.0.0.1:9")
    r = runner.invoke(app, ["job", "list"])
    assert r.exit_code == 2
    assert "no planning service answers at http://127.0.0.1:9" in r.output
    assert "--url or PLANNER_URL" in r.output
