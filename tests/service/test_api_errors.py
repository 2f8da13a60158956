"""Bad input of every kind gets a clean 4xx in FastAPI's ``detail`` format naming the field,
never a 500: NaN, infinities, wrong shapes, wrong types, unknown fields, absurd sizes,
malformed or huge bodies."""

from __future__ import annotations

import json

import pytest
from fastapi import FastAPI
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planner_api.errors import install_error_handlers
from planner_api.settings import Settings

ROUTES = ["/v1/fk", "/v1/ik", "/v1/analyze", "/v1/plan", "/v1/plan/batch"]
START = {"q": [0.0, 1.0, 2.0], "assembly_mode": "+"}
NaN = "NaN"  # written into the JSON text as the bare NaN token by the plan-body test


def _items(r):
    body = r.json()
    assert set(body) == {"detail"}
    assert isinstance(body["detail"], list) and body["detail"]
    for item in body["detail"]:
        assert set(item) == {"loc", "msg", "type"}
    return body["detail"]


def _locs(r):
    return [tuple(i["loc"]) for i in _items(r)]


def _raw(api, path, text):
    return api.post(path, content=text.encode(), headers={"content-type": "application/json"})


@pytest.mark.parametrize(
    ("path", "text", "loc"),
    [
        ("/v1/fk", '{"q": [NaN, 1, 2]}', ("body", "q", 0)),
        ("/v1/fk", '{"q": [0, Infinity, 2]}', ("body", "q", 1)),
        ("/v1/fk", '{"q": [0, 1, -Infinity]}', ("body", "q", 2)),
        ("/v1/fk", '{"q": [0, 1, 1e400]}', ("body", "q", 2)),
        ("/v1/ik", '{"p": [0.1, 0.2, NaN]}', ("body", "p", 2)),
        ("/v1/fk", '{"q": [0, 1, 2], "design": {"L1": NaN}}', ("body", "design", "L1")),
        (
            "/v1/analyze",
            '{"q": [0, 1, 2], "assembly_mode": "+", "qd": [0, NaN, 0]}',
            ("body", "qd", 1),
        ),
    ],
)
def test_non_finite_numbers_are_422_naming_the_element(api, path, text, loc):
    r = _raw(api, path, text)
    assert r.status_code == 422
    assert loc in _locs(r)


@pytest.mark.parametrize(
    ("body", "loc"),
    [
        ({"q": [0, 1]}, ("body", "q")),
        ({"q": [0, 1, 2, 3]}, ("body", "q")),
        ({"q": [[0, 1, 2]]}, ("body", "q", 0)),
        ({"q": "0 1 2"}, ("body", "q")),
        ({"q": [0, 1, "x"]}, ("body", "q", 2)),
        ({"q": [0, 1, 2], "assembly_mode": "up"}, ("body", "assembly_mode")),
        ({"q": [0, 1, 2], "speed": 3}, ("body", "speed")),
        ({}, ("body", "q")),
        ({"q": [0, 1, 2], "design": {"L1": -0.2}}, ("body", "design", "L1")),
        ({"q": [0, 1, 2], "design": {"L2": 0}}, ("body", "design", "L2")),
        ({"q": [0, 1, 2], "design": {"L0": 1e9}}, ("body", "design", "L0")),
        ({"q": [0, 1, 2], "design": {"link_radius": -1}}, ("body", "design", "link_radius")),
        (
            {"q": [0, 1, 2], "design": {"joint_min": [0, 0, 0], "joint_max": [1, -1, 1]}},
            ("body", "design", "joint_max"),
        ),
        (
            {"q": [0, 1, 2], "design": {"joint_max": [100, 1, 1]}},
            ("body", "design", "joint_max", 0),
        ),
        ({"q": [0, 1, 2], "design": {"L3": 1}}, ("body", "design", "L3")),
        ({"q": [1e6, 1, 2]}, ("body", "q", 0)),
        ({"q": [10**400, 1, 2]}, ("body", "q", 0)),
    ],
)
def test_bad_fk_bodies_are_422_naming_the_field(api, body, loc):
    r = api.post("/v1/fk", json=body)
    assert r.status_code == 422, r.text
    assert loc in _locs(r)


@pytest.mark.parametrize(
    ("patch", "loc"),
    [
        ({"goal": {"x": 1}}, ("body", "goal")),
        ({"goal": {"p": [0, 0, 0], "working_mode": "+0+"}}, ("body", "goal", "working_mode")),
        ({"goal": {"q": [0, 0, 0]}}, ("body", "goal", "assembly_mode")),
        # the goal union's member tag is no field: goal.p, never goal.p.p
        ({"goal": {"p": [0.3, 0.1]}}, ("body", "goal", "p")),
        ({"goal": {"p": [0.3, "x", 0.1]}}, ("body", "goal", "p", 1)),
        ({"goal": {"q": [0, 2]}}, ("body", "goal", "q")),
        ({"start": {"p": [0.3, 0, 0]}}, ("body", "start", "q")),
        ({"obstacles": [{"type": "cone"}]}, ("body", "obstacles", 0)),
        (
            {"obstacles": [{"type": "sphere", "center": [0, 0, 0], "radius": -1}]},
            ("body", "obstacles", 0, "sphere", "radius"),
        ),
        (
            {
                "obstacles": [
                    {
                        "type": "box",
                        "center": [0, 0, 0],
                        "size": [1, 1, 1],
                        "quaternion": [0, 0, 0, 0],
                    }
                ]
            },
            ("body", "obstacles", 0, "box", "quaternion"),
        ),
        (
            {"obstacles": [{"type": "capsule", "a": [0, 0, 0], "b": [0, 0, NaN], "radius": 1}]},
            ("body", "obstacles", 0, "capsule", "b", 2),
        ),
        ({"margins": {"kappa_max": 0.5}}, ("body", "margins", "kappa_max")),
        ({"margins": {"serial_min": 1.0}}, ("body", "margins", "serial_min")),
        ({"margins": {"clearance": -0.1}}, ("body", "margins", "clearance")),
        ({"planner": {"time_budget_s": 0}}, ("body", "planner", "time_budget_s")),
        ({"planner": {"name": "rm -rf /"}}, ("body", "planner", "name")),
        ({"planner": {"seed": -1}}, ("body", "planner", "seed")),
        ({"planner": {"seed": 8.5}}, ("body", "planner", "seed")),  # a whole 8.0 is taken
        ({"timing": {"method": "spline"}}, ("body", "timing", "method")),
        ({"timing": {"sample_rate_hz": 1e9}}, ("body", "timing", "sample_rate_hz")),
        ({"limits": {"velocity": [1, 0, 1]}}, ("body", "limits", "velocity", 1)),
        ({"limits": {"jerk": [1, 1]}}, ("body", "limits", "jerk")),
        ({"start": None}, ("body", "start")),
    ],
)
def test_bad_plan_bodies_are_422_naming_the_field(api, patch, loc):
    body = {"start": START, "goal": {"p": [0.3, 0.1, 0.2]}, **patch}
    r = _raw(api, "/v1/plan", json.dumps(body).replace('"NaN"', "NaN"))
    assert r.status_code == 422, r.text
    assert loc in _locs(r)


def test_a_whole_float_is_taken_where_a_field_is_an_integer(api):
    """JSON does not tell ``8.0`` from ``8``: an integer field takes it (and a fraction is a
    422 naming the field, above)."""
    body = {"start": START, "goal": START, "planner": {"seed": 8.0}, "timing": {"method": "none"}}
    r = api.post("/v1/plan", json=body)
    assert r.status_code == 200, r.text


def test_too_many_obstacles_is_422_naming_obstacles(api):
    sphere = {"type": "sphere", "center": [1, 1, 1], "radius": 0.1}
    r = api.post("/v1/plan", json={"start": START, "goal": START, "obstacles": [sphere] * 257})
    assert r.status_code == 422
    (item,) = _items(r)
    assert item["loc"] == ["body", "obstacles"] and item["type"] == "limit_exceeded"


def test_batch_limits_are_422_naming_the_field(api):
    one = {"start": START, "goal": START}
    r = api.post("/v1/plan/batch", json={"requests": [one] * 65})
    assert r.status_code == 422 and _items(r)[0]["loc"] == ["body", "requests"]
    r = api.post("/v1/plan/batch", json={"requests": []})
    assert r.status_code == 422 and _items(r)[0]["loc"] == ["body", "requests"]
    sphere = {"type": "sphere", "center": [1, 1, 1], "radius": 0.1}
    r = api.post("/v1/plan/batch", json={"requests": [one, {**one, "obstacles": [sphere] * 300}]})
    assert r.status_code == 422
    assert _items(r)[0]["loc"] == ["body", "requests", 1, "obstacles"]


@pytest.mark.parametrize("path", ROUTES)
@pytest.mark.parametrize(
    "text",
    [
        "",
        "{",
        "not json",
        "[]",
        "null",
        "3",
        '"q"',
        "[" * 100_000 + "]" * 100_000,
        '{"q": ' + "[" * 50_000 + "]" * 50_000 + "}",
    ],
    ids=[
        "empty",
        "truncated",
        "garbage",
        "list",
        "null",
        "number",
        "string",
        "deep-list",
        "deep-field",
    ],
)
def test_malformed_bodies_are_422(api, path, text):
    r = _raw(api, path, text)
    assert r.status_code == 422, r.text
    assert _items(r)[0]["loc"][0] == "body"


_BODY_LIMIT = Settings.model_fields["max_body_bytes"].default


def test_body_over_the_size_limit_is_413(api):
    r = _raw(api, "/v1/fk", '{"q": [0, 1, 2], "pad": "' + "x" * _BODY_LIMIT + '"}')
    assert r.status_code == 413
    assert _items(r)[0]["type"] == "body_too_large"


def test_streamed_body_over_the_size_limit_is_413(api):
    def chunks():
        yield b'{"q": [0, 1, 2], "pad": "'
        for _ in range(_BODY_LIMIT // (1024 * 1024) + 1):
            yield b"x" * (1024 * 1024)
        yield b'"}'

    r = api.post("/v1/fk", content=chunks(), headers={"content-type": "application/json"})
    assert r.status_code == 413


def test_unknown_route_and_method_are_clean(api):
    r = api.get("/v1/nope")
    assert r.status_code == 404 and _items(r)
    r = api.get("/v1/fk")
    assert r.status_code == 405 and _items(r)


def test_unexpected_error_is_a_clean_logged_500(caplog):
    from fastapi.testclient import TestClient

    app = FastAPI()
    install_error_handlers(app)

    @app.get("/boom")
    def boom() -> None:
        raise RuntimeError("secret internals")

    r = TestClient(app, raise_server_exceptions=False).get("/boom")
    assert r.status_code == 500
    (item,) = _items(r)
    assert item["type"] == "internal_error" and "secret" not in item["msg"]
    assert "secret internals" in caplog.text


_json = st.recursive(
    st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=5),
    lambda children: (
        st.lists(children, max_size=4)
        | st.dictionaries(
            st.sampled_from(
                [
                    "q",
                    "p",
                    "design",
                    "L0",
                    "assembly_mode",
                    "goal",
                    "start",
                    "type",
                    "obstacles",
                    "x",
                ]
            ),
            children,
            max_size=4,
        )
    ),
    max_leaves=12,
)


@settings(
    max_examples=60,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(path=st.sampled_from(ROUTES), body=_json)
def test_fuzzed_bodies_never_give_a_5xx(api, path, body):
    r = _raw(api, path, json.dumps(body))
    assert r.status_code < 500, r.text
    assert r.json()


def test_planning_budget_over_the_request_budget_is_422(api):
    r = api.post("/v1/plan", json={"start": START, "goal": START, "planner": {"time_budget_s": 31}})
    assert r.status_code == 422
    (item,) = _items(r)
    assert item["loc"] == ["body", "planner", "time_budget_s"]
    assert "30 s" in item["msg"]


@pytest.mark.parametrize(
    ("kwargs", "loc"),
    [
        ({"L0": -0.1}, ["body", "design", "L0"]),
        ({"joint_min": (-1, -1, 2), "joint_max": (1, 1, 1)}, ["body", "design", "joint_min", 2]),
    ],
)
def test_a_library_design_error_is_answered_at_its_field(kwargs, loc):
    """A :class:`planner.DesignError` that reaches the service (a design built in a job,
    inside ``located("body", "design")``, or not located at all) is a 422 whose ``loc`` ends
    with the error's ``field``: the path pydantic writes for the same field of a request."""
    import asyncio
    from contextlib import nullcontext

    from planner import Design, DesignError
    from planner.wire import located
    from planner_api.errors import error_answer

    for where in (located("body", "design"), nullcontext()):
        with pytest.raises(DesignError) as info, where:
            Design(**{"L0": 0.5, "L1": 0.2, "L2": 0.6, **kwargs})
        answer = asyncio.run(error_answer(info.value))
        (item,) = json.loads(answer.body)["detail"]
        assert answer.status_code == 422 and item["type"] == "design_error"
        assert item["loc"] == loc, where
