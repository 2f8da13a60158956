"""The library's goal options (:func:`planner.planning.plan_with_goal_options`), without the
service: the same behaviour as ``goal.prefer`` / ``goal.tolerance`` of ``POST /v1/plan``
(tests/service/test_api_goal_options.py holds the HTTP side), checked by the test's own arithmetic."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from planner import Design
from planner.exceptions import InputError
from planner.planning import (
    CartesianTarget,
    JointPosture,
    PlanOptions,
    plan,
    plan_with_goal_options,
)
from planner.planning.tolerance import goal_alternatives

START = JointPosture([-0.2187, 2.8609, 0.2807], "+")


@pytest.mark.parametrize("tolerance", [0.001, 0.05, 0.3])
def test_every_alternative_lies_within_the_tolerance(tolerance):
    goal = np.array([0.4, -0.1, 0.2])
    alts = goal_alternatives(goal, np.array([0.0, 0.3, 0.5]), tolerance)
    dist = np.linalg.norm(alts - goal, axis=1)
    assert len(alts) == 8 and np.all(dist <= tolerance) and np.all(dist > 0)
    # the first is on the way to the start, at the full tolerance
    toward = np.array([0.0, 0.3, 0.5]) - goal
    assert np.allclose(alts[0] - goal, tolerance * toward / np.linalg.norm(toward), atol=1e-9)


def test_a_joint_goal_beyond_its_limit_is_replaced_by_one_within_the_tolerance():
    design = replace(Design.default(), joint_max=(0.5, math.pi, math.pi))
    goal = JointPosture([0.52, 2.8609, 0.2807], "+")  # theta1 0.02 rad beyond 0.5
    options = PlanOptions(seed=1)
    assert plan(design, START, goal, options=options).status.value == "invalid_goal"
    near = plan_with_goal_options(design, START, goal, options=options, tolerance=0.05)
    assert near.solved, near.message
    end = near.path.waypoints[-1]
    assert np.linalg.norm(end - goal.q) <= 0.05 and end[0] <= 0.5
    assert "within goal.tolerance = 0.05 rad" in near.message


def test_without_options_it_is_plan():
    goal = CartesianTarget([0.45, 0.3, 0.1], "any")
    options = PlanOptions(seed=3)
    a = plan(Design.default(), START, goal, options=options)
    b = plan_with_goal_options(Design.default(), START, goal, options=options)
    assert a.solved and b.solved, (a.message, b.message)
    assert np.array_equal(a.path.waypoints, b.path.waypoints)
    assert b.message.startswith(a.message) and "shortest" in b.message


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [({"prefer": "fastest"}, "prefer"), ({"tolerance": -1.0}, "tolerance"),
     ({"tolerance": math.nan}, "tolerance")],
)  # fmt: skip
def test_bad_options_name_their_field(kwargs, field):
    with pytest.raises(InputError) as err:
        plan_with_goal_options(Design.default(), START, JointPosture([0, 2.8, 0.3], "+"), **kwargs)
    assert err.value.field == field
