"""Singularity loci and isoconditioning curves: every point really is what it claims, checked
with explicit Jacobians, SVD condition numbers and the direct kinematics."""

import math

import numpy as np
import pytest

from planner import Design, forward_batch, link_points
from planner.analysis.loci import (
    cd_distance_for_kappa,
    isoconditioning_loci,
    kappa_from_cd_distance,
    parallel_loci,
    serial_loci,
)
from planner.exceptions import InputError

DESIGNS = [
    Design.paper_optimum(),
    Design.singularity_free(),
    Design(0.3, 0.3, 0.4),
    Design(0.6, 0.25, 0.45),
]


def _matrix_a(design, q, passive):
    """A = [L2 k^T; (p - c)^T; (p - d)^T] built from the joint centres, shape (M, 3, 3)."""
    pts = link_points(design, q, passive)
    c, d, p = pts[:, 2], pts[:, 3], pts[:, 4]
    k = np.stack([np.sin(q[:, 0]), np.zeros(len(q)), np.cos(q[:, 0])], axis=1)
    return np.stack([design.L2 * k, p - c, p - d], axis=1), pts


@pytest.mark.parametrize("design", DESIGNS, ids=lambda d: f"{d.L0}-{d.L1}-{d.L2}")
def test_parallel_locus_points_make_a_singular(design):
    for kind, loc in parallel_loci(design, samples=181).items():
        v = loc.valid
        if loc.fills_region:
            assert kind == "C=D" and design.L0 == 0
            continue
        a, pts = _matrix_a(design, loc.q[v], loc.passive[v])
        assert np.abs(np.linalg.det(a)).max() < 1e-9 * design.L2**3
        assert np.allclose(pts[:, 4, 1], loc.uw[v, 0], atol=1e-12)  # P's u
        cd = np.linalg.norm(pts[:, 3] - pts[:, 2], axis=1)
        assert np.allclose(cd, 0.0 if kind == "C=D" else 2 * design.L2, atol=1e-9)


@pytest.mark.parametrize("design", DESIGNS, ids=lambda d: f"{d.L0}-{d.L1}-{d.L2}")
def test_serial_locus_points_zero_one_entry_of_b(design):
    for kind, loc in serial_loci(design, samples=181).items():
        v = loc.valid
        pts = link_points(design, loc.q[v], loc.passive[v])
        a_, b_, c_, d_, p_ = (pts[:, i] for i in range(5))
        if kind == "P_on_axis":
            measure = np.linalg.norm(p_[:, [0, 2]], axis=1)
        else:
            base, knee = (a_, c_) if kind.startswith("leg_A") else (b_, d_)
            u1, u2 = knee - base, p_ - knee
            measure = np.linalg.norm(np.cross(u1, u2), axis=1) / (design.L1 * design.L2)
            dist = np.linalg.norm(p_ - base, axis=1)
            target = design.reach if kind.endswith("stretched") else abs(design.L1 - design.L2)
            assert np.allclose(dist, target, atol=1e-9)
        assert measure.max() < 1e-9


@pytest.mark.parametrize("design", DESIGNS[1:], ids=lambda d: f"{d.L0}-{d.L1}-{d.L2}")
def test_locus_postures_are_reproduced_by_direct_kinematics(design):
    loc = serial_loci(design, samples=91)["leg_A_stretched"]
    v = loc.valid & (loc.assembly_mode != 0)
    b = forward_batch(design, loc.q[v], loc.assembly_mode[v].astype(float))
    assert b.ok.all()
    assert np.allclose(b.p[:, 1], loc.uw[v, 0], atol=1e-9)
    assert np.allclose(b.w, loc.uw[v, 1], atol=1e-9)


@pytest.mark.parametrize("kappa", [1.0, 1.5, 4.0, 30.0])
@pytest.mark.parametrize("design", DESIGNS, ids=lambda d: f"{d.L0}-{d.L1}-{d.L2}")
def test_isoconditioning_points_have_that_svd_condition_number(design, kappa):
    loc = isoconditioning_loci(design, kappa, samples=121)
    v = loc.valid
    lo, hi = max(0.0, design.L0 - 2 * design.L1), min(design.L0 + 2 * design.L1, 2 * design.L2)
    exists = any(lo < dist < hi for dist in cd_distance_for_kappa(design, kappa))
    assert (v.sum() > 10) == exists
    if not exists:  # e.g. the singularity-free design never reaches kappa = 30
        return
    a, _ = _matrix_a(design, loc.q[v], loc.passive[v])
    assert np.allclose(np.linalg.cond(a), kappa, rtol=1e-6)


def test_cd_distance_and_kappa_are_inverse():
    d = Design(0.3, 0.3, 0.4)
    for k in (1.0, 2.0, 10.0):
        near, far = cd_distance_for_kappa(d, k)
        assert kappa_from_cd_distance(d, near) == pytest.approx(k)
        assert kappa_from_cd_distance(d, far) == pytest.approx(k)
    assert cd_distance_for_kappa(d, 1.0)[0] == pytest.approx(math.sqrt(2) * d.L2)
    with pytest.raises(InputError):
        cd_distance_for_kappa(d, 0.5)


def test_parallel_kinds_present_follow_the_design_rules():
    assert set(parallel_loci(Design.singularity_free())) == set()
    assert set(parallel_loci(Design(0.6, 0.25, 0.45))) == {"CD_stretched"}
    assert set(parallel_loci(Design(0.3, 0.3, 0.5))) == {"C=D"}
    assert set(parallel_loci(Design(0.3, 0.3, 0.4))) == {"C=D", "CD_stretched"}


def test_select_and_polyline():
    loc = isoconditioning_loci(Design(0.6, 0.25, 0.45), 2.0, samples=201)
    sel = loc.select(working_mode="+-+")
    labels = {"".join("+" if s > 0 else "-" for s in row) for row in sel.working_mode[sel.valid]}
    assert labels == {"+-+"}
    xy = sel.polyline("joint")
    assert xy.shape[1] == 2 and np.isnan(xy).any()
    finite = xy[np.all(np.isfinite(xy), axis=1)]
    assert len(finite) == sel.valid.sum()
    with pytest.raises(InputError):
        loc.polyline("polar")


def test_curves_are_continuous_and_closed_in_the_plane():
    """The two circle-intersection branches are joined at their turning points: along a branch
    P moves by small steps, and each joined curve ends where it started."""
    d = Design(0.6, 0.25, 0.45)
    loc = isoconditioning_loci(d, 2.0, samples=2001)
    xy = loc.uw
    breaks = np.flatnonzero(~loc.valid)
    starts = np.concatenate([[0], breaks + 1])
    ends = np.concatenate([breaks, [len(xy)]])
    for s, e in zip(starts, ends, strict=True):
        seg = xy[s:e]
        steps = np.linalg.norm(np.diff(seg, axis=0), axis=1)
        assert steps.max() < 0.05 * d.reach
        assert np.linalg.norm(seg[0] - seg[-1]) < 0.03 * d.reach
