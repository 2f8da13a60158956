"""Single-mode planning: solved scenes checked by the independent checker (tests/plan_checker.py),
clean failures (no path, invalid start/goal, unreachable), seeds, planners, wire fields."""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import pytest
from planning_factories import check_library_plan, plan_answer

from planner.design import Design
from planner.exceptions import InputError
from planner.geometry import Box, Sphere
from planner.kinematics import forward_batch
from planner.planning import (
    PLANNERS,
    CartesianTarget,
    JointPosture,
    PlanOptions,
    PlanStatus,
    plan,
)
from planner.validity import Margins

DESIGN = Design.default()
START = JointPosture([0.0, 2.0, 1.0], "+")  # working mode +-+
# a sphere on the straight motion to GOAL: the direct motion is blocked
BLOCKER = [Sphere([0.549, -0.025, -0.376], 0.1)]
GOAL = JointPosture([1.2, 2.3, 1.3], "+")


def _goal_wire(goal):
    if isinstance(goal, JointPosture):
        return {"q": goal.q.tolist(), "assembly_mode": goal.assembly_mode}
    return {"p": goal.p.tolist(), "working_mode": goal.working_mode}


def test_blocker_blocks_the_direct_motion():
    from planner.validity import ValidityChecker

    chk = ValidityChecker(DESIGN, Margins(), BLOCKER, "+", "+-+")
    assert chk.check_states(np.stack([START.q, GOAL.q])).valid.all()
    assert not chk.check_motion(START.q, GOAL.q).valid


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_solved_paths_pass_the_independent_check(seed):
    margins = Margins()
    res = plan(
        DESIGN,
        START,
        GOAL,
        obstacles=BLOCKER,
        margins=margins,
        options=PlanOptions(seed=seed, time_budget_s=2.0),
    )
    assert res.status is PlanStatus.SOLVED, res.message
    w = res.path.waypoints
    assert len(w) > 2 and np.array_equal(w[0], START.q) and np.array_equal(w[-1], GOAL.q)
    seg = res.path.segments
    assert [(s.working_mode, s.assembly_mode, s.start_index, s.end_index) for s in seg] == [
        ("+-+", "+", 0, len(w) - 1)
    ]
    assert res.path.transits == ()
    d = res.diagnostics
    assert d.min_clearance >= margins.clearance and d.max_kappa_A <= margins.kappa_max
    assert d.min_serial_margin >= margins.serial_min
    assert d.path_length == pytest.approx(np.linalg.norm(np.diff(w, axis=0), axis=1).sum())
    report = check_library_plan(DESIGN, START, _goal_wire(GOAL), margins, BLOCKER, plan_answer(res))
    assert report.ok, report


def test_seed_reproduces_the_path():
    opts = PlanOptions(seed=5, simplify=False)
    a = plan(DESIGN, START, GOAL, obstacles=BLOCKER, options=opts)
    b = plan(DESIGN, START, GOAL, obstacles=BLOCKER, options=opts)
    assert a.solved and b.solved
    np.testing.assert_array_equal(a.path.waypoints, b.path.waypoints)


@pytest.mark.parametrize("name", PLANNERS)
def test_every_planner_solves_a_blocked_query(name):
    res = plan(
        DESIGN, START, GOAL, obstacles=BLOCKER, options=PlanOptions(name=name, time_budget_s=1.0)
    )
    assert res.status is PlanStatus.SOLVED, (name, res.message)
    assert res.diagnostics.planner == name
    report = check_library_plan(
        DESIGN, START, _goal_wire(GOAL), Margins(), BLOCKER, plan_answer(res)
    )
    assert report.ok, report


def test_free_space_takes_the_straight_motion():
    res = plan(DESIGN, START, JointPosture([0.5, 2.2, 1.1], "+"))
    assert res.solved and res.diagnostics.planner == "direct" and len(res.path.waypoints) == 2


WALL_DESIGN = Design(0.5, 0.2, 0.6, joint_min=(-2.0, -np.pi, -np.pi), joint_max=(2.0, np.pi, np.pi))
#: a plate at z = 0 for x >= 0.05: in a mode with w > 0 the arm cannot pass theta1 = 0 (every
#: link would need to stay within 0.02 m of the axis while |w| >= serial_min (L1 + L2) = 0.04
#: m), and this design's P never reaches the axis (no transit to the modes with w < 0)
WALL = [Box([0.65, 0.0, 0.0], [1.2, 3.0, 0.02])]
WALL_START = JointPosture([1.0, 2.0, 1.0], "+")
WALL_GOAL = JointPosture([-1.0, 2.0, 1.0], "+")


def test_wall_gives_no_path_within_budget(monkeypatch):
    """Without the region map the search runs its whole budget and says so.

    Observed on the search's side (a spy on :func:`planner.planning.compiled_rrt.search`, on the
    library's own clock ``time.monotonic``): the searches run, each for all the time it was
    given, from the first start to the last end over at least half the budget, and together
    never given more than the budget. Only lower bounds on elapsed time, which a slow machine
    cannot break. Mutants caught: ``planner.solve(min(time_budget_s, 0.001))`` in
    ``ompl_backend.search`` (when it was the search), a deadline cut short in
    ``compiled_rrt.rrt_connect``, and ``min(budget, 0.001)`` handed to its calls in
    ``single_mode.plan_in_region``; the old test (the message and an upper bound on the time)
    passed both.
    """
    from planner.planning import compiled_rrt

    searches = []  # (seconds given, start, end) of every search (compiled or OMPL)
    search = compiled_rrt.search

    def spy(checker, q_start, q_goal, options, time_budget_s, **kwargs):
        start = time.monotonic()
        outcome = search(checker, q_start, q_goal, options, time_budget_s, **kwargs)
        searches.append((time_budget_s, start, time.monotonic()))
        return outcome

    budget = 0.3

    def plan_wall(time_budget_s):
        options = PlanOptions(time_budget_s=time_budget_s, region_map=False)
        return plan(WALL_DESIGN, WALL_START, WALL_GOAL, obstacles=WALL, options=options)

    # a first call in a process compiles the checker's kernels inside its budget (tens of
    # seconds with a cold numba cache, no time left to search): a short one pays that first
    plan_wall(0.05)
    monkeypatch.setattr(compiled_rrt, "search", spy)
    res = plan_wall(budget)
    assert res.status is PlanStatus.NO_PATH and res.path is None
    assert "no path" in res.message and not res.diagnostics.proven_infeasible
    assert f"within {budget} s" in res.message  # the search ran on the budget it was given
    assert searches and res.diagnostics.searches == len(searches)
    for given, start, end in searches:  # the search ran out every budget it was handed
        assert end - start >= 0.9 * given, (given, end - start)
    assert searches[-1][2] - searches[0][1] >= 0.5 * budget, searches
    assert sum(given for given, _, _ in searches) <= budget  # and never more than the budget


def test_wall_is_proven_by_the_region_map_with_obstacles():
    """With the map the first search slice finds nothing, and the 3-D grid proves the wall:
    ``no_path`` with ``proven_infeasible``, at most the first try searched (none when this
    scene's corridor grid is cached already and tried first), the grid named."""
    res = plan(
        WALL_DESIGN, WALL_START, WALL_GOAL, obstacles=WALL, options=PlanOptions(time_budget_s=5.0)
    )
    assert res.status is PlanStatus.NO_PATH and res.path is None
    assert res.diagnostics.proven_infeasible and res.diagnostics.planner == "region_map"
    assert res.diagnostics.searches <= 1
    assert res.message.startswith("no valid path exists (proven by the region map with obstacles")
    assert "cells over (theta1, theta3, theta2)" in res.message


def test_invalid_start_and_goal_name_rule_and_value():
    res = plan(DESIGN, START, GOAL, obstacles=[Sphere([0.0, 0.0, 0.0], 0.3)])
    assert res.status is PlanStatus.INVALID_START
    assert res.message.startswith("start clearance:") and " m < margins.clearance" in res.message
    lim = Design(0.5, 0.2, 0.6, joint_min=(-1, -np.pi, -np.pi), joint_max=(1, np.pi, np.pi))
    res = plan(lim, START, JointPosture([1.2, 2.3, 1.3], "+"))
    assert res.status is PlanStatus.INVALID_GOAL
    assert "joint_limits: q[0] = 1.2 rad" in res.message
    res = plan(DESIGN, START, GOAL, margins=Margins(kappa_max=1.05))
    assert res.status is PlanStatus.INVALID_START and "kappa_max: kappa_A = " in res.message
    fb = forward_batch(DESIGN, START.q, "+")
    serial = float(np.min(np.abs(fb.serial_measures[0])))
    res = plan(DESIGN, START, GOAL, margins=Margins(serial_min=min(0.99, serial + 0.05)))
    assert res.status is PlanStatus.INVALID_START
    assert f"serial measure {serial:.6g}" in res.message


def test_other_mode_or_assembly_is_unreachable_for_a_single_mode_plan():
    from planner.kinematics import WORKING_MODES, inverse_batch
    from planner.planning.single_mode import plan_single_mode  # plan() changes mode

    ik = inverse_batch(DESIGN, forward_batch(DESIGN, START.q, "+").p)
    slot = WORKING_MODES.index("++-")
    assert ik.ok[0, slot] and ik.assembly_mode_signs[0, slot] == 1
    res = plan_single_mode(DESIGN, START, JointPosture(ik.q[0, slot], "+"))  # another mode
    assert res.status is PlanStatus.UNREACHABLE and "working mode ++-" in res.message
    res = plan(DESIGN, START, JointPosture(START.q, "-"))
    assert res.status is PlanStatus.UNREACHABLE and "assembly mode" in res.message
    res = plan(DESIGN, START, CartesianTarget([3.0, 0.0, 0.0], "any"))
    assert res.status is PlanStatus.UNREACHABLE and "out of reach" in res.message


def test_cartesian_goal_any_mode():
    q_goal = np.array([0.8, 2.3, 1.2])
    p = forward_batch(DESIGN, q_goal, "+").p[0]
    target = CartesianTarget(p, "any")
    res = plan(DESIGN, START, target, obstacles=BLOCKER)
    assert res.solved, res.message
    end = forward_batch(DESIGN, res.path.waypoints[-1], "+").p[0]
    np.testing.assert_allclose(end, p, atol=1e-9)
    report = check_library_plan(
        DESIGN, START, _goal_wire(target), Margins(), BLOCKER, plan_answer(res)
    )
    assert report.ok, report


def test_wire_fields():
    res = plan(DESIGN, START, GOAL, obstacles=BLOCKER)
    wire = plan_answer(res)
    assert wire["status"] == "solved"
    assert set(wire["path"]) == {"waypoints", "segments", "transits"}
    assert set(wire["path"]["segments"][0]) == {
        "working_mode",
        "assembly_mode",
        "start_index",
        "end_index",
    }
    assert {
        "planning_time_s",
        "min_clearance",
        "max_kappa_A",
        "min_serial_margin",
        "path_length",
    } <= set(wire["diagnostics"])
    assert {s.value for s in PlanStatus} == {
        "solved",
        "no_path",
        "unreachable",
        "invalid_start",
        "invalid_goal",
        "timeout",
    }


@pytest.mark.parametrize(
    "kwargs", [dict(name="kpiece"), dict(time_budget_s=0), dict(seed=0), dict(range=-1.0)]
)
def test_bad_options(kwargs):
    with pytest.raises(InputError, match=r"planner\."):
        PlanOptions(**kwargs)


def test_no_leak_warnings_or_ompl_output():
    code = (
        "import numpy as np\n"
        "from planner.design import Design\n"
        "from planner.geometry import Sphere\n"
        "from planner.planning import plan, JointPosture, PlanOptions\n"
        "for name in ('rrtconnect', 'aorrtc'):\n"
        "    r = plan(Design.default(), JointPosture([0.0, 2.0, 1.0]), JointPosture([1.2, 2.3, 1.3]),\n"
        "             obstacles=[Sphere([0.549, -0.025, -0.376], 0.1)], options=PlanOptions(name=name))\n"
        "    assert r.solved\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "leaked" not in proc.stderr and proc.stdout == "" and proc.stderr == ""


def test_plan_in_region_with_goal_candidates():
    """The building block of plan(): a checker, a start and goal candidates; its path passes
    the independent check."""
    from planner.planning import plan_in_region
    from planner.validity import ValidityChecker

    chk = ValidityChecker(DESIGN, Margins(), BLOCKER, "+", "+-+")
    res = plan_in_region(chk, START.q, np.stack([GOAL.q]), options=PlanOptions(seed=3))
    assert res.solved and res.diagnostics.attempts == 1
    report = check_library_plan(
        DESIGN, START, _goal_wire(GOAL), Margins(), BLOCKER, plan_answer(res)
    )
    assert report.ok, report


def test_start_that_does_not_assemble_names_the_measured_cd():
    """|CD| for q = (0, pi, 0) on (0.5, 0.2, 0.6) is L0 + 2 L1 = 0.9 m, and 2 L2 = 1.2 m: it
    assembles; with L2 = 0.4 (2 L2 = 0.8 m) it does not, and the message gives 0.9 m."""
    design = Design(0.5, 0.2, 0.4)
    res = plan(design, JointPosture([0.0, np.pi, 0.0], "+"), JointPosture([0.1, 2.0, 1.0], "+"))
    assert res.status is PlanStatus.INVALID_START
    assert "assembly" in res.message and "|CD| = 0.9 m > 2 L2 = 0.8 m" in res.message
