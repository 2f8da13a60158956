"""Proofs with a point-cloud wall: the region map with obstacles reads a cloud of thousands
of points through its tree, so a wall of points that cuts the start off from the goal is
proven (no_path, proven_infeasible, by the plan itself), and the same wall with a window
cut into it (one plate, a window in it) is not, where an independent witness shows the path: the planner's own
certified path, found with the proofs off (``region_map=False``), re-checked here by
dense sampling of the validity checker.

The scene is the plates of tests/analysis/test_obstacle_regions.py (theta1 limited to
[-2, 2]: the loop's plane cannot turn round them) sampled as a depth camera would give them:
points 2 cm apart on the plane z = 0, each a ball of 1.5 cm, no ball big enough to hold a
link alone (the proof needs the bound on the union of the balls)."""

from __future__ import annotations

import numpy as np

from planner.analysis import obstacle_regions as O
from planner.design import Design
from planner.geometry import Points
from planner.kinematics import WORKING_MODES
from planner.planning import JointPosture, PlanOptions, PlanStatus, plan
from planner.validity import Margins, ValidityChecker, densify

LIMITED = Design(0.5, 0.2, 0.6, joint_min=(-2.0, -np.pi, -np.pi), joint_max=(2.0, np.pi, np.pi))
START, GOAL = np.array([1.0, 2.0, 1.0]), np.array([-1.0, 2.0, 1.0])


def _wall_points(window: bool) -> np.ndarray:
    """The plates |x| >= 0.05 m within 1.3 m of the axis as points 2 cm apart; ``window``
    keeps only the plate x > 0 and leaves out its points of 0.05 < x < 0.45, |y| < 0.3 (the
    windowed plate of tests/analysis/test_obstacle_regions.py and benchmarks/planning.py's
    narrow scene)."""
    g = np.arange(-1.3, 1.3 + 1e-9, 0.02)
    x, y = (a.ravel() for a in np.meshgrid(g, g, indexing="ij"))
    keep = (np.abs(x) >= 0.05) & (np.hypot(x, y) <= 1.3)
    if window:
        keep &= (x > 0) & ~((x < 0.45) & (np.abs(y) < 0.3))
    return np.column_stack([x[keep], y[keep], np.zeros(keep.sum())])


def test_a_cloud_wall_is_proven_by_the_plan_and_its_window_is_not():
    wall = [Points(_wall_points(window=False), 0.015)]
    assert len(wall[0].points) > 10_000  # far above the 2,000 rows once the proof's limit
    res = plan(
        LIMITED,
        JointPosture(START, "+"),
        JointPosture(GOAL, "+"),
        obstacles=wall,
        options=PlanOptions(time_budget_s=5.0, seed=1),
    )
    assert res.status is PlanStatus.NO_PATH and res.diagnostics.proven_infeasible, res.message
    assert "region map with obstacles" in res.message

    # the window: pairs across it that the search alone (proofs off) joins by a certified
    # path, checked densely here; the proof must claim none of them
    window = [Points(_wall_points(window=True), 0.015)]
    rng = np.random.default_rng(5)
    solved = 0
    for mode in ("+++", "++-", "+-+", "+--"):
        if solved >= 2:
            break
        chk = ValidityChecker(LIMITED, Margins(), window, "+", mode)
        q = rng.uniform(LIMITED.joint_min, LIMITED.joint_max, (8000, 3))
        ok = chk.is_valid(q)
        for s, g in zip(q[ok & (q[:, 0] > 0.3)][:2], q[ok & (q[:, 0] < -0.3)][:2], strict=False):
            found = plan(
                LIMITED,
                JointPosture(s, "+"),
                JointPosture(g, "+"),
                obstacles=window,
                options=PlanOptions(time_budget_s=1.0, seed=1, region_map=False),
            )
            if not found.solved:
                continue
            solved += 1
            for seg in found.path.segments:  # each in one working mode (transits join them)
                seg_chk = chk.with_mode(seg.working_mode)
                w = found.path.waypoints[seg.start_index : seg.end_index + 1]
                assert seg_chk.is_valid(densify(w, 0.002)).all()
            proof = O.prove_disconnected_with_obstacles(LIMITED, Margins(), window, s, g, "+")
            assert not proof.proven and proof.visited > 0
    assert solved >= 2


def test_the_union_bound_never_blocks_a_valid_posture():
    """Every cell the proof calls blocked holds no valid posture: postures drawn uniformly in
    blocked cells of the cloud wall's grid break a rule in every working mode (the
    checker, an independent route to the clearance)."""
    wall = [Points(_wall_points(window=True), 0.015)]
    n, width = O.LEVELS[0]
    states, theta1, rmap = O.cell_states(LIMITED, Margins(), wall, START, "+", n, width)
    h1 = theta1[1] - theta1[0]
    rng = np.random.default_rng(4)
    blocked = np.argwhere(states == O.BLOCKED)
    assert len(blocked) > 1000
    pick = blocked[rng.choice(len(blocked), 4000)]
    lo = np.asarray(LIMITED.joint_min)
    q = np.column_stack(
        [
            theta1[pick[:, 0]] + h1 * rng.uniform(-0.5, 0.5, len(pick)),
            lo[1] + rmap.h2 * (pick[:, 2] + rng.uniform(0, 1, len(pick))),
            lo[2] + rmap.h3 * (pick[:, 1] + rng.uniform(0, 1, len(pick))),
        ]
    )
    for mode in WORKING_MODES:
        assert not ValidityChecker(LIMITED, Margins(), wall, "+", mode).is_valid(q).any()
