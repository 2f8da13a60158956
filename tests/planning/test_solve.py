"""The library's plan-and-time call, :func:`planner.solver.solve`: one call gives the plan and
its checked trajectory, the same answer the service's plan job gives (the job is convert ->
solve -> respond), under one deadline policy.

Independent routes: every solved answer is re-checked by ``tests/plan_checker.py`` (its own
kinematics, limits and clearance, the trajectory densely); the plan is the one
:func:`planner.planning.plan_with_goal_options` finds with the same seed; the deadline policy
is checked on the budget it hands the search, not on wall-clock times.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from plan_checker import check_plan
from planning_factories import plan_request

from planner import Design
from planner.constants import ANSWER_RESERVE_S
from planner.exceptions import InputError, TimingDeadlineError
from planner.geometry import Sphere
from planner.motion import Budget
from planner.planning import CartesianTarget, JointPosture, PlanOptions, plan_with_goal_options
from planner.solver import solve
from planner.timing import JointLimits, TimingOptions
from planner.validity import Margins
from planner.wire import solution_response

DESIGN = Design.default()
START = JointPosture([0.2, 1.0, 2.0], "+")
GOAL = JointPosture([1.0, 1.0, 2.0], "+")
SPHERE = [Sphere([0.623, -0.013, -0.426], 0.08)]  # blocks the straight motion: OMPL searches
MARGINS = Margins(clearance=0.01)


def _checked(solution, goal_wire: dict, obstacles=(), margins=MARGINS, limits=None) -> None:
    request = plan_request(DESIGN, START, goal_wire, margins, obstacles)
    if limits is not None:
        request["limits"] = {
            "velocity": list(limits.velocity),
            "acceleration": list(limits.acceleration),
        }
    answer = solution_response(solution).model_dump(mode="json")
    report = check_plan(request, answer)
    assert report.ok, str(report)


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_one_call_plans_and_times_and_the_checker_agrees(method):
    limits = JointLimits(
        velocity=(1.0, 1.5, 1.5), acceleration=(4.0, 6.0, 6.0), jerk=(100.0, 100.0, 100.0)
    )
    options = PlanOptions(seed=1)
    s = solve(
        DESIGN,
        START,
        GOAL,
        obstacles=SPHERE,
        margins=MARGINS,
        options=options,
        timing=TimingOptions(method=method),
        limits=limits,
    )
    assert s.solved and s.timing_error is None, s.message
    # a real search, not the straight motion: a sampling search, or the corridor's A* when an
    # earlier plan of this process cached its grid (its path then needs no sampling search)
    assert s.plan.diagnostics.planner != "direct" and len(s.path.waypoints) > 2
    assert s.plan.diagnostics.searches >= 1 or s.plan.diagnostics.planner == "corridor"
    traj = s.trajectory
    assert np.allclose(traj.q[0], START.q) and np.allclose(traj.q[-1], GOAL.q)
    assert np.all(np.abs(traj.qd) <= np.asarray(limits.velocity) * (1 + 1e-6))
    # the plan is the planner's own with the same seed: solve adds the timing, nothing else
    alone = plan_with_goal_options(
        DESIGN, START, GOAL, obstacles=SPHERE, margins=MARGINS, options=options
    )
    assert np.array_equal(alone.path.waypoints, s.path.waypoints)
    _checked(s, {"q": GOAL.q.tolist(), "assembly_mode": "+"}, SPHERE, limits=limits)


def test_a_mode_change_comes_to_rest_at_its_transit_when_asked():
    goal = CartesianTarget([0.73924837, -0.01303587, -0.14985306], "+--")
    s = solve(DESIGN, START, goal, options=PlanOptions(seed=1, stop_at_transits=True))
    assert s.solved and s.path.transits, s.message
    q_transit = s.path.waypoints[s.path.transits[0].index]
    k = int(np.argmin(np.linalg.norm(s.trajectory.q - q_transit, axis=1)))
    assert np.linalg.norm(s.trajectory.q[k] - q_transit) < 1e-6
    assert np.linalg.norm(s.trajectory.qd[k]) < 1e-6  # at rest on the transit
    _checked(s, {"p": goal.p.tolist(), "working_mode": "+--"}, margins=Margins())


def test_timing_none_is_the_path_alone():
    s = solve(
        DESIGN, START, GOAL, obstacles=SPHERE, margins=MARGINS, timing=TimingOptions(method="none")
    )
    assert s.plan.solved and s.trajectory is None and s.timing_error is None
    assert solution_response(s).trajectory is None


def test_an_unsolved_plan_is_not_timed():
    far = CartesianTarget([5.0, 0.0, 0.0], "any")
    s = solve(DESIGN, START, far)
    assert s.status.value == "unreachable" and s.trajectory is None and not s.solved


def test_the_deadline_policy_keeps_the_answer_reserve():
    options = PlanOptions(time_budget_s=5.0)
    assert Budget().search_options(options) is options and Budget().search_deadline is None
    soon = Budget.within(1.0)
    cut = soon.search_options(options)
    assert cut.time_budget_s <= 1.0 - ANSWER_RESERVE_S
    assert soon.search_deadline == pytest.approx(soon.deadline - ANSWER_RESERVE_S)
    assert Budget.within(-1.0).search_options(options).time_budget_s == pytest.approx(0.01)
    assert Budget.within(100.0).search_options(options) is options


def test_a_passed_deadline_stops_the_timing_not_the_caller():
    """A deadline already passed: the search gets its floor budget (the straight motion still
    answers), and the timing stops with the deadline error, kept on the solution (the service
    answers ``timeout``)."""
    near = JointPosture([0.3, 1.05, 2.0], "+")
    s = solve(DESIGN, START, near, deadline=time.monotonic() - 1.0)
    assert s.plan.solved and s.trajectory is None
    assert isinstance(s.timing_error, TimingDeadlineError)
    assert solution_response(s).status == "timeout"


def test_a_timing_error_names_its_field_under_timing():
    with pytest.raises(InputError) as err:
        solve(
            DESIGN,
            START,
            GOAL,
            obstacles=SPHERE,
            margins=MARGINS,
            timing=TimingOptions(sample_rate_hz=10_000.0, max_samples=10),
        )
    assert err.value.field_path == ("timing", "sample_rate_hz")


@pytest.mark.parametrize(
    "kwargs, field",
    [({"method": "spline"}, "method"), ({"sample_rate_hz": 0.0}, "sample_rate_hz"),
     ({"max_deviation": -0.1}, "max_deviation"), ({"max_cartesian_speed": 0.0},
      "max_cartesian_speed"), ({"max_samples": 1}, "max_samples")],
)  # fmt: skip
def test_bad_timing_options_name_their_field(kwargs, field):
    with pytest.raises(InputError) as err:
        TimingOptions(**kwargs)
    assert err.value.field == field
