"""The goal cells of a tolerance ball (:mod:`planner.analysis.goal_cells`) against independent
routes: every valid posture whose P (forward kinematics) lies in a point ball, or whose q lies
in a joint ball, sits in a kept 2-D cell of its working mode and in a kept 3-D cell; the sets
are useful (a small ball keeps a small share of the cells); and the 2-D proof over a ball
never separates a start from a ball that holds a posture of the start's own 4-connected
component on a dense grid of valid postures (the validity checker alone, steps of half a map
cell), over 600 seeded queries."""

from __future__ import annotations

import numpy as np
import pytest
from planning_factories import dense_grid_components

from planner.analysis import obstacle_regions as O
from planner.analysis import regions as R
from planner.analysis.goal_cells import GoalBall, grid_cells, plane_cells, prove_ball_disconnected
from planner.design import Design
from planner.exceptions import InputError
from planner.kinematics import WORKING_MODES, forward_batch
from planner.planning.proofs import PROOF_RESOLUTION
from planner.validity import Margins, ValidityChecker

DESIGNS = [
    Design.default(),
    Design.paper_optimum(),
    Design(0.3, 0.3, 0.4, joint_min=(-1.0, -2.0, -1.5), joint_max=(1.0, 2.5, 3.0)),
]


def _valid_postures(design: Design, margins: Margins, asm: str, rng, n: int = 20000):
    """Random valid postures (M, 3) and their working modes (M,)."""
    q = rng.uniform(design.joint_min, design.joint_max, (n, 3))
    qs, modes = [], []
    for mode in WORKING_MODES:
        ok = ValidityChecker(design, margins, (), asm, mode).is_valid(q)
        qs.append(q[ok])
        modes += [mode] * int(ok.sum())
    return np.vstack(qs), np.array(modes)


@pytest.mark.parametrize("design", DESIGNS, ids=["default", "paper", "limited"])
@pytest.mark.parametrize("kind", ["point", "joint"])
def test_every_posture_in_the_ball_lies_in_a_kept_cell(design: Design, kind: str) -> None:
    margins, asm = Margins(), "+"
    rng = np.random.default_rng(11)
    q, modes = _valid_postures(design, margins, asm, rng)
    rmap = R.region_map(design, margins, 64)
    theta1, h1 = O.theta1_grid(design, 0.04)
    comps = {r.component for r in rmap.regions if r.assembly_mode == asm}
    hits = 0
    for trial in range(12):
        i = rng.integers(len(q))
        radius = float(rng.uniform(0.02, 0.25))
        p_i = forward_batch(design, q[i], asm).p[0]
        centre = (p_i if kind == "point" else q[i]) + rng.normal(size=3) * radius / 3
        allowed = WORKING_MODES if trial % 2 else (modes[i],)
        ball = GoalBall(kind, centre, radius, allowed)
        # valid postures around q[i], some of them in the ball
        near = np.clip(q[i] + rng.normal(size=(6000, 3)) * 0.4, design.joint_min, design.joint_max)
        near_q, near_m = [], []
        for mode in allowed:
            ok = ValidityChecker(design, margins, (), asm, mode).is_valid(near)
            near_q.append(near[ok])
            near_m += [mode] * int(ok.sum())
        near_q, near_m = np.vstack(near_q), np.array(near_m)
        where = forward_batch(design, near_q, asm).p if kind == "point" else near_q
        inside = np.linalg.norm(where - centre, axis=1) <= radius
        plane = plane_cells(ball, rmap, asm)
        grid = grid_cells(ball, rmap, asm, comps, theta1, h1)
        for qk, mk in zip(near_q[inside], near_m[inside], strict=True):
            k3, k2 = rmap.cell_of(qk)
            assert plane[WORKING_MODES.index(mk), k3, k2], (trial, qk, mk)
            i1 = int(np.clip((qk[0] - theta1[0] + 0.5 * h1) // h1, 0, len(theta1) - 1))
            assert grid[i1, k3, k2], (trial, qk, mk)
            hits += 1
        # a ball of at most 0.25 (m or rad) keeps a minority of the cells
        assert plane.any(axis=0).mean() < 0.5
        assert grid.mean() < 0.5
    assert hits > 200


def test_a_ball_needs_a_kind_a_radius_and_known_modes() -> None:
    with pytest.raises(InputError, match="kind"):
        GoalBall("box", [0, 0, 0], 0.1)
    with pytest.raises(InputError, match="radius"):
        GoalBall("point", [0, 0, 0], -0.1)
    with pytest.raises(InputError, match="working_modes"):
        GoalBall("point", [0, 0, 0], 0.1, ("+0+",))


CONFIGS = [
    (Design.default(), Margins()),
    (Design(0.6, 0.25, 0.45), Margins(kappa_max=6.0, serial_min=0.1)),
    (Design(0.3, 0.3, 0.4, joint_min=(-3.14, -0.49, -2.81), joint_max=(3.14, 0.51, -1.72)),
     Margins()),
]  # fmt: skip
GRID = 2 * PROOF_RESOLUTION + 1


def test_no_false_ball_proof_over_600_queries_joined_by_the_dense_grid() -> None:
    """Start and a goal posture in one 4-connected component of one mode's valid grid (a
    valid path joins them, up to grid steps shorter than a map cell); a ball (point or
    joint, radius 1 mm to 0.2 m or rad) that holds that goal, its modes the goal's or all
    eight: the proof over the ball must never claim."""
    rng = np.random.default_rng(23)
    checked = 0
    for design, margins in CONFIGS:
        rmap = R.region_map(design, margins, PROOF_RESOLUTION)
        for asm in "+-":
            t2, t3, labels = dense_grid_components(design, margins, asm, GRID)
            filled = np.flatnonzero(labels.reshape(-1))
            for _ in range(100):
                a = int(filled[rng.integers(len(filled))])
                mi, rest = divmod(a, GRID * GRID)
                same = np.flatnonzero(labels[mi].ravel() == labels.reshape(-1)[a])
                b = int(same[rng.integers(len(same))])
                (ka3, ka2), (kb3, kb2) = divmod(rest, GRID), divmod(b, GRID)
                th1 = rng.uniform(design.joint_min[0], design.joint_max[0], 2)
                qa = np.array([th1[0], t2[ka2], t3[ka3]])
                qb = np.array([th1[1], t2[kb2], t3[kb3]])
                radius = float(rng.uniform(0.001, 0.2))
                off = rng.normal(size=3)
                off *= rng.uniform(0, radius) / np.linalg.norm(off)
                kind = "point" if rng.uniform() < 0.5 else "joint"
                where = forward_batch(design, qb, asm).p[0] if kind == "point" else qb
                modes = WORKING_MODES if rng.uniform() < 0.5 else (WORKING_MODES[mi],)
                ball = GoalBall(kind, where + off, radius, modes)
                assert not prove_ball_disconnected(rmap, qa, ball, asm), (design, asm, qa, qb)
                checked += 1
    assert checked == 600
