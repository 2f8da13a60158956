"""A goal with a tolerance in the library (:mod:`planner.planning.tolerance`): the set is
searched as a set, a proof is claimed only when it covers every goal the request allows, and
where it does, it is still claimed.

Independent routes: the end of a plan is checked by forward kinematics against the ball; a
false proof by a path that the search alone (``region_map=False``) found to a goal inside the
ball; the scenes that must be proven are cut by joint limits (the box of a map region) or by
a wall of plates that the arm cannot pass (tests/analysis/test_obstacle_regions.py).
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from planning_factories import CUT, cut_ends, seeded_scene

from planner.design import Design
from planner.geometry import Box, Sphere
from planner.kinematics import WORKING_MODES, forward_batch
from planner.planning import (
    CartesianTarget,
    JointPosture,
    PlanOptions,
    PlanStatus,
    plan,
    plan_with_goal_options,
)
from planner.planning.proofs import PROOF_RESOLUTION
from planner.planning.tolerance import goal_ball, prove_goal_set, sample_goal_set
from planner.validity import Margins, ValidityChecker

#: theta1 within [-2, 2] and plates at z = 0 on both sides of the axis: the plane cannot turn
#: from theta1 > 0 to theta1 < 0 (tests/analysis/test_obstacle_regions.py)
LIMITED = Design(0.5, 0.2, 0.6, joint_min=(-2.0, -np.pi, -np.pi), joint_max=(2.0, np.pi, np.pi))
WALL = [
    Box([(0.05 + 1.3) / 2, 0.0, 0.0], [1.3 - 0.05, 2.6, 0.02]),
    Box([-(0.05 + 1.3) / 2, 0.0, 0.0], [1.3 - 0.05, 2.6, 0.02]),
]


def _mode(design: Design, q: np.ndarray, asm: str) -> str:
    signs = forward_batch(design, q, asm).working_mode_signs[0]
    return "".join("+" if s > 0 else "-" for s in signs)


def test_a_joint_goal_cut_off_with_its_whole_tolerance_is_proven_and_a_wider_one_is_not():
    start, goal = cut_ends(PROOF_RESOLUTION)
    options = PlanOptions(time_budget_s=2.0, seed=3)
    s, g = JointPosture(start, "-"), JointPosture(goal, "-")
    small = plan_with_goal_options(CUT, s, g, options=options, tolerance=0.02)
    assert small.status is PlanStatus.NO_PATH and small.diagnostics.proven_infeasible
    assert "any goal within goal.tolerance = 0.02 rad of goal.q" in small.message
    assert small.diagnostics.searches == 0  # the map answered, no search ran
    # a tolerance that reaches back into the start's component: solved, the end inside it
    wide = float(np.linalg.norm(goal - start)) + 0.05
    near = plan_with_goal_options(CUT, s, g, options=options, tolerance=wide)
    assert near.solved and not near.diagnostics.proven_infeasible, near.message
    assert np.linalg.norm(near.path.waypoints[-1] - goal) <= wide
    assert f"within goal.tolerance = {wide:g} rad" in near.message


def test_a_point_behind_a_wall_is_proven_over_its_whole_tolerance():
    """The wall of plates cuts theta1 > 0 from theta1 < 0: a Cartesian goal on the other side
    with a 2 cm tolerance (every goal of the ball on that side) is proven by the 3-D map."""
    start = JointPosture([1.0, 2.0, 1.0], "+")
    p = forward_batch(LIMITED, np.array([-1.0, 2.0, 1.0]), "+").p[0]
    options = PlanOptions(time_budget_s=2.0, seed=1)
    for mode in ("any", _mode(LIMITED, np.array([-1.0, 2.0, 1.0]), "+")):
        res = plan_with_goal_options(
            LIMITED,
            start,
            CartesianTarget(p, mode),
            obstacles=WALL,
            options=options,
            tolerance=0.02,
        )
        assert res.status is PlanStatus.NO_PATH and res.diagnostics.proven_infeasible, res.message
        assert "within goal.tolerance = 0.02 m of goal.p" in res.message
        assert "region map with obstacles" in res.message


def test_the_exact_point_s_proof_is_not_the_ball_s():
    """Behind the wall, a ball that reaches back across the plate holds goals on the start's
    side: the exact point is proven apart, the ball is not, and the plan ends in the ball."""
    start = JointPosture([1.0, 2.0, 1.0], "+")
    p = forward_batch(LIMITED, np.array([-1.0, 2.0, 1.0]), "+").p[0]
    p_start = forward_batch(LIMITED, start.q, "+").p[0]
    tolerance = float(np.linalg.norm(p - p_start)) + 0.01  # the start's own P is in the ball
    goal = CartesianTarget(p, "any")
    options = PlanOptions(time_budget_s=2.0, seed=1)
    exact = plan(LIMITED, start, goal, obstacles=WALL, options=options)
    assert exact.diagnostics.proven_infeasible, exact.message
    ball = goal_ball(goal, tolerance)
    assert prove_goal_set(LIMITED, start, ball, obstacles=WALL, options=options) is None
    res = plan_with_goal_options(
        LIMITED, start, goal, obstacles=WALL, options=options, tolerance=tolerance
    )
    assert res.solved and not res.diagnostics.proven_infeasible, res.message
    end = forward_batch(LIMITED, res.path.waypoints[-1], "+").p[0]
    assert np.linalg.norm(end - p) <= tolerance


def test_a_blocked_exact_goal_finds_a_valid_one_in_the_set():
    """A sphere swallows the exact goal's P (every posture there collides: invalid_goal);
    the set search finds a goal within the tolerance, outside the sphere."""
    design = Design.default()
    start = JointPosture([-0.2187, 2.8609, 0.2807], "+")
    p = np.array([0.3, 0.1, -0.5])
    sphere = [Sphere(p, 0.06)]
    options = PlanOptions(time_budget_s=1.0, seed=1)
    goal = CartesianTarget(p, "any")
    assert plan(design, start, goal, obstacles=sphere, options=options).status in (
        PlanStatus.INVALID_GOAL,
        PlanStatus.UNREACHABLE,
    )
    goals = sample_goal_set(design, start, goal, 0.15, obstacles=sphere)
    assert goals.count > 0
    for mode, q in goals.targets.items():  # valid, in their mode, inside the ball
        assert ValidityChecker(design, Margins(), sphere, "+", mode).is_valid(q).all()
        assert np.all(np.linalg.norm(forward_batch(design, q, "+").p - p, axis=1) <= 0.15)
    res = plan_with_goal_options(
        design, start, goal, obstacles=sphere, options=options, tolerance=0.15
    )
    assert res.solved, res.message
    end = forward_batch(design, res.path.waypoints[-1], "+").p[0]
    assert 0.06 + design.link_radius < np.linalg.norm(end - p) <= 0.15


@pytest.mark.parametrize("part", range(2))
def test_no_proof_over_a_ball_that_holds_a_goal_the_search_reaches(part):
    """Seeded scenes (two designs, theta1 limited or not, spheres and boxes): a goal the
    search alone reaches (mode changes included) lies inside a ball (point or joint, the
    ball's centre off the goal); neither the proof over the ball nor the planner with the
    tolerance and ``prefer`` may claim that no path exists."""
    rng = np.random.default_rng(40 + part)
    found = 0
    for trial in range(12):
        base = (Design.default(), Design(0.3, 0.3, 0.4))[trial % 2]
        design = (
            base
            if (trial // 2) % 2
            else Design(
                base.L0,
                base.L1,
                base.L2,
                joint_min=(-2.0, -np.pi, -np.pi),
                joint_max=(2.0, np.pi, np.pi),
            )
        )
        obstacles = seeded_scene(rng, most=5)
        asm = "+-"[trial % 2]
        q = rng.uniform(design.joint_min, design.joint_max, (3000, 3))
        valid = {}
        for mode in WORKING_MODES:
            ok = ValidityChecker(design, Margins(), obstacles, asm, mode).is_valid(q)
            if ok.sum():
                valid[mode] = q[ok]
        if len(valid) < 1:
            continue
        modes = sorted(valid)
        m0, m1 = modes[rng.integers(len(modes))], modes[rng.integers(len(modes))]
        start = JointPosture(valid[m0][rng.integers(len(valid[m0]))], asm)
        g = valid[m1][rng.integers(len(valid[m1]))]
        off = PlanOptions(time_budget_s=0.3, seed=trial + 1, region_map=False)
        if not plan(design, start, JointPosture(g, asm), obstacles=obstacles, options=off).solved:
            continue
        found += 1
        radius = float(rng.uniform(0.01, 0.2))
        shift = rng.normal(size=3)
        shift *= rng.uniform(0, radius) / np.linalg.norm(shift)
        if trial % 3:
            goal = CartesianTarget(forward_batch(design, g, asm).p[0] + shift, "any")
            prefer = "best_conditioned"
        else:
            goal, prefer = JointPosture(g + shift, asm), "shortest"
        on = PlanOptions(time_budget_s=0.3, seed=trial + 1)
        ball = goal_ball(goal, radius)
        assert prove_goal_set(design, start, ball, obstacles=obstacles, options=on) is None
        res = plan_with_goal_options(
            design, start, goal, obstacles=obstacles, options=on, prefer=prefer, tolerance=radius
        )
        assert not res.diagnostics.proven_infeasible, (trial, res.message)
    assert found >= 5


def test_an_unreachable_message_names_each_working_mode_once():
    """A point no mode reaches (a sphere swallows it): the answer says why per working mode,
    each of the eight named once (it once read "in -++ in working mode -++")."""
    design = Design.default()
    res = plan(
        design,
        JointPosture([0.0, 2.0, 1.0], "+"),
        CartesianTarget([0.3, 0.1, -0.5]),
        obstacles=[Sphere([0.3, 0.1, -0.5], 0.1)],
    )
    assert res.status is PlanStatus.UNREACHABLE
    for mode in WORKING_MODES:
        assert len(re.findall(rf"(?<![+-]){re.escape(mode)}(?![+-])", res.message)) == 1, mode
