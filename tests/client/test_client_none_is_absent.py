"""None means absent in every public method of the client: each optional argument (and each
optional field a method takes as a keyword) given as None sends exactly the request sent
without it; and a point cloud's numpy ``points`` go into a plan as into a scene."""

from __future__ import annotations

import inspect
import json
from typing import Any

import numpy as np
import pytest

from planner.client import AsyncPlannerClient, PlannerClient
from planner.wire import (
    CartesianRequest,
    DesignOptimizeRequest,
    PlanRequest,
    SequenceRequest,
    SimulateRequest,
    StopRequest,
    TimingRequest,
    WorkspaceRequest,
)

START = {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"}
GOAL = {"q": [0.3, 2.1, 1.2], "assembly_mode": "+"}
PLAN = {"start": START, "goal": GOAL}
TRAJECTORY = {
    "t": [0.0, 0.1],
    "q": [[0.0, 2.0, 1.0], [0.0, 2.0, 1.0]],
    "qd": [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
    "qdd": [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
}

#: The required arguments of each public method (positional, keyword).
REQUIRED: dict[str, tuple[tuple[Any, ...], dict[str, Any]]] = {
    "health": ((), {}),
    "ready": ((), {}),
    "version": ((), {}),
    "designs": ((), {}),
    "fk": (([0.0, 2.0, 1.0],), {}),
    "ik": (([0.3, 0.1, 0.2],), {}),
    "analyze": (([0.0, 2.0, 1.0], "+"), {}),
    "check_design": ((), {}),
    "plan": ((), PLAN),
    "cartesian": ((), {"start": START, "waypoints": [[0.1, 0.0, 0.3]]}),
    "plan_batch": (([PLAN],), {}),
    "sequence": ((), {"start": START, "targets": [{"goal": GOAL}]}),
    "workspace": ((), {}),
    "figure": (("region_map",), {}),
    "timing": (([[0.0, 2.0, 1.0], [0.3, 2.1, 1.2]],), {}),
    "dynamics": (([0.0, 2.0, 1.0],), {}),
    "design_mjcf": ((), {}),
    "optimize_design": ((), {}),
    "regions": ((), {}),
    "submit_job": (("plan", PLAN), {}),
    "job": (("0" * 32,), {}),
    "jobs": ((), {}),
    "cancel_job": (("0" * 32,), {}),
    "put_scene": (("cell",), {}),
    "scene": (("cell",), {}),
    "delete_scene": (("cell",), {}),
    "scenes": ((), {}),
    "calibrate": (([{"q": [0.0, 2.0, 1.0], "p": [0.665, 0.022, 0.0]}],), {}),
    "calibration_poses": ((), {}),
    "identify": (([[0.0, 2.0, 1.0]], [[0.0, 0.0, 0.0]], [[0.0, 0.0, 0.0]], [[-6.7, 0.0, 0.0]]), {}),
    "simulate": ((), {"trajectory": TRAJECTORY}),
    "simulate_bag": ((), {"trajectory": TRAJECTORY}),
    "stop": ((TRAJECTORY, 0.05), {}),
}
#: Methods that open a session instead of sending one request (tested on their own below).
SESSIONS = {"stream"}
#: The request model whose optional fields a method takes as ``**keywords``.
KEYWORD_MODELS = {
    "plan": PlanRequest,
    "cartesian": CartesianRequest,
    "sequence": SequenceRequest,
    "workspace": WorkspaceRequest,
    "timing": TimingRequest,
    "optimize_design": DesignOptimizeRequest,
    "simulate": SimulateRequest,
    "simulate_bag": SimulateRequest,
    "stop": StopRequest,
}


def _public(cls: type) -> set[str]:
    return {n for n in vars(cls) if not n.startswith("_") and n not in ("close", "aclose")}


@pytest.fixture
def client(monkeypatch) -> PlannerClient:
    """A client whose calls return what they would send (no transport)."""
    monkeypatch.setattr(PlannerClient, "_execute", lambda self, call: self._request_args(call))
    return PlannerClient("http://planner.invalid")


def _optional_arguments(name: str) -> list[str]:
    """Every optional argument of the method ``name``: its parameters with a default, and
    for a method taking ``**keywords`` the optional fields of its request model."""
    params = inspect.signature(getattr(PlannerClient, name)).parameters.values()
    names = [p.name for p in params if p.default is not inspect.Parameter.empty]
    if any(p.kind is p.VAR_KEYWORD for p in params):
        model = KEYWORD_MODELS[name]
        names += [f for f, info in model.model_fields.items() if not info.is_required()]
    taken = set(REQUIRED[name][1])
    return [n for n in dict.fromkeys(names) if n not in taken]


def test_every_public_method_is_covered():
    assert set(REQUIRED) | SESSIONS == _public(PlannerClient) == _public(AsyncPlannerClient)


@pytest.mark.parametrize("name", sorted(REQUIRED))
def test_none_means_absent_for_every_optional_argument(client, name):
    args, kwargs = REQUIRED[name]
    method = getattr(client, name)
    sent = method(*args, **kwargs)
    optional = _optional_arguments(name)
    for arg in optional:
        assert method(*args, **kwargs, **{arg: None}) == sent, f"{name}({arg}=None)"
    # positional optional arguments as None too (e.g. ik(p, None), figure(name, None))
    params = list(inspect.signature(getattr(PlannerClient, name)).parameters.values())
    positional = [p for p in params if p.kind is p.POSITIONAL_OR_KEYWORD and p.name != "self"]
    if len(positional) > len(args) and not kwargs:
        assert method(*args, *[None] * (len(positional) - len(args))) == sent, name


def test_plan_sequence_and_cartesian_drop_a_none_in_their_request_mapping(client):
    for name, fields in (
        ("plan", PLAN),
        ("sequence", REQUIRED["sequence"][1]),
        ("cartesian", REQUIRED["cartesian"][1]),
    ):
        method = getattr(client, name)
        sent = method(fields)
        assert method({**fields, "obstacles": None, "limits": None, "timing": None}) == sent


def test_plan_takes_a_numpy_cloud_as_put_scene_does(client):
    points = np.array([[0.4, 0.0, 0.1], [0.4, 0.05, 0.1], [0.45, 0.0, 0.12]])
    cloud = {"type": "points", "points": points, "radius": 0.01}
    listed = {**cloud, "points": points.tolist()}
    for name, fields in (
        ("plan", PLAN),
        ("sequence", REQUIRED["sequence"][1]),
        ("cartesian", REQUIRED["cartesian"][1]),
    ):
        method = getattr(client, name)
        sent = method(**fields, obstacles=[cloud])
        assert sent == method(**fields, obstacles=[listed])
        assert json.loads(sent["content"])["obstacles"][0]["points"] == points.tolist()
        assert method({**fields, "obstacles": [cloud]}) == sent  # in the mapping too
    scene = client.put_scene("cell", [cloud])
    assert json.loads(scene["content"])["obstacles"] == [listed]


def test_stream_takes_none_as_absent():
    """The stream's opening message is the same with an option None as without it (the
    async session connects only when entered, so its message can be read unsent)."""
    from planner.client_stream import first_message

    client = AsyncPlannerClient("http://planner.invalid")
    sent = client.stream(PLAN)._first
    assert sent == first_message("plan", PLAN, 1000.0, 0.05)
    for name in ("kind", "rate_hz", "lookahead_s"):
        assert client.stream(PLAN, **{name: None})._first == sent, name
    assert client.stream(PLAN, auto_ack=None).auto_ack is True
