"""Small job bodies cross to a worker as their JSON text (:mod:`planner_api.routes.direct`,
"Bodies validated in the worker"): the event loop parses none, and what a bad body gets is
what it got when the loop validated it. The oracle is FastAPI's own path on the same app
(any ``dependency_overrides`` send every request there): the same status and the same
answer to the byte, for a broken rule, bad JSON, a body nested too deep, a number too long,
a JSON null or list, the service's limits, an unknown scene and a merged design that breaks
a rule; and with the pool full, a bad body still gets its 422 and a good one the 503,
a body the loop's own check refuses never reaching the pool."""

from __future__ import annotations

import json
import time

import pytest
import starlette.requests

START = {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"}
GOAL = {"q": [0.3, 2.2, 1.1], "assembly_mode": "+"}
PLAN = {"start": START, "goal": GOAL, "planner": {"seed": 1}, "timing": {"method": "none"}}
SPHERE = {"type": "sphere", "center": [3.0, 3.0, 3.0], "radius": 0.1}
JSON = {"Content-Type": "application/json"}


def _text(body: object) -> bytes:
    return body if isinstance(body, bytes) else json.dumps(body).encode()


BAD = {
    "plan, rule": ("/v1/plan", {**PLAN, "start": {"q": "x"}}),
    "plan, null": ("/v1/plan", b"null"),
    "plan, a list": ("/v1/plan", b"[1, 2]"),
    "plan, bad JSON": ("/v1/plan", b'{"start": '),
    "plan, too deep": ("/v1/plan", b"[" * 5000 + b"]" * 5000),
    "plan, number too long": ("/v1/plan", b'{"start": {"q": [1' + b"0" * 5000 + b", 0, 0]}}"),
    "plan, obstacles over the limit": ("/v1/plan", {**PLAN, "obstacles": [SPHERE, SPHERE]}),
    "plan, budget over the request's": ("/v1/plan", {**PLAN, "planner": {"time_budget_s": 1e4}}),
    "plan, unknown scene": ("/v1/plan", {**PLAN, "scene": "nowhere"}),
    "plan, merged design": ("/v1/plan", {**PLAN, "design": {"joint_min": [2, 0, 0]}}),
    "cartesian, rule": ("/v1/cartesian", {"start": START, "waypoints": []}),
    "cartesian, null": ("/v1/cartesian", b"null"),
    "sequence, rule": ("/v1/sequence", {"start": START, "targets": [{"goal": 1}]}),
    "sequence, targets over the limit": (
        "/v1/sequence",
        {"start": START, "targets": [{"goal": GOAL}] * 3},
    ),
    "timing, rule": ("/v1/timing", {"waypoints": [[0, 0]]}),
}


@pytest.fixture(scope="module")
def client(client_factory):
    """One worker, small limits, a configured default design whose ``joint_max`` a
    request's ``joint_min`` can cross."""
    settings = {
        "max_obstacles": 1,
        "max_sequence_targets": 2,
        "default_design": '{"L1": 0.3, "L2": 0.4, "joint_max": [1, 1, 1]}',
    }
    with client_factory(warm=False, **settings) as c:
        yield c


def _fastapis_path() -> None:
    """An override nobody asks for: with any override set, every request takes FastAPI's
    path (the loop parses and validates the body as it always did)."""


@pytest.mark.parametrize(("path", "body"), list(BAD.values()), ids=list(BAD))
def test_a_bad_body_gets_the_422_fastapis_path_gives(client, path, body):
    crossed = client.post(path, content=_text(body), headers=JSON)
    client.app.dependency_overrides[_fastapis_path] = _fastapis_path
    try:
        parsed_here = client.post(path, content=_text(body), headers=JSON)
    finally:
        client.app.dependency_overrides.clear()
    assert parsed_here.status_code == 422, parsed_here.text
    assert crossed.status_code == 422 and crossed.json() == parsed_here.json()


def test_a_small_plan_is_never_parsed_on_the_loop(client, monkeypatch):
    parsed: list[int] = []

    class CountingJson:
        @staticmethod
        def loads(data: bytes, **options: object) -> object:
            parsed.append(len(data))
            return json.loads(data, **options)

    monkeypatch.setattr(starlette.requests, "json", CountingJson)
    r = client.post("/v1/plan", json=PLAN)
    # the worker completed the design from the configured one: its joint_max of 1 rad
    assert r.status_code == 200 and r.json()["status"] == "invalid_start", r.text
    assert "[-3.141592654, 1]" in r.json()["message"]
    assert parsed == []
    r = client.post("/v1/plan", json={**PLAN, "start": {"q": "x"}})  # FastAPI's 422 reads it
    assert r.status_code == 422 and len(parsed) == 1


def test_a_full_pool_answers_a_bad_body_422_and_a_good_one_503(client_factory):
    design = '{"L1": 0.3, "L2": 0.4, "joint_max": [1, 1, 1]}'
    settings = {"workers": 1, "queue_size": 0, "max_obstacles": 1, "default_design": design}
    with client_factory(warm=False, **settings) as c:
        pool = c.app.state.pool
        busy = pool.submit(time.sleep, 3.0, deadline=time.monotonic() + 30)
        try:
            rule = c.post("/v1/plan", json={**PLAN, "start": {"q": "x"}})
            limit = c.post("/v1/plan", json={**PLAN, "obstacles": [SPHERE, SPHERE]})
            scene = c.post("/v1/plan", json={**PLAN, "scene": "nowhere"})
            merged = c.post("/v1/plan", json={**PLAN, "design": {"joint_min": [2, 0, 0]}})
            good = c.post("/v1/plan", json=PLAN)
            refused = pool.rejected
        finally:
            pool.cancel(busy)
    assert rule.status_code == 422 and rule.json()["detail"][0]["loc"] == ["body", "start", "q"]
    assert limit.status_code == 422 and limit.json()["detail"][0]["loc"] == ["body", "obstacles"]
    assert scene.status_code == 422 and scene.json()["detail"][0]["loc"] == ["body", "scene"]
    assert merged.status_code == 422
    assert merged.json()["detail"][0]["loc"][:2] == ["body", "design"], merged.text
    assert good.status_code == 503 and good.json()["detail"][0]["type"] == "saturated"
    # a broken rule and a limit never reach the pool (the loop's own check); the scene, the
    # merged design and the good body crossed, were refused, and were checked on the loop
    assert refused == 3


#: The bad bodies the loop's own check refuses (the rules, JSON and limits; not the scene or
#: the merged design, which only the worker finds).
CHECKED_HERE = [k for k in BAD if "scene" not in k and "merged" not in k]


def test_a_bad_body_never_reaches_the_pool(client, monkeypatch):
    """The loop checks every small body before it crosses (direct._passes_here): a bad one
    takes no queue slot while the worker is busy and no worker round trip while it is idle."""
    pool = client.app.state.pool
    sent: list[object] = []
    run = pool.run
    monkeypatch.setattr(pool, "run", lambda fn, *a, **k: (sent.append(fn), run(fn, *a, **k))[1])
    busy = pool.submit(time.sleep, 5.0, deadline=time.monotonic() + 30)
    try:
        while pool.in_flight < 1:  # pragma: no cover - submit counts it at once
            time.sleep(0.01)
        for name in CHECKED_HERE:
            path, body = BAD[name]
            checked = client.post(path, content=_text(body), headers=JSON)
            client.app.dependency_overrides[_fastapis_path] = _fastapis_path
            try:
                parsed_here = client.post(path, content=_text(body), headers=JSON)
            finally:
                client.app.dependency_overrides.clear()
            assert checked.status_code == 422 and checked.json() == parsed_here.json(), name
            assert sent == [] and pool.in_flight == 1, name  # nothing was queued
    finally:
        pool.cancel(busy)
    end = time.monotonic() + 30
    while (pool.in_flight or pool.warm_workers < 1) and time.monotonic() < end:
        time.sleep(0.02)  # the busy worker stopped and replaced
    with_idle_worker = client.post("/v1/plan", json={**PLAN, "start": {"q": "x"}})
    assert with_idle_worker.status_code == 422 and sent == []  # checked here: never crossed
    good = client.post("/v1/plan", json=PLAN)
    assert good.status_code == 200 and len(sent) == 1  # a good body crosses
