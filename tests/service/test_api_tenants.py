"""Tenants over HTTP (``PLANNER_API_KEYS``): a tenant's scenes and long jobs are 404 for
another tenant (get, delete, cancel; a PUT of the same name makes the other tenant's own
scene; a plan naming it does not find it), listings show each tenant its own; the quotas
refuse naming their setting; the single ``PLANNER_API_KEY`` and no key at all are the tenant
``default``. The oracle of "404, not a leak": the other tenant's answer is the answer to a
name or id that never existed, byte for byte but for the name or id itself.
"""

from __future__ import annotations

import os
import time

import pytest

from planner.endpoints import UNBOUNDED, JobBudget
from planner.wire import PlanRequest, PlanResponse
from planner_api.routes.plan import get_plan_function

ALICE = {"X-API-Key": "alice-key"}
BOB = {"Authorization": "Bearer bob-key"}
START = {"q": [0.0, 1.0, 2.0], "assembly_mode": "+"}
SPHERE = {"type": "sphere", "center": [5, 5, 5], "radius": 0.1}


def _sleep(request: PlanRequest, budget: JobBudget = UNBOUNDED) -> PlanResponse:
    time.sleep(request.planner.time_budget_s)
    return PlanResponse(status="timeout", message=str(os.getpid()))


@pytest.fixture(scope="module")
def two(client_factory, tmp_path_factory):
    """A service of two tenants (keys inline), its plan job a sleep."""
    store = str(tmp_path_factory.mktemp("tenants") / "scenes.db")
    client = client_factory(
        api_keys="alice:alice-key, bob:bob-key", scene_store=store, workers=2, warm=False
    )
    client.app.dependency_overrides[get_plan_function] = lambda: _sleep
    with client as c:
        yield c


def _same_but(a, b, x: str, y: str) -> None:
    """Two answers alike but for ``x`` in one where ``y`` is in the other."""
    assert a.status_code == b.status_code == 404
    assert a.text.replace(x, "@") == b.text.replace(y, "@")


def test_a_tenants_scene_is_404_to_another_and_names_are_per_tenant(two):
    c = two
    mine = c.put("/v1/scenes/table-1", json={"obstacles": [SPHERE]}, headers=ALICE).json()
    assert mine["version"] == 1
    _same_but(
        c.get("/v1/scenes/table-1", headers=BOB),
        c.get("/v1/scenes/never", headers=BOB),
        "table-1",
        "never",
    )
    _same_but(
        c.delete("/v1/scenes/table-1", headers=BOB),
        c.delete("/v1/scenes/never", headers=BOB),
        "table-1",
        "never",
    )
    assert c.get("/v1/scenes", headers=BOB).json() == {"scenes": []}
    plan = {
        "start": START,
        "goal": {"q": [0.1, 1.0, 2.0], "assembly_mode": "+"},
        "scene": "table-1",
        "planner": {"time_budget_s": 0.01},
    }
    r = c.post("/v1/plan", json=plan, headers=BOB)
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "scene"]
    # bob's PUT of the same name is bob's own scene: version 1, alice's untouched
    theirs = c.put("/v1/scenes/table-1", json={"obstacles": []}, headers=BOB).json()
    assert theirs["version"] == 1 and theirs["hash"] != mine["hash"]
    got = c.get("/v1/scenes/table-1", headers=ALICE).json()
    assert (got["version"], got["hash"], got["scene"]["obstacles"]) == (1, mine["hash"], [SPHERE])
    assert c.post("/v1/plan", json=plan, headers=BOB).status_code == 200
    assert c.delete("/v1/scenes/table-1", headers=BOB).status_code == 200
    assert c.get("/v1/scenes/table-1", headers=ALICE).json()["hash"] == mine["hash"]
    assert [s["name"] for s in c.get("/v1/scenes", headers=ALICE).json()["scenes"]] == ["table-1"]
    assert c.get("/v1/scenes").status_code == 401  # no key: no tenant


def test_a_tenants_job_is_404_to_another_and_listings_are_per_tenant(two):
    c = two
    body = {
        "kind": "plan",
        "request": {
            "start": START,
            "goal": {"p": [0.3, 0.1, 0.2]},
            "planner": {"time_budget_s": 30},
        },
    }
    job = c.post("/v1/jobs", json=body, headers=ALICE).json()
    never = "0" * 32
    _same_but(
        c.get(f"/v1/jobs/{job['id']}", headers=BOB),
        c.get(f"/v1/jobs/{never}", headers=BOB),
        job["id"],
        never,
    )
    _same_but(
        c.delete(f"/v1/jobs/{job['id']}", headers=BOB),
        c.delete(f"/v1/jobs/{never}", headers=BOB),
        job["id"],
        never,
    )
    assert c.get(f"/v1/jobs/{job['id']}", headers=ALICE).json()["status"] in ("queued", "running")
    assert c.get("/v1/jobs", headers=BOB).json() == []
    (listed,) = c.get("/v1/jobs", headers=ALICE).json()
    assert (listed["id"], listed["kind"]) == (job["id"], "plan")
    assert listed["status"] in ("queued", "running") and "result" not in listed
    # the conventions' names: created (the submit time) and finished (null until it ends)
    assert listed["created"] == job["submitted_at"] and listed["finished"] is None
    cancelled = c.delete(f"/v1/jobs/{job['id']}", headers=ALICE).json()
    assert cancelled["status"] == "cancelled"
    (listed,) = c.get("/v1/jobs", headers=ALICE).json()
    assert listed["status"] == "cancelled" and listed["finished_at"] is not None
    assert listed["finished"] == listed["finished_at"] >= listed["created"]


def test_quotas_refuse_naming_their_setting(client_factory, tmp_path):
    keys = tmp_path / "keys"
    keys.write_text("# tenants of this test\nalice alice-key\nbob   bob-key  \n")
    with client_factory(
        api_keys=str(keys),
        scene_store=str(tmp_path / "s.db"),
        scenes_max=2,
        scene_bytes_max=4096,
        warm=False,
    ) as c:
        for name in ("a", "b"):
            assert c.put(f"/v1/scenes/{name}", json={"obstacles": []}, headers=ALICE).is_success
        r = c.put("/v1/scenes/c", json={"obstacles": []}, headers=ALICE)
        assert r.status_code == 422, r.text
        item = r.json()["detail"][0]
        assert (item["type"], item["loc"]) == ("quota_exceeded", ["path", "name"])
        assert "PLANNER_SCENES_MAX" in item["msg"]
        assert c.put("/v1/scenes/a", json={"obstacles": [SPHERE]}, headers=ALICE).is_success
        assert c.put("/v1/scenes/c", json={"obstacles": []}, headers=BOB).is_success
        big = {"obstacles": [{"type": "points", "points": [[1.0, 2.0, 3.0]] * 400, "radius": 0.01}]}
        r = c.put("/v1/scenes/big", json=big, headers=BOB)
        assert r.status_code == 413, r.text
        item = r.json()["detail"][0]
        assert (item["type"], item["loc"]) == ("quota_exceeded", ["body"])
        assert "PLANNER_SCENE_BYTES_MAX" in item["msg"] and "4096" in item["msg"]
        assert c.get("/v1/scenes/big", headers=BOB).status_code == 404


@pytest.mark.parametrize("key", [None, "only-key"])
def test_one_key_or_none_is_the_default_tenant(client_factory, tmp_path, key):
    """The scenes of a store written before tenants are the tenant ``default``'s: the
    service with its one key, or with none, keeps serving them."""
    from planner_api.scene_store import SqliteSceneStore

    path = str(tmp_path / "s.db")
    SqliteSceneStore(path).put("default", "old", '{"obstacles": []}', "h", 0, 0)
    headers = {"X-API-Key": key} if key else {}
    settings = {"api_key": key} if key else {}
    with client_factory(scene_store=path, warm=False, **settings) as c:
        assert c.get("/v1/scenes/old", headers=headers).json()["hash"] == "h"
        if key:
            assert c.get("/v1/scenes/old").status_code == 401
