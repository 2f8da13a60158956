"""Named scenes over HTTP: PUT/GET/DELETE /v1/scenes/{name}, GET /v1/scenes, plans that
name a scene (the same answer as the same obstacles inline), bad names and unknown scenes,
last writer wins under concurrent PUTs, a scene changed during a plan does not change it,
and persistence across a real server restart."""

from __future__ import annotations

import json
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import httpx
import numpy as np
import pytest

START = {"q": [0.3, 2.0, 1.0], "assembly_mode": "+"}
GOAL = {"q": [-0.6, 1.4, 0.7], "assembly_mode": "+"}


def _cloud(n: int = 3000, seed: int = 0) -> dict:
    """A disc of points across the straight motion START -> GOAL (as tests/
    test_point_clouds.py builds it), on the wire."""
    from planner.design import Design
    from planner.kinematics import forward_batch

    rng = np.random.default_rng(seed)
    q = (np.array(START["q"]) + np.array(GOAL["q"])) / 2
    c = forward_batch(Design.default(), q[None], "+").p[0]
    r, phi = 0.09 * np.sqrt(rng.random(n)), rng.uniform(0, 2 * np.pi, n)
    u, v = np.array([1.0, 0, 0]), np.array([0, 0.29, -0.96]) / np.hypot(0.29, 0.96)
    pts = c + (r * np.cos(phi))[:, None] * u + (r * np.sin(phi))[:, None] * v
    return {"type": "points", "points": pts.tolist(), "radius": 0.004}


@pytest.fixture
def scenes_api(client_factory, tmp_path):
    """A service of its own (workers not warmed) with its scene store in ``tmp_path``."""
    with client_factory(scene_store=str(tmp_path / "scenes.db"), warm=False) as c:
        yield c


def test_put_get_list_delete(scenes_api):
    c = scenes_api
    sphere = {"type": "sphere", "center": [0.5, 0, 0], "radius": 0.1}
    r = c.put("/v1/scenes/cell-1", json={"obstacles": [sphere, _cloud(50)]})
    assert r.status_code == 200, r.text
    first = r.json()
    assert first["version"] == 1 and first["obstacles"] == 2 and first["points"] == 50
    got = c.get("/v1/scenes/cell-1").json()
    assert got["hash"] == first["hash"] and got["version"] == 1
    assert got["scene"]["obstacles"][0] == sphere
    assert len(got["scene"]["obstacles"][1]["points"]) == 50
    # the same content again: a new version, the same hash; other content: another hash
    again = c.put("/v1/scenes/cell-1", json={"obstacles": [sphere, _cloud(50)]}).json()
    assert again["version"] == 2 and again["hash"] == first["hash"]
    other = c.put("/v1/scenes/cell-1", json={"obstacles": [sphere]}).json()
    assert other["version"] == 3 and other["hash"] != first["hash"]
    c.put("/v1/scenes/a.b_c", json={"obstacles": []})
    listed = c.get("/v1/scenes").json()["scenes"]
    assert [s["name"] for s in listed] == ["a.b_c", "cell-1"]
    assert listed[1]["version"] == 3 and listed[1]["obstacles"] == 1
    assert c.delete("/v1/scenes/cell-1").json()["version"] == 3
    assert c.get("/v1/scenes/cell-1").status_code == 404
    assert c.delete("/v1/scenes/cell-1").status_code == 404
    assert [s["name"] for s in c.get("/v1/scenes").json()["scenes"]] == ["a.b_c"]


@pytest.mark.parametrize("name", ["-lead", "a" * 65, "sp ace", "semi;colon", "%2e%2e"])
def test_unsafe_names_are_422_at_the_name(scenes_api, name):
    r = scenes_api.put(f"/v1/scenes/{name}", json={"obstacles": []})
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["loc"] == ["path", "name"]


def test_bad_scene_bodies_name_the_field(scenes_api):
    r = scenes_api.put(
        "/v1/scenes/x", json={"obstacles": [{"type": "points", "points": [], "radius": 0.01}]}
    )
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "obstacles", 0, "points", "points"]
    r = scenes_api.put("/v1/scenes/x", json={"obstacles": [], "extra": 1})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "extra"]
    assert scenes_api.get("/v1/scenes/x").status_code == 404  # nothing stored


def test_a_plan_in_a_named_scene_equals_the_inline_plan(api):
    """The session's warm service: a plan naming the scene answers exactly as the same
    obstacles sent inline (same seed), and the cloud is in the way of the straight motion."""
    cloud = _cloud()
    name = f"plan-{time.monotonic_ns()}"
    assert api.put(f"/v1/scenes/{name}", json={"obstacles": [cloud]}).status_code == 200
    body = {"start": START, "goal": GOAL, "timing": {"method": "none"}, "planner": {"seed": 2}}
    named = api.post("/v1/plan", json={**body, "scene": name}).json()
    inline = api.post("/v1/plan", json={**body, "obstacles": [cloud]}).json()
    free = api.post("/v1/plan", json=body).json()
    assert named["status"] == inline["status"] == "solved"
    assert named["path"]["waypoints"] == inline["path"]["waypoints"]
    assert named["diagnostics"]["min_clearance"] == inline["diagnostics"]["min_clearance"]
    assert len(free["path"]["waypoints"]) == 2  # without the cloud: the straight motion
    assert len(named["path"]["waypoints"]) > 2
    # the scene's obstacles and the request's own together
    wall = {"type": "sphere", "center": [5, 5, 5], "radius": 0.1}
    both = api.post("/v1/plan", json={**body, "scene": name, "obstacles": [wall]}).json()
    assert both["path"]["waypoints"] == named["path"]["waypoints"]


def test_a_sequence_in_a_named_scene_equals_the_inline_sequence(api):
    """A sequence naming the scene answers as the same obstacles sent inline (same seed),
    and the cloud bends its first leg."""
    cloud = _cloud()
    name = f"sequence-{time.monotonic_ns()}"
    assert api.put(f"/v1/scenes/{name}", json={"obstacles": [cloud]}).status_code == 200
    body = {
        "start": START,
        "targets": [{"goal": GOAL}, {"goal": START}],
        "objective": "fixed",
        "timing": {"method": "none"},
        "planner": {"seed": 2},
    }
    named = api.post("/v1/sequence", json={**body, "scene": name}).json()
    inline = api.post("/v1/sequence", json={**body, "obstacles": [cloud]}).json()
    assert named["status"] == inline["status"] == "solved", named["message"]
    legs = [leg["path"]["waypoints"] for leg in named["legs"]]
    assert legs == [leg["path"]["waypoints"] for leg in inline["legs"]]
    assert len(legs[0]) > 2
    unknown = api.post("/v1/sequence", json={**body, "scene": "no-such-scene"})
    assert unknown.status_code == 422 and unknown.json()["detail"][0]["loc"][-1] == "scene"


def test_unknown_and_unsafe_scene_names_in_a_plan_are_422(scenes_api):
    body = {"start": START, "goal": GOAL, "timing": {"method": "none"}}
    r = scenes_api.post("/v1/plan", json={**body, "scene": "nowhere"})
    assert r.status_code == 422
    item = r.json()["detail"][0]
    assert item["loc"] == ["body", "scene"] and "nowhere" in item["msg"]
    r = scenes_api.post("/v1/plan", json={**body, "scene": "../etc"})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "scene"]
    r = scenes_api.post(
        "/v1/cartesian", json={"start": START, "waypoints": [[0.3, 0.1, -0.5]], "scene": "no"}
    )
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "scene"]
    r = scenes_api.post("/v1/plan/batch", json={"requests": [{**body, "scene": "nope"}]})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"][-1] == "scene"


def test_points_over_the_limit_with_a_named_scene_name_the_requests_own_cloud(scenes_api):
    """A scene's clouds and the request's own count together (at most MAX_POINTS); the cloud
    that passes the limit is named where the client sent it, ``obstacles.<i>.points``, as
    without a scene (not the index of the merged list, ``["body", "2"]``)."""
    from planner.constants import MAX_POINTS

    held = MAX_POINTS - 1_000
    scene_cloud = {"type": "points", "points": [[1.5, 1.5, 1.5]] * held, "radius": 0.001}
    assert scenes_api.put("/v1/scenes/dense", json={"obstacles": [scene_cloud]}).status_code == 200
    sphere = {"type": "sphere", "center": [1.5, -1.5, 1.5], "radius": 0.01}
    own = {"type": "points", "points": [[1.5, 1.5, -1.5]] * 2_000, "radius": 0.001}
    body = {"start": START, "goal": GOAL, "timing": {"method": "none"}}
    r = scenes_api.post("/v1/plan", json={**body, "scene": "dense", "obstacles": [sphere, own]})
    assert r.status_code == 422, r.text
    (item,) = r.json()["detail"]
    assert item["loc"] == ["body", "obstacles", 1, "points"], item
    assert str(MAX_POINTS) in item["msg"] and f"its scene's {held}" in item["msg"]
    # the same request's own clouds within the limit: planned
    r = scenes_api.post("/v1/plan", json={**body, "scene": "dense", "obstacles": [sphere]})
    assert r.status_code == 200, r.text


def test_concurrent_puts_leave_one_whole_scene(scenes_api):
    """16 PUTs of one name from 8 threads, each with its own content: the stored scene is
    one of them whole (its body's hash is its own), and every PUT made a version."""
    bodies = [
        {"obstacles": [{"type": "sphere", "center": [i, 0, 0], "radius": 0.1}] * (i + 1)}
        for i in range(16)
    ]
    with ThreadPoolExecutor(8) as ex:
        answers = list(ex.map(lambda b: scenes_api.put("/v1/scenes/race", json=b), bodies))
    assert all(a.status_code == 200 for a in answers)
    assert sorted(a.json()["version"] for a in answers) == list(range(1, 17))
    got = scenes_api.get("/v1/scenes/race").json()
    assert got["version"] == 16
    from planner.wire import SceneRequest, scene_hash

    stored = SceneRequest.model_validate(got["scene"]).model_dump_json(exclude_none=True)
    assert scene_hash(stored.encode()) == got["hash"]
    n = len(got["scene"]["obstacles"])
    assert got["scene"]["obstacles"] == bodies[n - 1]["obstacles"]
    last = max(answers, key=lambda a: a.json()["version"]).json()
    assert last["hash"] == got["hash"]


def test_a_scene_changed_during_a_plan_does_not_change_it(client_factory, tmp_path):
    """A plan whose job sleeps 1.5 s; the scene is replaced 0.3 s after it starts: the job
    still sees the scene it was started with (3 obstacles), the next plan the new one (1)."""
    import ops_jobs

    from planner_api.routes.plan import get_plan_function

    with client_factory(scene_store=str(tmp_path / "s.db"), warm=False, workers=2) as c:
        c.app.dependency_overrides[get_plan_function] = lambda: ops_jobs.scene_obstacle_count
        three = [{"type": "sphere", "center": [5, 5, k], "radius": 0.1} for k in range(3)]
        c.put("/v1/scenes/live", json={"obstacles": three})
        body = {"start": START, "goal": GOAL, "scene": "live", "planner": {"time_budget_s": 1.5}}
        out = {}
        plan = threading.Thread(target=lambda: out.update(r=c.post("/v1/plan", json=body)))
        plan.start()
        time.sleep(0.3)
        c.put("/v1/scenes/live", json={"obstacles": three[:1]})
        plan.join()
        assert out["r"].json()["message"] == "3"
        body["planner"]["time_budget_s"] = 0.01
        assert c.post("/v1/plan", json=body).json()["message"] == "1"


def test_scenes_persist_across_a_server_restart(server_factory, tmp_path):
    """A real server process (workers not warmed): PUT, stop it, start another on the same
    store, GET the scene back whole; then the same through the typed client."""
    from planner.client import PlannerClient

    store = str(tmp_path / "persist.db")
    cloud = _cloud(200)
    process, url, _ = server_factory(warm=False, scene_store=store, workers="1")
    put = httpx.put(f"{url}/v1/scenes/kept", json={"obstacles": [cloud]}, timeout=30).json()
    process.terminate()
    process.wait(timeout=30)
    _, url2, _ = server_factory(warm=False, scene_store=store, workers="1")
    got = httpx.get(f"{url2}/v1/scenes/kept", timeout=30).json()
    assert got.get("hash") == put.get("hash") and got["version"] == 1, (put, got)
    assert got["scene"]["obstacles"][0]["points"] == json.loads(json.dumps(cloud["points"]))
    with PlannerClient(url2) as client:
        info = client.put_scene(
            "by-client", [{"type": "points", "points": np.zeros((3, 3)) + 7, "radius": 0.01}]
        )
        assert info.version == 1 and info.points == 3
        assert client.scene("by-client").scene.obstacles[0].points[2] == [7.0, 7.0, 7.0]
        assert {s.name for s in client.scenes().scenes} == {"kept", "by-client"}
        assert client.delete_scene("kept").hash == put["hash"]
        assert [s.name for s in client.scenes().scenes] == ["by-client"]
    # and through the CLI (planner scene put|get|list|delete)
    from typer.testing import CliRunner

    from planner_cli.app import app

    runner = CliRunner()
    scene_file = tmp_path / "scene.json"
    scene_file.write_text(json.dumps({"obstacles": [cloud]}))
    r = runner.invoke(app, ["scene", "put", "cli", str(scene_file), "--url", url2])
    assert r.exit_code == 0 and "version 1" in r.output and "200 points" in r.output, r.output
    r = runner.invoke(app, ["scene", "list", "--url", url2])
    assert r.exit_code == 0 and r.output.splitlines()[1].startswith("cli\tv1"), r.output
    r = runner.invoke(app, ["scene", "get", "cli", "--url", url2])
    assert r.exit_code == 0 and json.loads(r.output)["obstacles"][0]["points"] == cloud["points"]
    assert runner.invoke(app, ["scene", "delete", "cli", "--url", url2]).exit_code == 0
    r = runner.invoke(app, ["scene", "get", "cli", "--url", url2])
    assert r.exit_code == 1 and "no scene named 'cli'" in r.output
    r = runner.invoke(app, ["scene", "get", "bad name", "--url", url2])
    assert r.exit_code == 2 and "path.name" in r.output
