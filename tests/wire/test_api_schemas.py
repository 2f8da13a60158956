"""The wire models hold exactly the vocabulary of docs/conventions.md (names, statuses, kinds)."""

from __future__ import annotations

import json
import math
import typing

import pytest
from pydantic import ValidationError

from planner import wire
from planner.wire import (
    BoxObstacle,
    CartesianTargetModel,
    DiagnosticsModel,
    JointPostureModel,
    PlanBatchRequest,
    PlanBatchResponse,
    PlanRequest,
    PlanResponse,
    SphereObstacle,
)

START = {"q": [0.0, 1.0, 2.0], "assembly_mode": "+"}


def test_plan_request_fields_and_required():
    assert set(PlanRequest.model_fields) == {
        "design",
        "start",
        "goal",
        "obstacles",
        "scene",
        "margins",
        "planner",
        "timing",
        "limits",
        "gravity",
        "replace",  # a running trajectory to replace mid-motion (docs/execution.md)
    }
    required = {n for n, f in PlanRequest.model_fields.items() if f.is_required()}
    assert required == {"start", "goal"}
    assert set(wire.MarginsModel.model_fields) == {"kappa_max", "serial_min", "clearance"}
    assert {"name", "time_budget_s", "seed", "simplify"} <= set(wire.PlannerOptions.model_fields)
    assert {"method", "sample_rate_hz"} <= set(wire.TimingOptionsModel.model_fields)
    assert {"velocity", "acceleration", "jerk"} <= set(wire.Limits.model_fields)
    assert typing.get_args(wire.TimingOptionsModel.model_fields["method"].annotation) == (
        "toppra",
        "ruckig",
        "none",
    )
    assert set(wire.DesignModel.model_fields) == {
        "L0",
        "L1",
        "L2",
        "link_radius",
        "joint_min",
        "joint_max",
        "inertia",
    }


def test_plan_response_vocabulary():
    assert set(typing.get_args(wire.PlanStatus)) == {
        "solved",
        "no_path",
        "unreachable",
        "invalid_start",
        "invalid_goal",
        "timeout",
    }
    assert {"status", "message", "path", "trajectory", "diagnostics"} <= set(
        PlanResponse.model_fields
    )
    assert set(wire.PathModel.model_fields) == {"waypoints", "segments", "transits"}
    assert set(wire.SegmentModel.model_fields) == {
        "working_mode",
        "assembly_mode",
        "start_index",
        "end_index",
    }
    assert set(wire.TransitModel.model_fields) == {"index", "q", "kind", "flipped"}
    assert set(typing.get_args(wire.TransitKind)) == {
        "P_on_axis",
        "leg_A_stretched",
        "leg_A_folded",
        "leg_B_stretched",
        "leg_B_folded",
    }
    assert set(typing.get_args(wire.TransitModel.model_fields["flipped"].annotation)) == {
        "axis",
        "A",
        "B",
    }
    assert {"duration", "t", "q", "qd", "qdd"} <= set(wire.TrajectoryModel.model_fields)
    assert {
        "planning_time_s",
        "timing_time_s",
        "min_clearance",
        "max_kappa_A",
        "min_serial_margin",
    } <= set(DiagnosticsModel.model_fields)
    assert set(PlanBatchRequest.model_fields) == {"requests"}
    assert set(PlanBatchResponse.model_fields) == {"results"}


def test_a_full_response_parses_with_declared_diagnostics_and_ignores_unknown_ones():
    text = """{"status": "solved", "message": "",
      "path": {"waypoints": [[0,1,2],[0.1,1,2],[0.2,1,2]],
               "segments": [{"working_mode": "++-", "assembly_mode": "+", "start_index": 0,
                             "end_index": 1},
                            {"working_mode": "+--", "assembly_mode": "+", "start_index": 1,
                             "end_index": 2}],
               "transits": [{"index": 1, "q": [0.1,1,2], "kind": "leg_A_stretched",
                             "flipped": "A"}]},
      "trajectory": {"duration": 1.0, "t": [0, 1], "q": [[0,1,2],[0.2,1,2]],
                     "qd": [[0,0,0],[0,0,0]], "qdd": [[0,0,0],[0,0,0]], "jerk": null},
      "diagnostics": {"planning_time_s": 0.01, "path_length": 0.2, "from_a_newer_server": 1},
      "future_field": 1}"""
    r = PlanResponse.model_validate_json(text)
    assert r.path.transits[0].kind == "leg_A_stretched"
    assert r.diagnostics.path_length == 0.2
    assert "from_a_newer_server" not in r.diagnostics.model_dump()
    assert r.trajectory.duration == 1.0


def test_goal_is_a_posture_or_a_target():
    joint = PlanRequest(start=START, goal={"q": [0, 1, 2], "assembly_mode": "-"})
    assert isinstance(joint.goal, JointPostureModel)
    cart = PlanRequest(start=START, goal={"p": [0.3, 0.1, 0.2]})
    assert isinstance(cart.goal, CartesianTargetModel) and cart.goal.working_mode == "any"
    with pytest.raises(ValidationError):
        PlanRequest(start=START, goal={"q": [0, 1, 2], "p": [0, 0, 0], "assembly_mode": "+"})


def test_obstacles_are_discriminated_on_type_and_box_quaternion_normalised():
    req = PlanRequest(
        start=START,
        goal=START,
        obstacles=[
            {"type": "sphere", "center": [0, 0, 1], "radius": 0.1},
            {"type": "box", "center": [0, 0, 0], "size": [1, 2, 3], "quaternion": [2, 0, 0, 0]},
            {"type": "capsule", "a": [0, 0, 0], "b": [1, 0, 0], "radius": 0.05},
        ],
    )
    assert [type(o).__name__ for o in req.obstacles] == [
        "SphereObstacle",
        "BoxObstacle",
        "CapsuleObstacle",
    ]
    assert req.obstacles[1].quaternion == [1.0, 0.0, 0.0, 0.0]
    q = BoxObstacle(center=[0, 0, 0], size=[1, 1, 1], quaternion=[1, 1, 1, 1]).quaternion
    assert math.isclose(sum(v * v for v in q), 1.0)


def test_the_obstacle_schemas_require_their_type():
    """The union picks its member by ``type`` and refuses a body without it: every member's
    schema says so (``required``, no default); tests/service/test_api_openapi.py reads the
    service's document."""
    defs = PlanRequest.model_json_schema()["$defs"]
    for name, tag in [
        ("SphereObstacle", "sphere"),
        ("BoxObstacle", "box"),
        ("CapsuleObstacle", "capsule"),
        ("PointsObstacle", "points"),
    ]:
        schema = defs[name]
        assert schema["required"][0] == "type", (name, schema["required"])
        assert schema["properties"]["type"] == {"const": tag, "title": "Type", "type": "string"}
    with pytest.raises(ValidationError) as info:
        PlanRequest(start=START, goal=START, obstacles=[{"center": [0, 0, 1], "radius": 0.1}])
    assert info.value.errors()[0]["type"] == "union_tag_not_found"
    assert SphereObstacle(center=[0, 0, 1], radius=0.1).type == "sphere"  # Python keeps it


def test_round_trip_through_json_is_lossless():
    req = PlanRequest(
        start=START,
        goal={"p": [0.3, 0.1, 0.2], "working_mode": "+-+"},
        planner={"seed": 3, "time_budget_s": 0.5},
        limits={"velocity": [1, 2, 3]},
    )
    assert PlanRequest.model_validate_json(req.model_dump_json()) == req


def test_second_part_vocabulary():
    """docs/conventions.md, "Wire, second part": the names and values fixed there."""
    from planner.wire import (
        CartesianRequest,
        CartesianResponse,
        JointGoal,
        TrajectoryPoint,
        TrajectoryPointsModel,
    )

    limits = wire.Limits.model_fields
    for name in ("velocity_scaling", "acceleration_scaling"):
        assert limits[name].default == 1.0
    assert typing.get_args(wire.TimingOptionsModel.model_fields["format"].annotation) == (
        "arrays",
        "points",
    )
    assert wire.TimingOptionsModel.model_fields["format"].default == "arrays"
    assert typing.get_args(CartesianTargetModel.model_fields["prefer"].annotation) == (
        "shortest",
        "best_conditioned",
    )
    assert CartesianTargetModel.model_fields["prefer"].default == "shortest"
    assert CartesianTargetModel.model_fields["tolerance"].default == 0.0
    assert JointGoal.model_fields["tolerance"].default == 0.0
    assert set(TrajectoryPointsModel.model_fields) >= {"duration", "joint_names", "points"}
    assert TrajectoryPointsModel.model_fields["joint_names"].default_factory() == [
        "theta1",
        "theta2",
        "theta3",
    ]
    assert set(TrajectoryPoint.model_fields) == {
        "time_from_start",
        "positions",
        "velocities",
        "accelerations",
        "effort",
    }
    assert set(CartesianRequest.model_fields) == {
        "design",
        "start",
        "waypoints",
        "path_tolerance",
        "obstacles",
        "scene",
        "margins",
        "timing",
        "limits",
        "gravity",
    }
    assert {n for n, f in CartesianRequest.model_fields.items() if f.is_required()} == {
        "start",
        "waypoints",
    }
    assert CartesianRequest.model_fields["path_tolerance"].default == 0.001
    assert set(PlanResponse.model_fields) <= set(CartesianResponse.model_fields)
    assert "fraction" in CartesianResponse.model_fields
    assert (
        "max_path_deviation"
        in CartesianResponse.model_fields["diagnostics"].annotation.model_fields
    )
    assert DiagnosticsModel().proven_infeasible is False


def test_third_part_dynamics_vocabulary():
    """docs/conventions.md, "Wire, third part": design.inertia, gravity, /v1/dynamics,
    limits.torque, trajectory.tau, point effort, diagnostics.max_torque_ratio."""
    from planner.wire import (
        DynamicsRequest,
        DynamicsResponse,
        InertiaModel,
        LinkInertiaModel,
        TrajectoryModel,
    )

    assert set(InertiaModel.model_fields) == {"proximal", "distal", "payload", "base", "rotor"}
    assert set(LinkInertiaModel.model_fields) == {"mass", "com", "I_perp", "I_axial"}
    assert set(DynamicsRequest.model_fields) == {
        "design",
        "gravity",
        "assembly_mode",
        "q",
        "qd",
        "qdd",
    }
    assert {"tau", "mass_matrix"} <= set(DynamicsResponse.model_fields)
    assert PlanRequest.model_fields["gravity"].default_factory() == [0.0, 0.0, -9.81]
    assert "torque" in wire.Limits.model_fields
    assert "tau" in TrajectoryModel.model_fields
    assert "max_torque_ratio" in DiagnosticsModel.model_fields


def _request_models() -> list[type]:
    """Every request model of the wire (strict: ``_Request`` and its subclasses)."""
    from planner.wire.common import _Request

    found, todo = set(), [_Request]
    while todo:
        for sub in todo.pop().__subclasses__():
            found.add(sub)
            todo.append(sub)
    assert len(found) > 20 and {m.__module__.split(".")[1] for m in found} == {"wire"}, wire
    return sorted(found, key=lambda m: m.__name__)


def _ints_take_whole_floats(tp: object, metadata: list) -> bool:
    """Whether every ``int`` in the annotation ``tp`` carries the wire's whole-float rule."""
    from typing import Annotated, get_args, get_origin

    from pydantic.functional_validators import BeforeValidator

    from planner.wire.common import _whole_number

    if tp is int:
        return any(isinstance(m, BeforeValidator) and m.func is _whole_number for m in metadata)
    if get_origin(tp) is Annotated:
        inner, *extra = get_args(tp)
        return _ints_take_whole_floats(inner, [*metadata, *extra])
    return all(_ints_take_whole_floats(arg, []) for arg in get_args(tp))


def test_every_integer_field_of_a_strict_request_takes_a_whole_float():
    """JSON does not tell ``8.0`` from ``8``: a strict request's integer field takes it (the
    wire's ``Integer``), so no field is left refusing it."""
    for model in _request_models():
        if model.model_config.get("strict") is False:
            continue  # a query model: lax already
        for name, field in model.model_fields.items():
            ok = _ints_take_whole_floats(field.annotation, list(field.metadata))
            assert ok, f"{model.__name__}.{name} refuses 8.0: annotate it planner.wire.Integer"


@pytest.mark.parametrize(
    ("body", "loc"),
    [
        ({"planner": {"seed": 8.0}}, None),
        ({"planner": {"seed": 8.5}}, ("planner", "seed")),
        ({"planner": {"seed": True}}, ("planner", "seed")),
        ({"planner": {"seed": "8"}}, ("planner", "seed")),
    ],
)
def test_a_whole_float_is_an_integer_and_a_fraction_is_named(body, loc):
    if loc is None:
        assert PlanRequest(start=START, goal=START, **body).planner.seed == 8
        assert type(PlanRequest(start=START, goal=START, **body).planner.seed) is int
        return
    with pytest.raises(ValidationError) as info:
        PlanRequest.model_validate_json(json.dumps({"start": START, "goal": START, **body}))
    (error,) = info.value.errors()
    assert error["loc"] == loc, error
