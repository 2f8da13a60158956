"""Large bodies are parsed in a worker (``api/routes/worker_body.py``), and a worker parses
exactly as the event loop does. The oracle is FastAPI's own path: one service parses every body
on the event loop (``inline_parse_bytes`` above any body), the other hands every body to a
worker (``inline_parse_bytes=0``); the same request must get the same status and the same
answer (for a 422 the same ``loc`` and ``type``), for valid requests of the four routes, a
batch, a scene's PUT and a long job, bad
JSON, a broken rule, a body nested too deep, a number too long, the service's limits, a design
that breaks a rule and a named scene. Then, with ``json.loads`` of the serving process
counting what it parses, a large plan is answered with nothing parsed there."""

from __future__ import annotations

import json
import time

import pytest
import starlette.requests

START = {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"}
#: A cloud far from the robot (it collides with nothing), 5,000 points: a body of ~90 kB,
#: larger than the default PLANNER_INLINE_PARSE_BYTES.
CLOUD = {
    "type": "points",
    "radius": 0.01,
    "points": [[3.0 + 0.001 * i, 3.0, 3.0] for i in range(5000)],
}
PLAN = {
    "start": START,
    "goal": {"q": [0.3, 2.2, 1.1], "assembly_mode": "+"},
    "obstacles": [CLOUD],
    "planner": {"seed": 1},
    "timing": {"method": "ruckig"},
}
SETTINGS = {"max_obstacles": 3, "max_sequence_targets": 2, "max_batch": 3, "warm": False}
_DIAGNOSTIC_TIMES = ("planning_time_s", "timing_time_s", "computation_time_s")


@pytest.fixture(scope="module")
def pair(client_factory, tmp_path_factory):
    """(the event loop parses, a worker parses), same settings otherwise, each its own scene
    store (so that a scene stored through both is version 1 in each)."""
    stores = [str(tmp_path_factory.mktemp("worker-body") / f"{k}.sqlite3") for k in "ab"]
    with client_factory(inline_parse_bytes=1 << 30, scene_store=stores[0], **SETTINGS) as inline:
        with client_factory(inline_parse_bytes=0, scene_store=stores[1], **SETTINGS) as in_worker:
            yield inline, in_worker


def _same(pair, path: str, body: bytes | dict, method: str = "POST") -> dict:
    """Send ``body`` to both; assert the same status and answer; the answer."""
    content = body if isinstance(body, bytes) else json.dumps(body).encode()
    answers = [
        c.request(method, path, content=content, headers={"Content-Type": "application/json"})
        for c in pair
    ]
    codes = [a.status_code for a in answers]
    assert codes[0] == codes[1], [a.text[:500] for a in answers]
    bodies = [a.json() for a in answers]
    if codes[0] == 422:
        where = [[(d["loc"], d["type"]) for d in b["detail"]] for b in bodies]
        assert where[0] == where[1], where
    else:
        for b in bodies:
            for key in (*_DIAGNOSTIC_TIMES, "updated_at"):
                b.get("diagnostics", {}).pop(key, None)
                b.pop(key, None)
        assert bodies[0] == bodies[1]
    return {**bodies[0], "http": codes[0]}


def test_valid_requests_of_the_four_routes_answer_the_same(pair):
    plan = _same(pair, "/v1/plan", PLAN)
    assert plan["http"] == 200 and plan["path"]["waypoints"]
    waypoints = plan["path"]["waypoints"]
    timing = _same(pair, "/v1/timing", {"waypoints": waypoints, "obstacles": [CLOUD]})
    assert timing["http"] == 200
    cartesian = {"start": START, "waypoints": [[0.5, 0.05, 0.25]], "obstacles": [CLOUD]}
    assert _same(pair, "/v1/cartesian", cartesian)["http"] == 200
    sequence = {"start": START, "targets": [{"goal": {"q": [0.3, 2.2, 1.1], "assembly_mode": "+"}}]}
    assert _same(pair, "/v1/sequence", {**sequence, "obstacles": [CLOUD]})["http"] == 200


@pytest.mark.parametrize(
    "body",
    [
        b'{"start": {"q": [0, 2, 1]}, "goal": ',  # cut short
        b"[" * 100_000 + b"]" * 100_000,  # nested too deep
        b'{"start": {"q": [' + b"9" * 5000 + b', 2, 1]}, "goal": {"q": [0, 2, 1]}}',
        json.dumps({**PLAN, "obstacles": [{**CLOUD, "points": [[0.0, 0.0, "x"]]}]}).encode(),
        json.dumps({**PLAN, "planner": {"seed": -1, "planner": "nope"}}).encode(),
        json.dumps({**PLAN, "obstacles": [CLOUD] * 4}).encode(),  # over max_obstacles
        json.dumps({**PLAN, "planner": {"time_budget_s": 1e4}}).encode(),  # over the budget
        json.dumps({**PLAN, "design": {"joint_min": [5, 5, 5]}}).encode(),
    ],
    ids=["cut", "deep", "long-number", "rule", "planner", "obstacles", "budget", "design"],
)
def test_bad_plans_are_the_same_422(pair, body):
    assert _same(pair, "/v1/plan", body)["http"] == 422


def test_a_sequence_over_its_limit_is_the_same_422(pair):
    targets = [{"goal": {"q": [0.3, 2.2, 1.1], "assembly_mode": "+"}}] * 3
    answer = _same(pair, "/v1/sequence", {"start": START, "targets": targets})
    assert answer["http"] == 422 and answer["detail"][0]["loc"] == ["body", "targets"]


def test_a_named_scene_is_resolved_by_the_server(pair):
    for c in pair:
        r = c.put("/v1/scenes/far-cloud", json={"obstacles": [CLOUD]})
        assert r.status_code == 200, r.text
    answer = _same(pair, "/v1/plan", {**PLAN, "obstacles": [], "scene": "far-cloud"})
    assert answer["http"] == 200, answer
    missing = _same(pair, "/v1/plan", {**PLAN, "scene": "no-such-scene"})
    assert missing["http"] == 422


@pytest.mark.parametrize(
    ("name", "body"),
    [
        ("big-cloud", {"obstacles": [CLOUD]}),
        ("bad-cloud", {"obstacles": [{**CLOUD, "radius": -1.0}]}),
        ("too-many", {"obstacles": [CLOUD] * 4}),
        ("no spaces allowed", {"obstacles": [CLOUD]}),
    ],
    ids=["stored", "rule", "obstacles", "name"],
)
def test_a_scene_put_is_the_same_in_a_worker(pair, name, body):
    answer = _same(pair, f"/v1/scenes/{name}", body, method="PUT")
    if answer["http"] == 200:
        stored = [c.get(f"/v1/scenes/{name}").json() for c in pair]
        assert stored[0]["scene"] == stored[1]["scene"] and stored[0]["hash"] == stored[1]["hash"]
    else:
        assert answer["http"] == 422


@pytest.mark.parametrize(
    "requests",
    [
        [PLAN, {**PLAN, "goal": {"q": [0.2, 2.1, 1.0], "assembly_mode": "+"}}],
        [PLAN, {**PLAN, "obstacles": [], "scene": "far-cloud"}],
        [PLAN, {**PLAN, "obstacles": [CLOUD] * 4}],
        [PLAN, {**PLAN, "goal": {"q": [0.2, "x", 1.0], "assembly_mode": "+"}}],
        [PLAN] * 4,
    ],
    ids=["plans", "scene", "obstacles", "rule", "count"],
)
def test_a_batch_is_the_same_in_a_worker(pair, requests):
    for c in pair:
        assert c.put("/v1/scenes/far-cloud", json={"obstacles": [CLOUD]}).status_code == 200
    answers = [c.post("/v1/plan/batch", json={"requests": requests}) for c in pair]
    assert answers[0].status_code == answers[1].status_code, [a.text[:300] for a in answers]
    if answers[0].status_code == 422:
        a, b = ([(d["loc"], d["type"]) for d in r.json()["detail"]] for r in answers)
        assert a == b
        return
    results = [r.json()["results"] for r in answers]
    for batch in results:
        for item in batch:
            for key in _DIAGNOSTIC_TIMES:
                item["diagnostics"].pop(key, None)
    assert results[0] == results[1] and all(r["status"] == "solved" for r in results[0])


def _job(c, body: dict) -> tuple[int, dict]:
    """Submit a long job and wait for its end: (the submit's status, the job at its end)."""
    r = c.post("/v1/jobs", json=body)
    if r.status_code != 202:
        return r.status_code, r.json()
    end = time.monotonic() + 120
    while (job := c.get(f"/v1/jobs/{r.json()['id']}").json())["status"] in ("queued", "running"):
        assert time.monotonic() < end, job
        time.sleep(0.02)
    return 202, job


@pytest.mark.parametrize(
    "body",
    [
        {"kind": "plan", "request": PLAN},
        {"kind": "plan", "request": {**PLAN, "obstacles": [], "scene": "far-cloud"}},
        {"kind": "plan", "request": {**PLAN, "obstacles": [CLOUD] * 4}},
        {"kind": "plan", "request": {**PLAN, "obstacles": [{**CLOUD, "radius": "x"}]}},
        {"kind": "dance", "request": PLAN},
    ],
    ids=["plan", "scene", "obstacles", "rule", "kind"],
)
def test_a_long_job_is_the_same_in_a_worker(pair, body):
    for c in pair:
        assert c.put("/v1/scenes/far-cloud", json={"obstacles": [CLOUD]}).status_code == 200
    (code_a, a), (code_b, b) = (_job(c, body) for c in pair)
    assert code_a == code_b, (a, b)
    if code_a == 422:
        assert [(d["loc"], d["type"]) for d in a["detail"]] == [
            (d["loc"], d["type"]) for d in b["detail"]
        ]
        return
    assert a["status"] == b["status"] == "done", (a["error"], b["error"])
    for job in (a, b):
        for key in _DIAGNOSTIC_TIMES:
            job["result"]["diagnostics"].pop(key, None)
    assert a["result"] == b["result"]


def test_the_event_loop_never_parses_a_large_body(pair, monkeypatch):
    """The serving process's ``json.loads`` (the one FastAPI reads a body with) counts the
    bodies it parses: none for the service that hands them to a worker; for the other, none
    for a plan (the loop only checks it, in pydantic's JSON mode, and the worker validates
    it: :mod:`planner_api.routes.direct`) and one for a batch."""
    inline, in_worker = pair
    parsed: list[int] = []

    class CountingJson:
        @staticmethod
        def loads(data: bytes, **options: object) -> object:
            parsed.append(len(data))
            return json.loads(data, **options)

    monkeypatch.setattr(starlette.requests, "json", CountingJson)
    r = in_worker.post("/v1/plan", json=PLAN)
    assert r.status_code == 200 and r.json()["status"] == "solved", r.text
    assert parsed == []
    r = in_worker.put("/v1/scenes/parsed-elsewhere", json={"obstacles": [CLOUD]})
    assert r.status_code == 200 and parsed == [], r.text
    code, job = _job(in_worker, {"kind": "plan", "request": PLAN})
    assert code == 202 and job["status"] == "done" and parsed == [], job
    r = in_worker.post("/v1/plan/batch", json={"requests": [PLAN, PLAN]})
    assert r.status_code == 200 and parsed == [], r.text
    r = inline.post("/v1/plan", json=PLAN)  # checked in JSON mode, validated in the worker
    assert r.status_code == 200 and parsed == [], r.text
    r = inline.post("/v1/plan/batch", json={"requests": [PLAN]})  # the loop parses a batch
    assert r.status_code == 200 and len(parsed) == 1 and parsed[0] > 65536, r.text
