"""best_conditioned against shortest on a seeded suite, kappa(A) measured independently."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest

from planner import Design, forward_batch
from planner.planning import JointPosture, PlanOptions, posture_mode
from planner.planning.preference import choose_plan, plan_candidates
from planner.validity import Margins, ValidityChecker


def own_max_kappa(design: Design, waypoints: np.ndarray, asm: str, per: int = 400) -> float:
    """kappa(A) = max(|tan(d/2)|, |cot(d/2)|), d = theta4 - theta5, from docs/conventions.md:
    theta4 - theta5 is the apex angle of the isosceles triangle C-P-D (|CD| = 2 L2 sin(g/2))."""
    q = np.concatenate(
        [a + np.linspace(0, 1, per)[:, None] * (b - a) for a, b in pairwise(waypoints)]
    )
    half = design.L0 / 2
    cu, cw = -half + design.L1 * np.cos(q[:, 1]), design.L1 * np.sin(q[:, 1])
    du, dw = half + design.L1 * np.cos(q[:, 2]), design.L1 * np.sin(q[:, 2])
    r = np.hypot(du - cu, dw - cw) / (2 * design.L2)  # sin(g / 2)
    t = r / np.sqrt(1 - r**2)  # tan(g / 2)
    return float(np.max(np.maximum(t, 1 / t)))


@pytest.mark.parametrize("design", [Design.default(), Design(0.6, 0.25, 0.45)])
def test_best_conditioned_is_never_worse_than_shortest(design):
    rng = np.random.default_rng(11)
    compared = 0
    opts = PlanOptions(time_budget_s=0.3, seed=3)
    for _ in range(60):
        q = rng.uniform(-2.5, 2.5, 3)

        start = JointPosture(q, "+")
        mode = posture_mode(design, start)
        if (
            mode is None
            or not ValidityChecker(design, Margins(), (), "+", mode).is_valid(q[None])[0]
        ):
            continue
        q_goal = np.clip(q + rng.uniform(-1.0, 1.0, 3), -3.0, 3.0)

        fb = forward_batch(design, q_goal, "+")
        if not fb.ok[0]:
            continue
        cands = plan_candidates(design, start, fb.p[0], options=opts)
        solved = [m for m, r in cands.items() if r.solved]
        if len(solved) < 2:
            continue
        best = choose_plan(design, cands, "best_conditioned")
        short = choose_plan(design, cands, "shortest")
        k_best = own_max_kappa(design, best.result.path.waypoints, "+")
        k_short = own_max_kappa(design, short.result.path.waypoints, "+")
        assert k_best <= k_short * (1 + 1e-3), (best.message, short.message)
        assert best.working_mode in best.message and "best_conditioned" in best.message
        compared += 1
        if compared >= 4:
            break
    assert compared >= 2
