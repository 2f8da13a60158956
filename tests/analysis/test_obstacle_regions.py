"""The region map with obstacles (:mod:`planner.analysis.obstacle_regions`) against
independent routes: the point sets hold P and the distal midpoints of every posture in the
kappa band (forward kinematics and closed-form C, D); a blocked proximal cell holds no
posture whose link clears a sphere (closed-form point-segment distance in numpy); every
posture of a blocked cell breaks a rule (the validity checker, every working mode); a wall is
proven, its windowed twin is not; and no proof is ever claimed for a start and goal that a
found path joins (seeded scenes, single-mode and mode-change queries).
"""

from __future__ import annotations

import numpy as np
import pytest
from planning_factories import seeded_scene

from planner.analysis import obstacle_regions as O
from planner.analysis import regions as R
from planner.analysis.apex_bounds import point_sets
from planner.design import Design
from planner.geometry import Box, Capsule, Sphere
from planner.kinematics import WORKING_MODES, forward_batch
from planner.planning import JointPosture, PlanOptions, PlanStatus, plan
from planner.validity import Margins, ValidityChecker

DESIGNS = [
    Design.default(),
    Design.paper_optimum(),
    Design(0.3, 0.3, 0.4),
    Design(0.6, 0.25, 0.45),
]
#: theta1 limited to [-2, 2]: the plane cannot turn round the plates below
LIMITED = Design(0.5, 0.2, 0.6, joint_min=(-2.0, -np.pi, -np.pi), joint_max=(2.0, np.pi, np.pi))
_X0, _X1, _Y1, _T = 0.05, 1.3, 1.3, 0.02
#: plates at z = 0 on both sides of the axis: at theta1 = 0 every link point farther than
#: 0.05 m from the axis is in a plate, and P never comes that close
WALL = [
    Box([(_X0 + _X1) / 2, 0.0, 0.0], [_X1 - _X0, 2 * _Y1, _T]),
    Box([-(_X0 + _X1) / 2, 0.0, 0.0], [_X1 - _X0, 2 * _Y1, _T]),
]
#: the plate of benchmarks/planning.py's narrow scene: one side, with a window
_HX, _HY = 0.45, 0.3
WINDOW = [
    Box([(_X0 + _X1) / 2, -(_HY + _Y1) / 2, 0.0], [_X1 - _X0, _Y1 - _HY, _T]),
    Box([(_X0 + _X1) / 2, (_HY + _Y1) / 2, 0.0], [_X1 - _X0, _Y1 - _HY, _T]),
    Box([(_HX + _X1) / 2, 0.0, 0.0], [_X1 - _HX, 2 * _HY, _T]),
]


def _in_cells(rmap: R.RegionMap, k3: np.ndarray, k2: np.ndarray, rng) -> np.ndarray:
    """One uniform (theta2, theta3) in each closed cell (k3, k2)."""
    lo = np.asarray(rmap.design.joint_min)
    t2 = lo[1] + rmap.h2 * (k2 + rng.uniform(0.0, 1.0, len(k2)))
    t3 = lo[2] + rmap.h3 * (k3 + rng.uniform(0.0, 1.0, len(k3)))
    return np.stack([t2, t3], axis=1)


@pytest.mark.parametrize("design", DESIGNS, ids=lambda d: f"{d.L0}/{d.L1}/{d.L2}")
@pytest.mark.parametrize("asm", ["+", "-"])
def test_point_sets_hold_p_and_the_distal_midpoints(design: Design, asm: str) -> None:
    margins = Margins()
    rmap = R.region_map(design, margins, 32)
    sets = point_sets(design, margins, rmap, asm)
    rng = np.random.default_rng(4)
    k3, k2 = np.nonzero(np.isfinite(sets[..., 0, 0]))
    pick = rng.integers(len(k3), size=6000)
    k3, k2 = k3[pick], k2[pick]
    t = _in_cells(rmap, k3, k2, rng)
    q = np.stack([np.zeros(len(t)), t[:, 0], t[:, 1]], axis=1)
    L0, L1, L2 = design.L0, design.L1, design.L2
    c = np.stack([-L0 / 2 + L1 * np.cos(t[:, 0]), L1 * np.sin(t[:, 0])], axis=1)
    d = np.stack([L0 / 2 + L1 * np.cos(t[:, 1]), L1 * np.sin(t[:, 1])], axis=1)
    lo, hi = margins.cd_range
    cd = np.linalg.norm(d - c, axis=1) / (2 * L2)
    band = (cd >= lo) & (cd <= hi)
    fb = forward_batch(design, q, asm)
    assert band.sum() > 3000 and np.all(fb.ok[band])
    p = np.stack([fb.p[:, 1], fb.p[:, 0]], axis=1)  # theta1 = 0: P = (w, u, 0)
    for m, point in enumerate((p, (c + p) / 2, (d + p) / 2)):
        box = sets[k3, k2, m][band]
        u, w = point[band, 0], point[band, 1]
        eps = 1e-12
        assert np.all((box[:, 0] - eps <= u) & (u <= box[:, 1] + eps)), m
        assert np.all((box[:, 2] - eps <= w) & (w <= box[:, 3] + eps)), m
    # the bound is useful: a cell of 32 x 32 keeps P within a fraction of the reach
    width = np.maximum(sets[..., 0, 1] - sets[..., 0, 0], sets[..., 0, 3] - sets[..., 0, 2])
    assert np.nanmedian(width) < 0.6 * (L1 + L2)


def _link_sphere_distance(a: np.ndarray, b: np.ndarray, centre: np.ndarray, r: float):
    """Closed-form distance from segments a-b (N, 3) to a sphere."""
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", centre - a, ab) / np.einsum("ij,ij->i", ab, ab), 0, 1)
    return np.linalg.norm(a + t[:, None] * ab - centre, axis=1) - r


def test_blocked_proximal_cells_hold_no_link_clear_of_the_spheres() -> None:
    design, margins = LIMITED, Margins()
    rng = np.random.default_rng(9)
    spheres = [Sphere(rng.uniform(-0.3, 0.3, 3), rng.uniform(0.04, 0.12)) for _ in range(8)]
    rmap = R.region_map(design, margins, 32)
    theta1, h1 = O.theta1_grid(design, 0.08)
    blocked_a, blocked_b = O.proximal_tables(design, margins, spheres, theta1, h1, rmap)
    limit = design.link_radius + margins.clearance
    for table, theta, h, base in (
        (blocked_a, rmap.theta2, rmap.h2, -design.L0 / 2),
        (blocked_b, rmap.theta3, rmap.h3, design.L0 / 2),
    ):
        assert 0.02 < table.mean() < 0.9  # the scene blocks some cells, not all
        i, k = np.nonzero(table)
        i, k = np.repeat(i, 8), np.repeat(k, 8)
        t1 = theta1[i] + h1 * rng.uniform(-0.5, 0.5, len(i))
        tk = theta[k] + h * rng.uniform(-0.5, 0.5, len(k))
        eu, ew = base + design.L1 * np.cos(tk), design.L1 * np.sin(tk)
        a = np.tile([0.0, base, 0.0], (len(i), 1))
        b = np.stack([ew * np.cos(t1), eu, -ew * np.sin(t1)], axis=1)
        dist = np.min(
            [_link_sphere_distance(a, b, np.asarray(s.center), s.radius) for s in spheres], axis=0
        )
        assert np.all(dist < limit)
        # and the cells left open do hold links clear of every sphere (not all blocked)
        assert (~table).sum() > 0


def _sample_cells(states, theta1, h1, rmap, code, per_cell, rng):
    i, k3, k2 = np.nonzero(states == code)
    pick = rng.permutation(len(i))[:400]
    i, k3, k2 = (np.repeat(x[pick], per_cell) for x in (i, k3, k2))
    t = _in_cells(rmap, k3, k2, rng)
    t1 = theta1[i] + h1 * rng.uniform(-0.5, 0.5, len(i))
    return np.stack([t1, t[:, 0], t[:, 1]], axis=1)


@pytest.mark.parametrize(
    "obstacles",
    [WALL, WINDOW, [Sphere([0.1, 0.0, 0.5], 0.25), Capsule([0.4, -1, 0], [0.4, 1, 0], 0.05)]],
    ids=["wall", "window", "sphere-capsule"],
)
def test_every_posture_of_a_blocked_cell_breaks_a_rule(obstacles) -> None:
    design, margins = LIMITED, Margins()
    start = np.array([1.0, 2.0, 1.0])
    theta1, h1 = O.theta1_grid(design, 0.08)
    states, theta1, rmap = O.cell_states(design, margins, obstacles, start, "+", 32, 0.08)
    assert (states == O.BLOCKED).sum() > 100 and (states == O.PASSABLE).sum() > 100
    rng = np.random.default_rng(2)
    q = _sample_cells(states, theta1, h1, rmap, O.BLOCKED, 6, rng)
    for mode in WORKING_MODES:
        assert not ValidityChecker(design, margins, obstacles, "+", mode).is_valid(q).any()


def test_a_wall_is_proven_and_its_window_is_not() -> None:
    design, margins = LIMITED, Margins()
    start, goal = np.array([1.0, 2.0, 1.0]), np.array([-1.0, 2.0, 1.0])
    wall = O.prove_disconnected_with_obstacles(design, margins, WALL, start, goal, "+")
    assert wall.proven and wall.visited > 0
    # the window lets the arm through (benchmarks/planning.py plans through it): never proven
    rng = np.random.default_rng(5)
    solved = 0
    for mode in ("+-+", "++-", "+++", "+--"):
        chk = ValidityChecker(design, margins, WINDOW, "+", mode)
        q = rng.uniform(design.joint_min, design.joint_max, (8000, 3))
        ok = chk.is_valid(q)
        for s, g in zip(q[ok & (q[:, 0] > 0.3)][:3], q[ok & (q[:, 0] < -0.3)][:3], strict=False):
            if solved >= 4:
                break
            res = plan(
                design,
                JointPosture(s, "+"),
                JointPosture(g, "+"),
                obstacles=WINDOW,
                options=PlanOptions(time_budget_s=0.5, seed=1, region_map=False),
            )
            proof = O.prove_disconnected_with_obstacles(design, margins, WINDOW, s, g, "+")
            if res.solved:
                solved += 1
                assert not proof.proven
    assert solved >= 4


def test_no_false_proof_for_queries_a_found_path_joins() -> None:
    """Seeded scenes (four designs, theta1 limited or not, 2-6 spheres and plates), start
    and goal in one assembly mode, the goal in any working mode (mode changes included):
    whenever the search alone finds a path, the 3-D grid must not claim a proof."""
    rng = np.random.default_rng(17)
    solved = changed = 0
    for trial in range(64):
        base = DESIGNS[trial % len(DESIGNS)]
        design = (
            base
            if trial % 2
            else Design(
                base.L0,
                base.L1,
                base.L2,
                joint_min=(-2.0, -np.pi, -np.pi),
                joint_max=(2.0, np.pi, np.pi),
            )
        )
        obstacles = seeded_scene(rng)
        asm = "+" if trial % 3 else "-"
        q = rng.uniform(design.joint_min, design.joint_max, (4000, 3))
        valid = {}
        for mode in WORKING_MODES:
            ok = ValidityChecker(design, Margins(), obstacles, asm, mode).is_valid(q)
            if ok.sum() >= 2:
                valid[mode] = q[ok]
        if not valid:
            continue
        modes = sorted(valid)
        m0 = modes[rng.integers(len(modes))]
        m1 = m0 if trial % 2 or len(modes) == 1 else modes[rng.integers(len(modes))]
        start = valid[m0][rng.integers(len(valid[m0]))]
        goal = valid[m1][rng.integers(len(valid[m1]))]
        res = plan(
            design,
            JointPosture(start, asm),
            JointPosture(goal, asm),
            obstacles=obstacles,
            options=PlanOptions(time_budget_s=0.5, seed=trial + 1, region_map=False),
        )
        if res.status is not PlanStatus.SOLVED:
            continue
        solved += 1
        changed += bool(res.path.transits)
        proof = O.prove_disconnected_with_obstacles(design, Margins(), obstacles, start, goal, asm)
        assert not proof.proven, (trial, design, obstacles, start, goal)
    # the count depends on the machine (a time-bounded search solves less under load); the
    # property is the assertion above, these bounds only keep it from passing vacuously
    assert solved >= 24 and changed >= 3, (solved, changed)
