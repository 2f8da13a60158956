"""Labelled sections against geometry, the direct kinematics and the Manipulator API."""

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from planner import Design, InputError, Manipulator
from planner.analysis.loci import kappa_from_cd_distance
from planner.analysis.sections import cartesian_section, joint_section
from planner.kinematics import WORKING_MODES


@pytest.mark.parametrize(
    "design", [Design.paper_optimum(), Design.singularity_free(), Design(0.3, 0.5, 0.2)]
)
def test_cartesian_reach_matches_the_two_shells(design):
    s = cartesian_section(design, 96)
    uu, ww = np.meshgrid(s.x, s.y)
    big, small = design.reach, abs(design.L1 - design.L2)
    da = np.hypot(uu + design.L0 / 2, ww)
    db = np.hypot(uu - design.L0 / 2, ww)
    inside = (da >= small) & (da <= big) & (db >= small) & (db <= big)
    cell = max(s.x[1] - s.x[0], s.y[1] - s.y[0])
    margin = np.minimum.reduce(
        [np.abs(da - big), np.abs(da - small), np.abs(db - big), np.abs(db - small)]
    )
    clear = (margin > cell) & (np.abs(ww) > cell)
    reached = s.reached.any(axis=-1)
    assert np.array_equal(reached[clear], inside[clear])
    # in the plane at theta1 only the modes with s_axis = sign(w) reach
    upper = ww > 0
    assert not s.reached[upper][:, 4:].any()
    assert not s.reached[~upper][:, :4].any()


def test_cartesian_section_of_optimum_flags_c_equals_d_modes():
    s = cartesian_section(Design.paper_optimum(), 64)
    for k, mode in enumerate(WORKING_MODES):
        r = s.reached[..., k]
        if mode[1] == mode[2]:
            assert np.all(s.singular[..., k][r])
        else:
            assert np.all(np.isfinite(s.kappa_A[..., k][r]))


def test_cartesian_postures_reproduce_their_point():
    d = Design(0.3, 0.3, 0.4)
    s = cartesian_section(d, 40)
    m = Manipulator(d)
    j, i, k = np.argwhere(s.reached)[::97].T
    for jj, ii, kk in zip(j, i, k, strict=True):
        p = np.array([s.y[jj], s.x[ii], 0.0])
        post = {x.working_mode: x for x in m.inverse(p)}[WORKING_MODES[kk]]
        assert post.working_mode == WORKING_MODES[kk]
        assert np.sign(math.sin(post.passive[1] - post.passive[0])) == s.assembly_mode[jj, ii, kk]


def test_joint_section_kappa_follows_cd_distance():
    """kappa(A) depends on |CD| only (isosceles C-P-D): a second route to the core's value."""
    d = Design(0.3, 0.3, 0.4)
    s = joint_section(d, 64)
    g2, g3 = np.meshgrid(s.x, s.y)
    cd = np.hypot(d.L0 + d.L1 * (np.cos(g3) - np.cos(g2)), d.L1 * (np.sin(g3) - np.sin(g2)))
    ref = kappa_from_cd_distance(d, cd)
    for k in range(2):
        r = s.reached[..., k]
        assert np.allclose(s.kappa_A[..., k][r], ref[r], rtol=1e-7)
    closes = cd <= 2 * d.L2
    assert np.array_equal(s.reached[..., 0], closes)


def test_joint_section_working_modes_match_inverse_kinematics():
    d = Design.singularity_free()
    s = joint_section(d, 48)
    m = Manipulator(d)
    for jj, ii, kk in np.argwhere(s.reached & ~s.singular)[::211]:
        q = np.array([0.0, s.x[ii], s.y[jj]])
        post = m.posture(q, s.labels[kk])
        found = {x.working_mode: x for x in m.inverse(post.p)}
        label = "".join("+" if v > 0 else "-" for v in s.working_mode[jj, ii, kk])
        assert np.allclose(np.cos(found[label].q[1:] - q[1:]), 1.0)


def test_joint_section_of_optimum_marks_the_base_point_singular():
    """Erratum 6: half of each assembly mode's plane maps P onto A = B."""
    d = Design.paper_optimum()
    s = joint_section(d, 64)
    m = Manipulator(d)
    base = np.zeros(s.reached.shape, dtype=bool)
    for jj in range(0, 64, 7):
        for ii in range(0, 64, 7):
            for kk, mode in enumerate(s.labels):
                if s.reached[jj, ii, kk]:
                    post = m.posture(np.array([0.0, s.x[ii], s.y[jj]]), mode)
                    base[jj, ii, kk] = np.linalg.norm(post.p) < 1e-9
    assert base.any()
    assert np.all(s.singular[base])
    frac = s.singular.mean()
    assert 0.45 < frac < 0.6


def test_singularity_free_design_has_only_serial_cells_and_bounded_kappa():
    s = joint_section(Design.singularity_free(), 64)
    assert np.nanmax(s.kappa_A) < 1e3
    assert s.singular.mean() < 0.15


def test_bad_grid_arguments():
    with pytest.raises(InputError, match="n must"):
        cartesian_section(Design.default(), 1)
    with pytest.raises(InputError, match="extent"):
        joint_section(Design.default(), 8, extent=(1.0, 0.0, 0.0, 1.0))
    with pytest.raises(InputError, match="theta1"):
        cartesian_section(Design.default(), 8, theta1=float("nan"))


def _cells_of(section, xy):
    """Grid indices (row, col) of the cells holding points xy (M, 2), or -1 outside."""
    dx, dy = section.x[1] - section.x[0], section.y[1] - section.y[0]
    col = np.floor((xy[:, 0] - (section.x[0] - dx / 2)) / dx).astype(int)
    row = np.floor((xy[:, 1] - (section.y[0] - dy / 2)) / dy).astype(int)
    inside = (col >= 0) & (col < len(section.x)) & (row >= 0) & (row < len(section.y))
    return row[inside], col[inside]


def test_grid_singular_flags_lie_along_the_computed_loci():
    """Two routes to the same singularities: sign flips between grid cells and the closed-form
    curves. Every cell on the stretched-CD curve of a mode is flagged (or a neighbour is)."""
    from planner.analysis.loci import parallel_loci, serial_loci

    d = Design(0.6, 0.25, 0.45)
    s = cartesian_section(d, 128)
    loc = parallel_loci(d)["CD_stretched"].select(working_mode="+-+")
    v = loc.valid & (loc.uw[:, 1] > 0.02)
    row, col = _cells_of(s, loc.uw[v])
    k = s.slot("+-+")
    hit, interior = [], []
    for r, c in zip(row, col, strict=True):
        block = (slice(max(r - 2, 0), r + 3), slice(max(c - 2, 0), c + 3), k)
        interior.append(s.reached[block].all())  # the curve also touches the boundary
        hit.append(s.singular[max(r - 1, 0) : r + 2, max(c - 1, 0) : c + 2, k].any())
    hit = np.array(hit)[np.array(interior)]
    assert len(hit) > 50 and hit.all()
    # and the flagged cells of a regular mode lie near its serial boundary only
    j = joint_section(d, 96)
    sl = serial_loci(d, samples=20001)
    pts = np.concatenate([loc_.q[loc_.valid][:, 1:] for loc_ in sl.values()])
    flagged = np.argwhere(j.singular[..., 0])
    cell = j.x[1] - j.x[0]
    g = np.stack([j.x[flagged[:, 1]], j.y[flagged[:, 0]]], axis=1)

    def on_torus(x):
        y = np.mod(x + np.pi, 2 * np.pi)
        return np.where(y >= 2 * np.pi, 0.0, y)

    torus = cKDTree(on_torus(pts), boxsize=2 * np.pi)
    dist, _ = torus.query(on_torus(g), p=np.inf)
    assert len(g) > 100 and dist.max() < 1.5 * cell
