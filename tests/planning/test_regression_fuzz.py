"""A seeded, small regression fuzz of :func:`planner.planning.plan` (issue 36): random designs,
random valid starts and goals (joint postures, Cartesian targets in a mode and in 'any'), in
free space and among obstacles.

Every solved answer is re-checked by the independent plan checker (``tests/plan_checker.py``,
dense, from the conventions alone). Every free-space query is compared with the design's
region map: where the map puts start and goal in one component of its union graph (regions
joined by transits), the answer must be solved, through whatever detour of other modes the
map shows (a goal in another region of the start's own mode among them); where it puts them
apart, the answer is the map's proof (``no_path`` with ``proven_infeasible``), never an
unproven ``no_path`` after a spent budget. Among obstacles an answer is solved (and checked)
or ``no_path``; never anything else for valid ends.

The budgets are generous (10 s; the free-space queries take tens of milliseconds each here)
so that a slow machine answers the same."""

from __future__ import annotations

import numpy as np
import pytest
from planning_factories import CUT, check_library_plan, plan_answer, seeded_scene

from planner.analysis import regions as R
from planner.design import Design
from planner.kinematics import WORKING_MODES, forward_batch, inverse_batch
from planner.planning import CartesianTarget, JointPosture, PlanOptions, PlanStatus, plan
from planner.planning.proofs import PROOF_RESOLUTION
from planner.validity import Margins, ValidityChecker

MARGINS = Margins(kappa_max=10.0, serial_min=0.05, clearance=0.01)
BUDGET_S = 10.0


def _mode(design: Design, q: np.ndarray, asm: str) -> str | None:
    signs = forward_batch(design, q, asm).working_mode_signs[0]
    if np.any(signs == 0):
        return None
    return "".join("+" if s > 0 else "-" for s in signs)


def _random_valid(
    design: Design, rng: np.random.Generator, asm: str, obstacles=()
) -> np.ndarray | None:
    """A posture drawn uniformly in the joint box until one is valid in its own mode (None
    after 2,000 draws: a scene that leaves almost nothing free)."""
    for _ in range(2000):
        q = rng.uniform(design.joint_min, design.joint_max)
        if not forward_batch(design, q, asm).ok[0]:
            continue
        mode = _mode(design, q, asm)
        if mode and ValidityChecker(design, MARGINS, obstacles, asm, mode).is_valid_one(*q):
            return q
    return None


def _random_design(rng: np.random.Generator) -> Design:
    l0, l1, l2 = rng.uniform([0.2, 0.2, 0.4], [0.35, 0.35, 0.7])
    return Design(float(l0), float(l1), float(l2), link_radius=0.01)


def _components(rmap: R.RegionMap, design: Design, q: np.ndarray, asm: str, modes) -> set[int]:
    """Components of the map's regions of ``modes`` holding q (empty: the map cannot place
    it)."""
    return {r.component for r in R.regions_at(rmap, q, asm) if r.working_mode in modes}


def _point_components(rmap, design: Design, p: np.ndarray, asm: str, modes) -> set[int]:
    """Components of the map's regions holding a valid joint solution of the point p in
    ``asm`` and one of ``modes`` (None: any mode): the inverse kinematics, each solution
    kept when the forward kinematics of ``asm`` gives p back and it is valid in its mode."""
    inv = inverse_batch(design, p[None])
    out: set[int] = set()
    for k, m in enumerate(WORKING_MODES):
        if not inv.ok[0, k] or (modes is not None and m not in modes):
            continue
        q = inv.q[0, k]
        fb = forward_batch(design, q, asm)
        if not fb.ok[0] or np.linalg.norm(fb.p[0] - p) > 1e-6:
            continue
        if ValidityChecker(design, MARGINS, (), asm, m).is_valid_one(*q):
            out |= _components(rmap, design, q, asm, {m})
    return out


def _query(rng: np.random.Generator, design: Design, asm: str, kind: str, obstacles=()):
    """(start, goal, goal on the wire, modes the goal allows (None: any)) of one query, None
    where the scene leaves no valid end."""
    qa = _random_valid(design, rng, asm, obstacles)
    qb = _random_valid(design, rng, asm, obstacles)
    if qa is None or qb is None:
        return None
    start = JointPosture(qa, asm)
    if kind == "joint":
        goal = JointPosture(qb, asm)
        return start, goal, {"q": qb.tolist(), "assembly_mode": asm}, {_mode(design, qb, asm)}
    p = forward_batch(design, qb, asm).p[0]
    mode = "any" if kind == "any" else _mode(design, qb, asm)
    assert mode is not None
    wire = {"p": p.tolist(), "working_mode": mode}
    modes = {mode} if mode != "any" else None
    return start, CartesianTarget(p, mode), wire, modes


def _check(design, start, goal, wire, obstacles, res) -> None:
    assert res.status in (PlanStatus.SOLVED, PlanStatus.NO_PATH, PlanStatus.UNREACHABLE), (
        res.status,
        res.message,
    )
    if res.solved:
        report = check_library_plan(design, start, wire, MARGINS, obstacles, plan_answer(res))
        assert report.ok, str(report)


@pytest.mark.parametrize("seed", range(3))
def test_free_space_answers_agree_with_the_region_map(seed):
    """Random designs and ends in free space: solved where the map joins start and goal (and
    checked), the map's proof where it does not; joint goals in another region of the start's
    own mode included (the seeds hold some: a detour back to the start's mode)."""
    rng = np.random.default_rng(3600 + seed)
    detours = 0
    for i in range(12):
        design = CUT if i == 0 else _random_design(rng)
        rmap = R.region_map(design, MARGINS, PROOF_RESOLUTION)
        asm = "-" if design is CUT else "+-"[int(rng.integers(2))]
        kind = ("joint", "joint", "mode", "any")[i % 4]
        query = _query(rng, design, asm, kind)
        assert query is not None
        start, goal, wire, modes = query
        res = plan(
            design,
            start,
            goal,
            margins=MARGINS,
            options=PlanOptions(time_budget_s=BUDGET_S, seed=1 + i),
        )
        _check(design, start, goal, wire, (), res)
        here = _components(rmap, design, start.q, asm, {_mode(design, start.q, asm)})
        if isinstance(goal, JointPosture):
            there = _components(rmap, design, goal.q, asm, modes)
        else:
            there = _point_components(rmap, design, goal.p, asm, modes)
        if here and there and not here & there:
            assert res.status is PlanStatus.NO_PATH and res.diagnostics.proven_infeasible, (
                res.message
            )
        elif here & there:
            assert res.solved, (i, res.message)
        detours += "which no path inside the mode joins" in res.message
    if seed == 0:
        assert detours > 0  # the seed holds a detour back to the start's mode


@pytest.mark.parametrize("seed", range(2))
def test_answers_among_obstacles_are_checked(seed):
    """Random designs, scenes and ends among obstacles: every solved plan passes the
    independent checker; the rest are ``no_path`` (proven or not) or ``unreachable``."""
    rng = np.random.default_rng(3700 + seed)
    solved = asked = 0
    while asked < 4:
        design = _random_design(rng)
        obstacles = seeded_scene(rng, most=4)
        asm = "+-"[int(rng.integers(2))]
        kind = ("joint", "any")[asked % 2]
        query = _query(rng, design, asm, kind, obstacles)
        if query is None:
            continue
        i, asked = asked, asked + 1
        start, goal, wire, _ = query
        res = plan(
            design,
            start,
            goal,
            obstacles=obstacles,
            margins=MARGINS,
            options=PlanOptions(time_budget_s=2.0, seed=1 + i),
        )
        _check(design, start, goal, wire, obstacles, res)
        solved += res.solved
    assert solved > 0
