"""Mode changes guided by the region map (issue 17): transit postures from the map's
transit cells, mode walks the map's transit graph cannot realise left out, and region walks
(chains of regions, a mode possibly revisited, longer than the mode walks' detours)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from planning_factories import check_library_plan, plan_answer

from planner.analysis import regions as R
from planner.design import Design
from planner.kinematics import WORKING_MODES, forward_batch
from planner.planning import JointPosture, PlanOptions, mode_sequences, plan, posture_mode
from planner.planning.proofs import PROOF_RESOLUTION
from planner.planning.region_walks import map_transits, region_walks, walk_possible
from planner.validity import Margins, ValidityChecker

DESIGNS = [Design.default(), Design(0.6, 0.25, 0.45), Design(0.3, 0.3, 0.4), Design.paper_optimum()]


def _flip(mode: str, j: int) -> str:
    return mode[:j] + ("-" if mode[j] == "+" else "+") + mode[j + 1 :]


@pytest.mark.parametrize("design", DESIGNS, ids=lambda d: f"{d.L0}/{d.L1}/{d.L2}")
def test_map_transits_lie_on_the_surface_with_the_other_signs_kept(design):
    """Every posture map_transits returns has the flipped measure 0 (forward kinematics,
    computed here from the passive angles) and the two other measures >= serial_min with
    the signs of the mode; some flip of some mode has postures."""
    rmap = R.region_map(design, Margins(), PROOF_RESOLUTION)
    s_min = Margins().serial_min
    found = 0
    for asm in "+-":
        for mode in WORKING_MODES:
            for j in range(3):
                q = map_transits(rmap, asm, mode, _flip(mode, j))
                if not len(q):
                    continue
                found += len(q)
                fb = forward_batch(design, q, asm)
                assert fb.ok.all()
                t2, t3 = fb.q[:, 1], fb.q[:, 2]
                t4, t5 = fb.passive[:, 0], fb.passive[:, 1]
                m = np.stack([fb.w / (design.L1 + design.L2), np.sin(t4 - t2), np.sin(t5 - t3)])
                assert np.abs(m[j]).max() < 1e-8
                for k in range(3):
                    if k != j:
                        sign = 1.0 if mode[k] == "+" else -1.0
                        assert (sign * m[k]).min() >= s_min - 1e-9
    assert found > 0


def test_impossible_walks_are_left_out_and_the_plan_still_solves():
    """On the general design the map's transit graph rules out some walks between the
    start's and the goal's modes (a walk it rules out is never the one the plan used), and
    the guided plan solves the query like the search alone."""
    design = Design(0.3, 0.3, 0.4)
    rmap = R.region_map(design, Margins(), PROOF_RESOLUTION)
    rng = np.random.default_rng(4)
    checked = ruled_out = 0
    for _ in range(400):
        if checked >= 4:
            break
        q = rng.uniform(-np.pi, np.pi, (2, 3))
        fb = forward_batch(design, q, "+")
        if not fb.ok.all() or np.any(fb.working_mode_signs == 0):
            continue
        modes = ["".join("+" if s > 0 else "-" for s in sg) for sg in fb.working_mode_signs]
        if modes[0] == modes[1] or not all(
            ValidityChecker(design, Margins(), (), "+", m).is_valid_one(*x)
            for m, x in zip(modes, q, strict=True)
        ):
            continue
        res = plan(
            design,
            JointPosture(q[0], "+"),
            JointPosture(q[1], "+"),
            options=PlanOptions(time_budget_s=1.0, seed=2),
        )
        if not res.solved:
            continue
        used = tuple(s.working_mode for s in res.path.segments)
        assert walk_possible(rmap, "+", used, q[0], q[1][None])
        ruled_out += sum(
            not walk_possible(rmap, "+", w, q[0], q[1][None])
            for w in mode_sequences(modes[0], [modes[1]])
        )
        checked += 1
    assert checked >= 4
    assert ruled_out > 0


#: Mode-change queries of the design 0.3/0.3/0.4 (2 L1 > L0) that ``benchmarks/planning.py
#: --map`` built (``build_mode_change_queries``, seed 13) and that the planner left unsolved
#: with a 2 s budget (and a 20 s one) before it followed region walks: (assembly mode,
#: start q, goal q). The first two are one sign apart but joined only through five transits
#: (beyond every walk of ``mode_sequences``); the other two need three and two, and failed
#: because crossings anywhere on the surface land in the wrong region of the next mode.
SPLIT_DESIGN = Design(0.3, 0.3, 0.4)
SPLIT_QUERIES = [
    ("+", [-0.8844, -0.564, 2.4242], [0.4696, -1.6407, -2.8628]),
    ("-", [-2.7325, 0.9142, -3.1072], [-2.4661, 1.4133, 2.3251]),
    ("+", [-1.4024, -2.9143, -1.0833], [-1.6888, -2.6071, 1.5264]),
    ("-", [-0.3661, -1.2281, -1.5036], [2.8849, -0.5024, -2.5426]),
]


def _modes(design, asm, q_start, q_goal):
    return (
        posture_mode(design, JointPosture(q_start, asm)),
        posture_mode(design, JointPosture(q_goal, asm)),
    )


@pytest.mark.parametrize("query", SPLIT_QUERIES, ids=range(len(SPLIT_QUERIES)))
def test_region_walks_are_chains_of_map_transits_from_the_start_to_the_goal(query):
    """Every region walk starts in a region of the start's mode holding the start, ends in
    a region of the goal's mode holding the goal, joins consecutive regions by a transit of
    the map (modes one sign apart), repeats no region, and the walks come fewest transits
    first."""
    asm, q0, q1 = query
    q0, q1 = np.asarray(q0), np.asarray(q1)
    m0, m1 = _modes(SPLIT_DESIGN, asm, q0, q1)
    rmap = R.region_map(SPLIT_DESIGN, Margins(), PROOF_RESOLUTION)
    walks = region_walks(rmap, asm, m0, q0, {m1: q1[None]})
    assert walks
    joined = {frozenset((t.a, t.b)) for t in rmap.transits}
    for w in walks:
        first, last = rmap.regions[w[0]], rmap.regions[w[-1]]
        assert first.working_mode == m0 and first in R.regions_at(rmap, q0, asm)
        assert last.working_mode == m1 and last in R.regions_at(rmap, q1, asm)
        assert len(set(w)) == len(w)
        for a, b in itertools.pairwise(w):
            assert frozenset((a, b)) in joined
            ma, mb = rmap.regions[a].working_mode, rmap.regions[b].working_mode
            assert sum(x != y for x, y in zip(ma, mb, strict=True)) == 1
    assert [len(w) for w in walks] == sorted(len(w) for w in walks)


@pytest.mark.parametrize("query", SPLIT_QUERIES, ids=range(len(SPLIT_QUERIES)))
def test_queries_joined_only_through_split_regions_are_solved(query):
    """The four queries above are solved (they were ``no_path`` before, whatever the
    budget), and the independent plan checker accepts each plan; the first two through a
    mode walk longer than any of ``mode_sequences``."""
    asm, q0, q1 = query
    start, goal = JointPosture(q0, asm), JointPosture(q1, asm)
    res = plan(SPLIT_DESIGN, start, goal, options=PlanOptions(time_budget_s=5.0))
    assert res.solved, res.message
    goal_wire = {"q": list(q1), "assembly_mode": asm}
    report = check_library_plan(SPLIT_DESIGN, start, goal_wire, Margins(), [], plan_answer(res))
    assert report.ok, str(report)
    used = tuple(s.working_mode for s in res.path.segments)
    m0, m1 = _modes(SPLIT_DESIGN, asm, np.asarray(q0), np.asarray(q1))
    assert used[0] == m0 and used[-1] == m1
    if query in SPLIT_QUERIES[:2]:
        assert used not in mode_sequences(m0, [m1])
        assert len(res.path.transits) == 5
