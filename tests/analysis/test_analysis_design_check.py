"""The design-check verdict against sampling of the joint space, and the optimiser against the
paper's claim."""

import math

import numpy as np
import pytest

from planner import Design, InputError, conditioning, forward_batch
from planner.analysis.design_check import check_design, parallel_singularity_kinds
from planner.analysis.optimize import optimize_design
from planner.analysis.workspace import closed_form_volume


def _cd_range_sampled(design, n=400):
    """min and max of |CD| over an n x n grid of (theta2, theta3), from the joint centres."""
    t = np.linspace(-math.pi, math.pi, n)
    g2, g3 = np.meshgrid(t, t)
    cu = -design.L0 / 2 + design.L1 * np.cos(g2)
    du = design.L0 / 2 + design.L1 * np.cos(g3)
    cd = np.hypot(du - cu, design.L1 * (np.sin(g3) - np.sin(g2)))
    return cd.min(), cd.max()


def test_verdict_matches_sampled_cd_range():
    rng = np.random.default_rng(7)
    checked = 0
    while checked < 40:
        l0, l1, l2 = rng.uniform(0.0, 1.0), rng.uniform(0.05, 0.6), rng.uniform(0.05, 0.6)
        # stay clear of the thresholds, where a finite grid cannot decide
        gaps = [abs(l0 - 2 * l1), abs(l0 - 2 * (l2 - l1)), abs(l0 - 2 * (l1 + l2))]
        if min(gaps) < 0.05:
            continue
        d = Design(l0, l1, l2)
        kinds, reasons = parallel_singularity_kinds(d)
        lo, hi = _cd_range_sampled(d)
        workspace = l0 < 2 * (l1 + l2)
        assert ("C=D" in kinds) == (workspace and lo < 0.02 * l1), reasons
        assert ("CD_stretched" in kinds) == (workspace and lo < 2 * l2 < hi), reasons
        checked += 1


def test_singularity_free_design_has_no_sampled_posture_above_kappa_1e6():
    d = Design.singularity_free()
    check = check_design(d)
    assert check.singularity_free and check.parallel_singularities == ()
    q = np.random.default_rng(11).uniform(-math.pi, math.pi, (200_000, 3))
    for mode in ("+", "-"):
        b = forward_batch(d, q, mode)
        assert b.ok.all()  # |CD| <= L0 + 2 L1 < 2 L2: every joint posture assembles
        kappa = conditioning(d, b.q, b.passive, b.w).kappa_A
        assert kappa.max() < 1e6


def test_design_with_c_equals_d_reaches_huge_kappa_near_the_predicted_posture():
    d = Design(0.3, 0.3, 0.5)
    check = check_design(d)
    assert check.parallel_singularities == ("C=D",)
    t2 = math.atan2(math.sqrt(d.L1**2 - d.L0**2 / 4), d.L0 / 2)  # C = D = (0, h)
    t3 = math.pi - t2
    q = np.array([[0.0, t2 + 1e-8, t3]])
    kappa = conditioning(d, *(lambda b: (b.q, b.passive, b.w))(forward_batch(d, q, "+"))).kappa_A
    assert kappa[0] > 1e6


def test_paper_optimum_check():
    c = check_design(Design.paper_optimum())
    assert set(c.parallel_singularities) == {"C=D", "CD_stretched"}
    assert not c.singularity_free
    assert set(c.operative_working_modes) == {"++-", "+-+", "-+-", "--+"}
    assert c.volume == pytest.approx(4 / 3 * math.pi * 0.8**3)
    assert abs(c.sampled_volume.value - c.volume) <= 3 * c.sampled_volume.standard_error
    assert 0.5 < c.well_conditioned_fraction.value <= 1.0
    with pytest.raises(InputError):
        check_design(Design.paper_optimum(), kappa_max=0.5)


def test_empty_workspace():
    c = check_design(Design(2.0, 0.3, 0.4))
    assert c.volume == 0.0 and not c.singularity_free and c.operative_working_modes == ()


def test_volume_optimum_is_the_papers_for_fixed_reach():
    """Section 3.1: for fixed L1 + L2 the volume is largest at L0 = 0, L1 = L2."""
    r = optimize_design("volume", reach=0.8)
    assert r.design.L0 == pytest.approx(0.0, abs=1e-6)
    assert r.design.L1 == pytest.approx(0.4, abs=1e-4)
    assert r.design.L2 == pytest.approx(0.4, abs=1e-4)
    # independent check: no design on a grid of the same reach does better
    grid = [
        closed_form_volume(Design(l0, l1, 0.8 - l1))
        for l0 in np.linspace(0, 0.8, 9)
        for l1 in np.linspace(0.05, 0.75, 15)
    ]
    assert r.value >= max(grid) - 1e-12


def test_sampled_objective_improves_on_a_poor_design():
    r = optimize_design("well_conditioned_volume", reach=0.8, n_samples=512, maxiter=3, seed=1)
    assert 0.0 <= r.design.L0 <= 0.8 and r.design.L1 + r.design.L2 == pytest.approx(0.8)
    from planner.analysis.workspace import sample_workspace

    poor = sample_workspace(
        Design(0.7, 0.1, 0.7),
        rel_se=None,
        n_per_replicate=128,
        replicates=4,
        kappa_max=10.0,
        seed=1,
    )
    assert r.value > poor.well_conditioned.value


def test_optimiser_rejects_bad_arguments():
    with pytest.raises(InputError, match="objective"):
        optimize_design("speed")
    with pytest.raises(InputError, match="L1_bounds"):
        optimize_design("volume", reach=None)
