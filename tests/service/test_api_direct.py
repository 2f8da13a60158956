"""The routes answered without FastAPI's per-request dependency solving, and the route table
(:mod:`planner_api.routes.direct`): the same answers as FastAPI's path, FastAPI's path taken
for what is not the plain case, and the route the table remembers the one the scan chose."""

from __future__ import annotations

import json

import fastapi.routing
import pytest
from ops_jobs import timed_outcome

from planner.endpoints import as_json
from planner.endpoints import kinematics as jobs
from planner.wire import FKRequest
from planner_api.routes.plan import get_plan_function


@pytest.fixture
def solved(monkeypatch):
    """How many times FastAPI solved a route's dependencies (its per-request path)."""
    count = {"n": 0}
    original = fastapi.routing.solve_dependencies

    async def counting(*args, **kwargs):
        count["n"] += 1
        return await original(*args, **kwargs)

    monkeypatch.setattr(fastapi.routing, "solve_dependencies", counting)
    return count


def test_fk_is_answered_directly_with_the_jobs_own_answer(client_factory, solved):
    body = {"q": [0.2, 1.0, 2.0], "assembly_mode": "+"}
    with client_factory(warm=False) as c:
        solved["n"] = 0  # the readiness probes are FastAPI's
        answers = [c.post("/v1/fk", json=body) for _ in range(3)]  # the scan, then the table
    assert [r.status_code for r in answers] == [200, 200, 200]
    assert solved["n"] == 0
    expected = json.loads(as_json(jobs.fk, FKRequest.model_validate(body)))
    assert all(r.json() == expected for r in answers)


def test_a_body_that_breaks_a_rule_gets_fastapis_own_422(client_factory, solved):
    with client_factory(warm=False) as c:
        solved["n"] = 0
        r = c.post("/v1/fk", json={"q": "not a list"})
        empty = c.post("/v1/ik", content=b"", headers={"content-type": "application/json"})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "q"]
    assert empty.status_code == 422 and empty.json()["detail"][0]["loc"] == ["body"]
    assert solved["n"] == 2  # both took FastAPI's path


def test_an_overridden_job_is_honoured_on_every_request(client_factory):
    """The table hands a known path to the router's entry (the included router), whose
    route runs FastAPI's path while ``dependency_overrides`` are set."""

    plan = {
        "start": {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"},
        "goal": {"q": [0.3, 2.1, 0.9], "assembly_mode": "+"},
        "planner": {"seed": 1},  # timed_outcome's no_path; the real planner solves it
    }
    with client_factory(warm=False) as c:
        c.app.dependency_overrides[get_plan_function] = lambda: timed_outcome
        statuses = [c.post("/v1/plan", json=plan).json()["status"] for _ in range(3)]
    assert statuses == ["no_path"] * 3


@pytest.mark.parametrize(
    ("method", "path", "status"),
    [
        ("GET", "/v1/health", 200),
        ("GET", "/v1/fk", 405),  # a partial match: never remembered
        ("POST", "/v1/nowhere", 404),
        ("GET", "/v1/designs", 200),
    ],
)
def test_the_table_answers_as_the_scan(client_factory, method, path, status):
    with client_factory(warm=False) as c:
        codes = [c.request(method, path).status_code for _ in range(3)]
    assert codes == [status] * 3
