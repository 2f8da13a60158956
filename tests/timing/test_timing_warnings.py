"""A path shorter than any float can measure times without a numpy warning: waypoints that
differ by a subnormal (2.2e-311 rad, whose length underflows to 0) are one point, and the
trajectory rests there; the plan request that showed the warnings answers cleanly."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from planner import Design
from planner.endpoints.plan import plan
from planner.timing import JointLimits, time_path
from planner.wire import PlanRequest

TINY = [0.0, 0.0, -2.225073858507e-311]


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_a_subnormal_path_times_without_warnings(method):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        traj = time_path(
            Design.default(),
            np.array([TINY, [0.0, 0.0, 0.0]]),
            JointLimits.default(),
            method=method,
        )
    assert traj.duration == 0.0 and np.array_equal(traj.q[-1], [0.0, 0.0, 0.0])
    assert np.all(traj.qd == 0.0)


def test_the_plan_request_answers_without_warnings():
    body = {"start": {"q": TINY, "assembly_mode": "+"},
            "goal": {"q": [0.0, 0.0, 0.0], "assembly_mode": "+"}}  # fmt: skip
    for method in ("toppra", "ruckig"):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            answer = plan(PlanRequest.model_validate({**body, "timing": {"method": method}}))
        assert answer.status in ("solved", "invalid_start", "invalid_goal"), answer.message
