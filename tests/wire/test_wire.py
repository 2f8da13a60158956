"""The wire room: its export list is exactly its modules' public names, errors located at
their field in one way, and plan answers built from library results with every diagnostics
field declared."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import numpy as np
import pytest

import planner.wire
from planner import Design
from planner.exceptions import InputError, LimitsError, PlannerError
from planner.timing import JointLimits, time_path
from planner.wire import Limits, PlanRequest, located, plan_inputs, plan_response


def test_the_wire_exports_exactly_its_modules_public_names():
    """``planner.wire.__all__`` is the
    union of its modules' ``__all__``, each listing every class and function its module
    defines without a leading underscore: a model added to a module and forgotten in the
    list fails here, and so does a library name passed through the wire (the wire owns its
    shapes; a core class under a wire name would shadow it)."""
    declared: dict[str, object] = {}
    for info in pkgutil.iter_modules(planner.wire.__path__):
        module = importlib.import_module(f"planner.wire.{info.name}")
        public = {
            name
            for name, obj in vars(module).items()
            if not name.startswith("_")
            and name.isidentifier()  # not pydantic's own entry for a parametrised generic
            and (inspect.isclass(obj) or inspect.isfunction(obj))
            and obj.__module__ == module.__name__
        }
        listed = set(module.__all__)
        assert public <= listed, (module.__name__, "not exported", public - listed)
        for name in listed:
            obj = getattr(module, name)
            if inspect.isclass(obj) or inspect.isfunction(obj):  # not a constant or an alias
                home = obj.__module__
                assert home.startswith("planner.wire."), (module.__name__, name, home)
            assert declared.setdefault(name, obj) is obj, name  # one object per name
    assert len(planner.wire.__all__) == len(set(planner.wire.__all__))
    assert set(planner.wire.__all__) == set(declared), set(planner.wire.__all__) ^ set(declared)
    for name, obj in declared.items():
        assert getattr(planner.wire, name) is obj, name


@pytest.mark.parametrize(
    ("field", "path"),
    [(None, ()), ("sample_rate_hz", ("sample_rate_hz",)), ("limits.jerk", ("limits", "jerk")),
     (("waypoints", 3, 1), ("waypoints", 3, 1))],
)  # fmt: skip
def test_located_prefixes_the_field_path(field, path):
    with pytest.raises(PlannerError) as info, located("body", "timing"):
        raise InputError("bad", field=field)
    assert info.value.loc == ("body", "timing", *path)


def test_an_inner_location_wins():
    with pytest.raises(PlannerError) as info, located("body"), located("body", "design"):
        raise InputError("bad")
    assert info.value.loc == ("body", "design")


def test_library_errors_name_their_argument():
    """The library sets ``field`` where it knows it: no caller parses messages."""
    with pytest.raises(InputError) as info:
        time_path(
            Design.default(),
            np.array([[0, 2, 1], [0.1, 2, 1]]),
            JointLimits.default(),
            sample_rate_hz=-1.0,
        )
    assert info.value.field == "sample_rate_hz"
    with pytest.raises(LimitsError) as info:
        JointLimits(velocity=(1.0, 0.0, 1.0), acceleration=(1.0, 1.0, 1.0))
    assert info.value.field == "velocity"


def test_bad_limits_are_located_at_their_field():
    model = Limits.model_construct(velocity=[1.0, 1e9, 1.0], acceleration=None, jerk=None)
    with pytest.raises(LimitsError) as info:
        planner.wire.joint_limits_to_core(model)
    assert info.value.loc == ("body", "limits", "velocity")


def test_a_plan_answer_declares_every_diagnostics_field():
    from planner.planning import plan

    request = PlanRequest.model_validate(
        {"start": {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"},
         "goal": {"q": [0.3, 2.1, 0.9], "assembly_mode": "+"}, "planner": {"seed": 1}}
    )  # fmt: skip
    inputs = plan_inputs(request)
    problem = inputs.problem
    assert problem.design is request.design.to_design()  # built once, at validation
    result = plan(problem.design, problem.start, inputs.goal, options=problem.options)
    answer = plan_response(result)
    assert answer.status == "solved"
    d = answer.diagnostics
    assert d.model_extra in (None, {})
    assert d.planner and d.path_length == pytest.approx(
        float(np.sum(np.linalg.norm(np.diff(np.array(answer.path.waypoints), axis=0), axis=1)))
    )
