"""Proven infeasibility in the planner (issue 17): ``planner.planning.plan`` answers
``no_path`` with ``diagnostics.proven_infeasible`` at once where the region map proves start
and goal apart, and never where a path exists.

The scenes built to be disconnected are cut by joint limits (the 2-D map proves those); a
wall of obstacles is not proven (the obstacle-free map cannot see it). False proofs are
checked over 1,000 seeded queries against an independent route: a flood fill of the valid
postures on a dense (theta2, theta3) grid (the validity checker, 4-connected steps shorter
than a map cell) and, for a bounded subset with mode changes, paths the search found.
"""

from __future__ import annotations

import numpy as np
import pytest
from planning_factories import CUT, cut_ends, dense_grid_components

from planner.analysis import regions as R
from planner.design import Design
from planner.geometry import Box, Sphere
from planner.kinematics import forward_batch
from planner.planning import CartesianTarget, JointPosture, PlanOptions, PlanStatus, plan
from planner.planning.proofs import PROOF_RESOLUTION
from planner.validity import Margins, ValidityChecker
from planner.wire import plan_response

FULL = Design(0.3, 0.3, 0.4)
BUDGET = PlanOptions(time_budget_s=5.0, seed=3)


def _assert_proven(res, start_mode: str) -> None:
    assert res.status is PlanStatus.NO_PATH, res.message
    assert res.diagnostics.proven_infeasible
    assert res.diagnostics.searches == 0 and res.diagnostics.planner == "region_map"
    assert "proven by the region map" in res.message and f"working mode {start_mode}" in res.message
    wire = plan_response(res)
    assert wire.status == "no_path" and wire.diagnostics.proven_infeasible


def _mode(design: Design, q: np.ndarray, asm: str) -> str:
    signs = forward_batch(design, q, asm).working_mode_signs[0]
    return "".join("+" if s > 0 else "-" for s in signs)


def test_joint_limits_cut_scene_is_proven_without_a_search():
    start, goal = cut_ends(PROOF_RESOLUTION)
    res = plan(CUT, JointPosture(start, "-"), JointPosture(goal, "-"), options=BUDGET)
    _assert_proven(res, _mode(CUT, start, "-"))


def test_the_proof_holds_with_obstacles_and_for_cartesian_goals():
    """Obstacles only remove postures, so the obstacle-free proof stands; a Cartesian target
    in the goal's working mode (all its candidates) is proven too, while in working mode
    'any' another branch of the inverse kinematics is reachable: no proof there."""
    start, goal = cut_ends(PROOF_RESOLUTION)
    far = [Sphere([1.5, 1.5, 1.5], 0.1)]
    res = plan(
        CUT, JointPosture(start, "-"), JointPosture(goal, "-"), obstacles=far, options=BUDGET
    )
    _assert_proven(res, _mode(CUT, start, "-"))
    p = forward_batch(CUT, goal, "-").p[0]
    res = plan(
        CUT, JointPosture(start, "-"), CartesianTarget(p, _mode(CUT, goal, "-")), options=BUDGET
    )
    _assert_proven(res, _mode(CUT, start, "-"))
    # in 'any' the start's own mode reaches p (another IK branch): solved, and the map does
    # not prove the path's end apart
    res_any = plan(CUT, JointPosture(start, "-"), CartesianTarget(p, "any"), options=BUDGET)
    assert res_any.solved and not res_any.diagnostics.proven_infeasible
    rmap = R.region_map(CUT, n=PROOF_RESOLUTION)
    assert not R.prove_disconnected(rmap, start, res_any.path.waypoints[-1], "-")


def test_no_proof_without_the_cut_or_with_the_map_off():
    """The same postures under full-turn limits are joined (the planner solves, no proof);
    with ``region_map=False`` the search runs and spends its budget, never proving."""
    start, goal = cut_ends(PROOF_RESOLUTION)
    res = plan(FULL, JointPosture(start, "-"), JointPosture(goal, "-"), options=BUDGET)
    assert res.solved and not res.diagnostics.proven_infeasible
    off = PlanOptions(time_budget_s=0.2, seed=3, region_map=False)
    res = plan(CUT, JointPosture(start, "-"), JointPosture(goal, "-"), options=off)
    assert not res.solved and not res.diagnostics.proven_infeasible
    assert not plan_response(res).diagnostics.proven_infeasible


def test_a_wall_of_obstacles_is_not_proven_by_the_2d_map():
    """A wall the arm cannot pass (box plates around the start's P) is invisible to the
    obstacle-free map: the answer is an honest ``no_path`` after a search, never a proof."""
    design = Design.default()
    start, goal = JointPosture([0.0, 2.0, 1.0], "+"), JointPosture([1.2, 2.0, 1.0], "+")
    p = forward_batch(design, start.q, "+").p[0]
    cage = [
        Box(p + off, size, [1.0, 0.0, 0.0, 0.0])
        for off, size in (
            ([0.12, 0, 0], [0.02, 0.3, 0.3]),
            ([-0.12, 0, 0], [0.02, 0.3, 0.3]),
            ([0, 0, 0.12], [0.3, 0.3, 0.02]),
            ([0, 0, -0.12], [0.3, 0.3, 0.02]),
        )
    ]
    res = plan(design, start, goal, obstacles=cage, options=PlanOptions(time_budget_s=0.3))
    assert res.status in (PlanStatus.NO_PATH, PlanStatus.INVALID_START, PlanStatus.INVALID_GOAL)
    assert not res.diagnostics.proven_infeasible


# ----------------------------------------------------------------- zero false proofs
CONFIGS = [
    (Design.default(), Margins()),
    (Design.paper_optimum(), Margins()),
    (Design(0.6, 0.25, 0.45), Margins(kappa_max=6.0, serial_min=0.1)),
    (FULL, Margins()),
    (CUT, Margins()),
    (Design(0.3, 0.3, 0.4, joint_min=(-1, -2, -1.5), joint_max=(1, 2.5, 3)),
     Margins(kappa_max=20.0, serial_min=0.03)),
]  # fmt: skip
GRID = 2 * PROOF_RESOLUTION + 1  # grid step half a map cell: no step jumps over a cell


def _grid_components(design: Design, margins: Margins, asm: str):
    return dense_grid_components(design, margins, asm, GRID)


def test_zero_false_proofs_over_1000_queries_joined_by_the_dense_grid():
    """1,000 seeded queries over six designs, margins and joint limits: start and goal are
    grid postures (theta1 random within its limits) in one 4-connected component of one
    mode's valid grid, so a valid path joins them (up to the grid's steps, each shorter than
    a map cell, between valid postures); the planner's map must never prove them apart."""
    rng = np.random.default_rng(17)
    checked = false = 0
    per = 1000 // (len(CONFIGS) * 2) + 1
    for design, margins in CONFIGS:
        rmap = R.region_map(design, margins, PROOF_RESOLUTION)
        for asm in "+-":
            t2, t3, labels = _grid_components(design, margins, asm)
            filled = np.flatnonzero(labels.reshape(-1))
            if not len(filled):
                continue
            for _ in range(per):
                if checked >= 1000:
                    break
                a = int(filled[rng.integers(len(filled))])
                mi, rest = divmod(a, GRID * GRID)
                same = np.flatnonzero(labels[mi].ravel() == labels.reshape(-1)[a])
                b = int(same[rng.integers(len(same))])
                (ka3, ka2), (kb3, kb2) = divmod(rest, GRID), divmod(b, GRID)
                th1 = rng.uniform(design.joint_min[0], design.joint_max[0], 2)
                qa = np.array([th1[0], t2[ka2], t3[ka3]])
                qb = np.array([th1[1], t2[kb2], t3[kb3]])
                false += R.prove_disconnected(rmap, qa, qb, asm)
                checked += 1
    assert checked == 1000
    assert false == 0


def _random_valid(design, margins, rng, asm):
    while True:
        q = rng.uniform(design.joint_min, design.joint_max)
        fb = forward_batch(design, q, asm)
        if not fb.ok[0] or np.any(fb.working_mode_signs[0] == 0):
            continue
        if ValidityChecker(design, margins, (), asm, _mode(design, q, asm)).is_valid_one(*q):
            return q


@pytest.mark.parametrize("k", range(3))
def test_no_proof_on_mode_change_queries_the_search_solves(k):
    """Random pairs in different working modes (mode changes included), planned by the
    search alone (``region_map=False``): every solved one is not proven apart by the map,
    and the planner with the map on never answers a proof for it."""
    design, margins = CONFIGS[[0, 2, 3][k]]
    rmap = R.region_map(design, margins, PROOF_RESOLUTION)
    rng = np.random.default_rng(100 + k)
    solved = 0
    for i in range(8):
        asm = "+-"[i % 2]
        qa, qb = _random_valid(design, margins, rng, asm), _random_valid(design, margins, rng, asm)
        res = plan(
            design,
            JointPosture(qa, asm),
            JointPosture(qb, asm),
            margins=margins,
            options=PlanOptions(time_budget_s=0.3, seed=1 + i, region_map=False),
        )
        if res.solved:
            solved += 1
            assert not R.prove_disconnected(rmap, qa, qb, asm)
            again = plan(
                design,
                JointPosture(qa, asm),
                JointPosture(qb, asm),
                margins=margins,
                options=PlanOptions(time_budget_s=0.3, seed=1 + i),
            )
            assert not again.diagnostics.proven_infeasible
    assert solved > 0
