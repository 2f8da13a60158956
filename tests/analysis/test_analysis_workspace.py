"""Workspace volume: closed form against independent integration, sampling against the closed
form, joint limits and working modes against geometric expectations."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate

from planner import Design, InputError
from planner.analysis.workspace import (
    ball_intersection_volume,
    closed_form_volume,
    sample_workspace,
)

DESIGNS = [
    Design.paper_optimum(),  # L0 = 0, L1 = L2
    Design(0.0, 0.25, 0.45),  # L0 = 0, L1 < L2
    Design.singularity_free(),  # 2 L1 < L0 < 2 (L2 - L1)
    Design(0.7, 0.2, 0.5),  # L0 > 2 L1
    Design(0.3, 0.5, 0.2),  # L1 > L2
    Design(1.2, 0.3, 0.35),  # thin lens, L0 close to 2 (L1 + L2)
]


def _slab_volume(design: Design) -> float:
    """Volume by integrating cross-sections normal to AB: at y the workspace is the annulus
    of radii rho with rho^2 in [max(r^2 - a^2, r^2 - b^2, 0), min(R^2 - a^2, R^2 - b^2)],
    a = y + L0/2, b = y - L0/2 (an independent route to erratum 5's volume)."""
    big, small = design.L1 + design.L2, abs(design.L1 - design.L2)

    def area(y: float) -> float:
        a, b = y + design.L0 / 2, y - design.L0 / 2
        hi = min(big**2 - a * a, big**2 - b * b)
        lo = max(small**2 - a * a, small**2 - b * b, 0.0)
        return math.pi * max(hi - lo, 0.0)

    lim = big + design.L0 / 2
    pts = sorted(
        {c + s for c in (-design.L0 / 2, design.L0 / 2) for s in (-big, -small, small, big)} | {0.0}
    )
    return integrate.quad(area, -lim, lim, points=pts, limit=400, epsabs=1e-12)[0]


@pytest.mark.parametrize(
    ("r1", "r2", "d"),
    [(1.0, 1.0, 0.5), (1.0, 0.3, 0.2), (0.3, 1.0, 0.9), (1.0, 0.5, 1.6), (1.0, 0.5, 0.0)],
)
def test_ball_intersection_matches_slab_integration(r1, r2, d):
    def area(y):
        return math.pi * max(0.0, min(r1**2 - (y + d / 2) ** 2, r2**2 - (y - d / 2) ** 2))

    ref = integrate.quad(area, -3, 3, points=[-d / 2 - r1, d / 2 - r2, 0.0], limit=200)[0]
    assert ball_intersection_volume(r1, r2, d) == pytest.approx(ref, rel=1e-8, abs=1e-12)


@pytest.mark.parametrize("design", DESIGNS, ids=lambda d: f"{d.L0}-{d.L1}-{d.L2}")
def test_closed_form_matches_slab_integration(design):
    assert closed_form_volume(design) == pytest.approx(_slab_volume(design), rel=1e-7)


def test_closed_form_for_l0_zero_is_shell_volume():
    d = Design(0.0, 0.3, 0.5)
    assert closed_form_volume(d) == pytest.approx(4 / 3 * math.pi * (0.8**3 - 0.2**3), rel=1e-12)


def test_closed_form_is_zero_when_the_legs_cannot_meet():
    assert closed_form_volume(Design(2.0, 0.3, 0.4)) == 0.0
    assert sample_workspace(Design(2.0, 0.3, 0.4)).volume.value == 0.0


@pytest.mark.parametrize("design", DESIGNS, ids=lambda d: f"{d.L0}-{d.L1}-{d.L2}")
def test_sampled_volume_agrees_with_closed_form(design):
    s = sample_workspace(design, rel_se=0.003, replicates=16, seed=3)
    exact = closed_form_volume(design)
    assert s.volume.relative_error <= 0.003
    assert abs(s.volume.value - exact) <= 3 * s.volume.standard_error


def test_target_relative_error_is_met_by_growing_the_sample():
    d = Design(0.3, 0.5, 0.2)
    coarse = sample_workspace(d, rel_se=0.05, n_per_replicate=16, seed=1)
    fine = sample_workspace(d, rel_se=0.002, n_per_replicate=16, seed=1)
    assert fine.volume.relative_error <= 0.002
    assert fine.volume.n_samples > coarse.volume.n_samples


def test_paper_optimum_has_two_operative_mode_pairs():
    """Erratum 5: with L0 = 0 and L1 = L2 the modes with s_A = s_B are on C = D everywhere."""
    d = Design.paper_optimum()
    s = sample_workspace(d, rel_se=0.01)
    exact = closed_form_volume(d)
    for mode, est in s.per_mode_regular.items():
        if mode[1] == mode[2]:
            assert est.value == 0.0
        else:
            assert abs(est.value - exact) <= 3 * est.standard_error + 1e-12
    assert all(abs(e.value - exact) <= 3 * e.standard_error for e in s.per_mode.values())


def test_half_turn_of_theta1_keeps_the_volume_but_halves_each_mode():
    """Every P is reached with theta1 or theta1 + pi (s_axis flips): a half-turn window of
    theta1 keeps all points but each working mode reaches only half of them."""
    base = Design.singularity_free()
    d = Design(
        base.L0,
        base.L1,
        base.L2,
        joint_min=(-math.pi / 2, -math.pi, -math.pi),
        joint_max=(math.pi / 2, math.pi, math.pi),
    )
    s = sample_workspace(d, rel_se=0.004, replicates=16, seed=5)
    exact = closed_form_volume(d)
    assert abs(s.volume.value - exact) <= 3 * s.volume.standard_error
    for est in s.per_mode.values():
        assert abs(est.value - exact / 2) <= 3 * est.standard_error


def test_quarter_turn_of_theta1_halves_the_volume():
    base = Design(0.2, 0.4, 0.35)
    d = Design(
        base.L0, base.L1, base.L2, joint_min=(0.0, -4.0, -4.0), joint_max=(math.pi / 2, 4.0, 4.0)
    )
    s = sample_workspace(d, rel_se=0.004, replicates=16, seed=2)
    assert abs(s.volume.value - closed_form_volume(d) / 2) <= 3 * s.volume.standard_error


def test_well_conditioned_volume_is_monotone_in_the_bound():
    d = Design(0.3, 0.3, 0.4)
    mode = ["+-+"]
    vals = [
        sample_workspace(
            d, rel_se=None, kappa_max=k, seed=0, working_modes=mode
        ).well_conditioned.value
        for k in (1.0, 1.5, 3.0, 1e9)
    ]
    full = sample_workspace(d, rel_se=None, seed=0, working_modes=mode).volume.value
    assert vals[0] == 0.0  # kappa = 1 exactly is a surface: no volume
    assert vals[1] < vals[2] < vals[3]
    assert vals[3] == pytest.approx(full, rel=1e-12)


def test_gci_is_a_mean_of_inverse_kappa():
    s = sample_workspace(Design.singularity_free(), rel_se=None, seed=0)
    assert 0.0 < s.gci.value < 1.0


def test_bad_arguments_raise_typed_errors():
    d = Design.default()
    with pytest.raises(InputError, match="replicates"):
        sample_workspace(d, replicates=1)
    with pytest.raises(InputError, match="rel_se"):
        sample_workspace(d, rel_se=-1.0)
    with pytest.raises(InputError, match="kappa_max"):
        sample_workspace(d, kappa_max=0.5)
    with pytest.raises(InputError, match="working_mode"):
        sample_workspace(d, working_modes=["+x+"])


def test_one_mode_reaches_everything_without_limits_but_not_with_them():
    """With theta1 free, the plane turns so that w > 0 and each leg reaches any point of its
    shell with either elbow: one working mode covers the workspace. A theta2 window cuts it."""
    d = Design(0.3, 0.3, 0.4)
    all_modes = sample_workspace(d, rel_se=None, seed=4).volume.value
    one = sample_workspace(d, rel_se=None, seed=4, working_modes=["+-+"]).volume.value
    assert one == pytest.approx(all_modes, rel=1e-12)
    lim = Design(0.3, 0.3, 0.4, joint_min=(-math.pi, 0.0, -math.pi), joint_max=(math.pi,) * 3)
    cut = sample_workspace(lim, rel_se=None, seed=4, working_modes=["+-+"]).volume.value
    both = sample_workspace(lim, rel_se=None, seed=4).volume.value
    assert 0.0 < cut < both <= all_modes
    assert np.isfinite(cut)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(
    l0=st.floats(0.0, 2.0),
    l1=st.floats(0.01, 1.0),
    l2=st.floats(0.01, 1.0),
)
def test_closed_form_matches_slab_integration_for_any_design(l0, l1, l2):
    d = Design(l0, l1, l2)
    assert closed_form_volume(d) == pytest.approx(_slab_volume(d), rel=1e-6, abs=1e-10)
