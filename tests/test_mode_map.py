"""Mode changes guided by the region map (issue 17): transit postures from the map's
transit cells, and mode walks the map's transit graph cannot realise left out."""

from __future__ import annotations

import numpy as np
import pytest

from planner.analysis import regions as R
from planner.design import Design
from planner.kinematics import WORKING_MODES, forward_batch
from planner.planning import JointPosture, PlanOptions, plan
from planner.planning.modes import PROOF_RESOLUTION, map_transits, walk_possible
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
        res = plan(design, JointPosture(q[0], "+"), JointPosture(q[1], "+"),
                   options=PlanOptions(time_budget_s=1.0, seed=2))  # fmt: skip
        if not res.solved:
            continue
        used = tuple(s.working_mode for s in res.path.segments)
        assert walk_possible(rmap, "+", used, q[0], q[1][None])
        from planner.planning import mode_sequences

        ruled_out += sum(
            not walk_possible(rmap, "+", w, q[0], q[1][None])
            for w in mode_sequences(modes[0], [modes[1]])
        )
        checked += 1
    assert checked >= 4
    assert ruled_out > 0
