"""The front door's direct answer (:func:`planner_api.routes.direct.index_routes`): once the
route table knows a hot path, the gate answers its plain requests itself, without FastAPI's
exception middleware, exit stack, router and route wrapper. The oracle is the same app with
the direct answers off (every request through those layers, as before): the same status,
the same headers but the request id, the same body to the byte, for good requests, a body
that breaks a rule, a limit, a merged design that breaks a rule, a posture that does not
close, a missing key; the request counted in the metrics under its route."""

from __future__ import annotations

import json

import pytest

import planner_api.routes.direct as direct

START = {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"}
GOAL = {"q": [0.3, 2.2, 1.1], "assembly_mode": "+"}
PLAN = {"start": START, "goal": GOAL, "planner": {"seed": 1}, "timing": {"method": "none"}}
SPHERE = {"type": "sphere", "center": [3.0, 3.0, 3.0], "radius": 0.1}
KEY = {"X-API-Key": "k" * 16}

CASES = {
    "fk": ("/v1/fk", {"q": [0.2, 1.0, 2.0], "assembly_mode": "+"}),
    "fk, both modes": ("/v1/fk", {"q": [0.2, 1.0, 2.0]}),
    "fk, a rule": ("/v1/fk", {"q": "x"}),
    "fk, merged design": ("/v1/fk", {"q": [0.2, 1.0, 2.0], "design": {"joint_min": [2, 0, 0]}}),
    "ik": ("/v1/ik", {"p": [0.3, 0.1, 0.2]}),
    "analyze": ("/v1/analyze", {"q": [0.2, 1.0, 2.0], "assembly_mode": "+"}),
    "analyze, does not close": ("/v1/analyze", {"q": [0.0, 3.1, 0.0], "assembly_mode": "+"}),
    "plan": ("/v1/plan", PLAN),
    "plan, a rule": ("/v1/plan", {**PLAN, "start": {"q": "x"}}),
    "plan, over the limit": ("/v1/plan", {**PLAN, "obstacles": [SPHERE, SPHERE]}),
    "plan, merged design": ("/v1/plan", {**PLAN, "design": {"joint_min": [2, 0, 0]}}),
    "timing": ("/v1/timing", {"waypoints": [[0, 2, 1], [0.1, 2.1, 1.0]]}),
}


@pytest.fixture(scope="module")
def client(client_factory):
    """One worker, a key, a limit a request can break and a configured default design
    whose ``joint_max`` a request's ``joint_min`` can cross."""
    settings = {
        "api_key": KEY["X-API-Key"],
        "max_obstacles": 1,
        "default_design": '{"L1": 0.3, "L2": 0.4, "joint_max": [1, 1, 1]}',
    }
    with client_factory(warm=False, **settings) as c:
        for path in {path for path, _ in CASES.values()}:  # the table learns every path
            for _ in range(2):
                c.post(path, json=CASES["fk"][1], headers=KEY)
        yield c


def _timed(value: object) -> bool:
    """Whether an answer holds a measured duration (a plan's ``planning_time_s``)."""
    if isinstance(value, dict):
        return any(k.endswith("_time_s") and v is not None for k, v in value.items()) or any(
            _timed(v) for v in value.values()
        )
    return isinstance(value, list) and any(_timed(v) for v in value)


def _untimed(value: object) -> object:
    if isinstance(value, dict):
        return {k: None if k.endswith("_time_s") else _untimed(v) for k, v in value.items()}
    return [_untimed(v) for v in value] if isinstance(value, list) else value


def _seen(response) -> tuple[int, list[tuple[str, str]], object]:
    """Status, headers but the request id, and the body to the byte; an answer holding a
    measured duration (which differs between two runs of the same job) is compared with its
    durations masked, and without its length."""
    headers = [(k, v) for k, v in response.headers.items() if k != "x-request-id"]
    if not _timed(response.json()):
        return response.status_code, headers, response.content
    headers = [(k, v) for k, v in headers if k != "content-length"]
    return response.status_code, headers, _untimed(response.json())


@pytest.mark.parametrize(("path", "body"), list(CASES.values()), ids=list(CASES))
def test_the_direct_answer_is_the_layers_answer(client, monkeypatch, path, body):
    answered = []
    original = direct._direct_answer

    async def counted(*args):
        done = await original(*args)
        answered.append(done)
        return done

    monkeypatch.setattr(direct, "_direct_answer", counted)
    text = json.dumps(body).encode()
    headers = {**KEY, "Content-Type": "application/json"}
    at_the_door = client.post(path, content=text, headers=headers)
    assert answered, "the front door did not try its direct answer"
    kept, client.app.state.direct_answers = client.app.state.direct_answers, {}
    try:
        through_the_layers = client.post(path, content=text, headers=headers)
    finally:
        client.app.state.direct_answers = kept
    assert len(answered) == 1  # the second request never met the front door's answer
    assert _seen(at_the_door) == _seen(through_the_layers)
    assert at_the_door.headers["x-request-id"]


def test_a_missing_key_is_refused_before_any_direct_answer(client):
    r = client.post("/v1/fk", json=CASES["fk"][1])
    assert r.status_code == 401 and r.headers["www-authenticate"] == "Bearer"


def test_the_hot_paths_are_answered_at_the_door_and_counted_under_their_route(client):
    assert {("POST", path) for path, _ in CASES.values()} <= set(client.app.state.direct_answers)

    def count() -> float:
        text = client.get("/metrics").text
        line = 'planner_http_requests_total{method="POST",route="/v1/fk",status="200"}'
        found = [row for row in text.splitlines() if row.startswith(line)]
        return float(found[0].rsplit(" ", 1)[1]) if found else 0.0

    before = count()
    for _ in range(3):
        assert client.post("/v1/fk", json=CASES["fk"][1], headers=KEY).status_code == 200
    assert count() == before + 3


def test_the_gate_is_the_innermost_middleware(client):
    """The front door answers from inside the gate, skipping what lies between the gate and
    the routes: a middleware added inside the gate would be skipped for the hot routes
    without a word. So the gate stays the innermost middleware of the application (add a
    new one after it, outside; or teach the front door about it)."""
    from planner_api.middleware import RequestGate

    assert client.app.user_middleware[-1].cls is RequestGate


def test_requests_enter_at_the_front_unless_fastapis_telemetry_is_on(client, monkeypatch):
    """HTTP requests go from the server to the observer and the gate without FastAPI's own
    outer layers (planner_api.app.ServiceApp), answered as before; while FastAPI's telemetry
    is on (an OpenTelemetry provider configured), every request takes FastAPI's path again,
    through its telemetry, as FastAPI would route it."""
    from fastapi.telemetry._asgi import ExceptionTelemetryMiddleware, NativeTelemetry

    passed: list[str] = []
    inner = ExceptionTelemetryMiddleware.__call__

    async def counted(self, scope, receive, send):
        passed.append(scope["path"])
        await inner(self, scope, receive, send)

    monkeypatch.setattr(ExceptionTelemetryMiddleware, "__call__", counted)
    at_the_front = client.post("/v1/fk", json=CASES["fk"][1], headers=KEY)
    assert at_the_front.status_code == 200 and passed == []
    traced: list[str] = []

    async def telemetry(self, *, app, scope, receive, send, legacy_otel):
        traced.append(scope["path"])
        scope["fastapi.telemetry"] = object()  # as FastAPI marks a traced request
        await app(scope, receive, send)

    monkeypatch.setattr(NativeTelemetry, "enabled", lambda self: True)
    monkeypatch.setattr(NativeTelemetry, "__call__", telemetry)
    through_fastapi = client.post("/v1/fk", json=CASES["fk"][1], headers=KEY)
    assert traced == ["/v1/fk"] and passed == ["/v1/fk"]
    assert _seen(through_fastapi) == _seen(at_the_front)
    assert client.app._front is not None


def test_an_unexpected_error_at_the_front_is_fastapis_500(client, monkeypatch, caplog):
    """An error no handler answers, in a request that entered at the front: the same clean
    500 (status, headers but the request id, body) as through FastAPI's own outer layers,
    and the error logged."""
    from planner.kinematics import Manipulator

    def boom(*args, **kwargs):
        raise RuntimeError("secret internals")

    monkeypatch.setattr(Manipulator, "posture", boom)
    at_the_front = client.post("/v1/fk", json=CASES["fk"][1], headers=KEY)
    assert at_the_front.status_code == 500 and "secret" not in at_the_front.text
    assert "secret internals" in caplog.text
    kept, client.app._front = client.app._front, None
    try:
        through_fastapi = client.post("/v1/fk", json=CASES["fk"][1], headers=KEY)
    finally:
        client.app._front = kept
    assert _seen(at_the_front) == _seen(through_fastapi)


def test_a_fastapi_without_the_layers_the_front_knows_keeps_its_own_path(client, monkeypatch):
    """pyproject admits FastAPI releases without the private layers the front recognises
    (planner_api.app._private_layers): there the application has no front and answers
    through FastAPI's own layers, the same answer."""
    import planner_api.app as app_module

    at_the_front = client.post("/v1/fk", json=CASES["fk"][1], headers=KEY)
    monkeypatch.setattr(app_module, "_private_layers", lambda: None)
    client.app.build_middleware_stack()
    try:
        assert client.app._front is None
        through_fastapi = client.post("/v1/fk", json=CASES["fk"][1], headers=KEY)
    finally:
        monkeypatch.undo()
        client.app.build_middleware_stack()
    assert client.app._front is not None
    assert _seen(through_fastapi) == _seen(at_the_front)
