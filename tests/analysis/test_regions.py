"""Region maps (``planner.analysis.regions``): cell labels against the validity checker,
the paper optimum's modes, transits, and proofs of disconnection against the planner."""

from __future__ import annotations

import numpy as np
import pytest

from planner import caching
from planner.analysis import _region_kernels as K
from planner.analysis import coverage as C
from planner.analysis import regions as R
from planner.design import Design
from planner.exceptions import InputError
from planner.kinematics import WORKING_MODES, forward_batch
from planner.planning import JointPosture, PlanOptions, plan
from planner.transits import FLIPPED_SIGN
from planner.validity import Margins, ValidityChecker

DESIGNS = {
    "singularity-free": Design.default(),
    "paper-optimum": Design.paper_optimum(),
    "mode-change": Design(0.6, 0.25, 0.45),
    "general": Design(0.3, 0.3, 0.4),
    "limits": Design(0.3, 0.3, 0.4, joint_min=(-1, -2, -1.5), joint_max=(1, 2.5, 3)),
}
#: The general design cut by a box of joint limits into two components in assembly mode '-'.
CUT = Design(0.3, 0.3, 0.4, joint_min=(-3.14, -0.49, -2.81), joint_max=(3.14, 0.51, -1.72))


def _cell_samples(rmap, k3, k2, rng, per_cell=6):
    """Postures (len(k3) * per_cell, 3) inside the closed cells: two opposite corners and
    random points."""
    u = rng.uniform(-0.5, 0.5, (len(k3), per_cell, 2))
    u[:, 0] = (-0.5, -0.5)
    u[:, 1] = (0.5, 0.5)
    t2 = rmap.theta2[k2][:, None] + u[..., 0] * rmap.h2
    t3 = rmap.theta3[k3][:, None] + u[..., 1] * rmap.h3
    t1 = rng.uniform(-1.0, 1.0, t2.shape)
    return np.stack([t1, t2, t3], axis=-1).reshape(-1, 3)


@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_labels_agree_with_the_validity_checker(name):
    """Every sampled posture of a surely valid cell is valid in its mode by the
    ValidityChecker, and every sample of a surely invalid cell is invalid."""
    design = DESIGNS[name]
    rmap = R.region_map(design, n=64)
    rng = np.random.default_rng(7)
    checked = {0: 0, 2: 0}
    for ai, asm in enumerate("+-"):
        for mi, mode in enumerate(WORKING_MODES):
            chk = ValidityChecker(design, Margins(), (), asm, mode)
            for code in (R.INVALID, R.VALID):
                k3, k2 = np.nonzero(rmap.status[ai, mi] == code)
                if len(k3) == 0:
                    continue
                pick = rng.choice(len(k3), min(len(k3), 150), replace=False)
                q = _cell_samples(rmap, k3[pick], k2[pick], rng)
                valid = chk.is_valid(q)
                assert valid.all() if code == R.VALID else not valid.any(), (asm, mode, code)
                checked[code] += len(q)
    assert checked[0] > 1000 and checked[2] > 1000


@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_every_cell_agrees_with_dense_sampling(name):
    """Every cell of a 128 x 128 map, at its four corners, its centre and four random points
    (the cells are closed: corners belong to four of them), checked in every working mode
    by the ValidityChecker: no sample of a surely valid cell is invalid, none of a surely
    invalid cell is valid; undecided cells hold valid and invalid samples often enough that
    the map is not trivially undecided."""
    design = DESIGNS[name]
    rmap = R.region_map(design, n=128)
    rng = np.random.default_rng(17)
    k3, k2 = np.meshgrid(np.arange(rmap.n), np.arange(rmap.n), indexing="ij")
    k3, k2 = k3.ravel(), k2.ravel()
    u = np.concatenate(
        [
            [[-0.5, -0.5], [0.5, -0.5], [-0.5, 0.5], [0.5, 0.5], [0.0, 0.0]],
            rng.uniform(-0.5, 0.5, (4, 2)),
        ]
    )
    t2 = rmap.theta2[k2][:, None] + u[None, :, 0] * rmap.h2
    t3 = rmap.theta3[k3][:, None] + u[None, :, 1] * rmap.h3
    t1 = rng.uniform(design.joint_min[0], design.joint_max[0], t2.shape)
    q = np.stack([t1, t2, t3], axis=-1).reshape(-1, 3)
    decided = 0
    for ai, asm in enumerate("+-"):
        for mi, mode in enumerate(WORKING_MODES):
            valid = ValidityChecker(design, Margins(), (), asm, mode).is_valid(q)
            valid = valid.reshape(len(k3), len(u))
            st = rmap.status[ai, mi][k3, k2]
            assert valid[st == R.VALID].all(), (asm, mode)
            assert not valid[st == R.INVALID].any(), (asm, mode)
            decided += int((st != R.UNDECIDED).sum())
    assert decided > 0.97 * 16 * len(k3)


@pytest.mark.parametrize("name", ["singularity-free", "paper-optimum", "mode-change", "general"])
def test_mirror_image_equals_the_direct_classification(name):
    """On a box symmetric about 0 the map builds one assembly mode and mirrors it (reflection
    about AB); the other assembly mode classified directly gives the same verdicts, masks,
    kinds and centre modes, and the same bounds to rounding."""
    design = DESIGNS[name]
    both = R._classify(design, Margins(), 96, R.DEFAULT_REFINE, mirror=False)
    mirrored = R._classify(design, Margins(), 96, R.DEFAULT_REFINE)
    assert np.array_equal(both.status, mirrored.status)
    assert np.array_equal(both.bits, mirrored.bits)
    assert np.array_equal(both.centre_mode, mirrored.centre_mode)
    inside = np.isfinite(both.m_lo)
    assert np.array_equal(inside, np.isfinite(mirrored.m_lo))
    for a, b in ((both.m_lo, mirrored.m_lo), (both.m_hi, mirrored.m_hi)):
        assert np.allclose(a[inside], b[inside], rtol=0, atol=1e-12)
    zero = ((both.bits >> K.BITS_ZERO) & 7).astype(bool)
    for k in range(3):
        where = (both.bits >> (K.BITS_ZERO + k)) & 1 == 1
        assert np.array_equal(both.kind[:, k][where], mirrored.kind[:, k][where])
    assert zero.any()


@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_labels_are_those_of_scipy_ndimage(name):
    """The one-pass labelling of every layer gives the labels of ``scipy.ndimage.label``
    with 8-connectivity, layer by layer, numbered alike, and the cell counts of bincount."""
    from scipy import ndimage

    rmap = R.region_map(DESIGNS[name], n=96)
    eight = np.ones((3, 3), dtype=bool)
    for ai in range(2):
        for mi in range(8):
            st = rmap.status[ai, mi]
            for src, mask in ((rmap.labels, st != R.INVALID), (rmap.certified, st == R.VALID)):
                expected, count = ndimage.label(mask, structure=eight)
                assert np.array_equal(src[ai, mi], expected), (ai, mi)
                assert int(src[ai, mi].max()) == count
            for region in rmap.regions_of("+-"[ai], WORKING_MODES[mi]):
                cells = rmap.labels[ai, mi] == region.label
                assert region.cells == int(cells.sum())
                assert region.valid_cells == int((cells & (st == R.VALID)).sum())


def test_refinement_only_sharpens_the_verdicts():
    """Refined maps keep every verdict of the unrefined one and decide more cells."""
    design = DESIGNS["general"]
    coarse = R.region_map(design, n=64, refine=1)
    fine = R.region_map(design, n=64)
    decided = coarse.status != R.UNDECIDED
    assert np.array_equal(coarse.status[decided], fine.status[decided])
    assert (fine.status != R.UNDECIDED).sum() > decided.sum()


def test_measure_bounds_hold_by_forward_kinematics():
    """The bounds on the three serial measures hold for samples inside the kappa band, with
    the measures from :func:`planner.kinematics.forward_batch` (atan2 angles, another route
    than the closed forms of the map)."""
    design = DESIGNS["general"]
    rmap = R.region_map(design, n=48)
    lo, hi = Margins().cd_range
    rng = np.random.default_rng(3)
    for ai, asm in enumerate("+-"):
        k3, k2 = np.nonzero(np.isfinite(rmap.measure_low[ai, 0]))
        q = _cell_samples(rmap, k3, k2, rng, per_cell=4)
        fb = forward_batch(design, q, asm)
        c = np.stack([-design.L0 / 2 + design.L1 * np.cos(q[:, 1]), design.L1 * np.sin(q[:, 1])])
        d = np.stack([design.L0 / 2 + design.L1 * np.cos(q[:, 2]), design.L1 * np.sin(q[:, 2])])
        cd = np.hypot(*(d - c)) / (2 * design.L2)
        inside = (cd >= lo) & (cd <= hi)
        m = fb.serial_measures[inside]
        cells = np.repeat(np.arange(len(k3)), 4)[inside]
        low = rmap.measure_low[ai][:, k3[cells], k2[cells]].T
        high = rmap.measure_high[ai][:, k3[cells], k2[cells]].T
        assert np.all(m >= low - 1e-9) and np.all(m <= high + 1e-9)


def test_mirror_symmetry_maps_modes_and_assembly():
    """Reflecting the plane about AB maps (theta2, theta3) to (-theta2, -theta3), flips every
    working-mode sign and the assembly mode: the map must be symmetric that way."""
    rmap = R.region_map(DESIGNS["mode-change"], n=64)
    flip = {m: "".join("-" if c == "+" else "+" for c in m) for m in WORKING_MODES}
    for mi, mode in enumerate(WORKING_MODES):
        mj = WORKING_MODES.index(flip[mode])
        assert np.array_equal(rmap.status[0, mi], rmap.status[1, mj][::-1, ::-1])


def test_paper_optimum_has_no_region_for_equal_leg_signs():
    """L0 = 0, L1 = L2: the modes with s_A = s_B are C = D everywhere (erratum 5), so no
    cell is even undecided in them; the two other mode pairs have regions."""
    rmap = R.region_map(Design.paper_optimum())
    counts = rmap.region_count()
    for mi, mode in enumerate(WORKING_MODES):
        if mode[1] == mode[2]:
            assert counts[:, mi].sum() == 0, mode
            assert not (rmap.status[:, mi] != R.INVALID).any()
    assert rmap.region_count(certified=True).sum() > 0


@pytest.mark.parametrize("name", ["singularity-free", "mode-change", "general"])
def test_transits_join_modes_differing_by_the_flipped_sign_only(name):
    rmap = R.region_map(DESIGNS[name], n=128)
    assert rmap.transits
    index = {"axis": 0, "A": 1, "B": 2}
    for t in rmap.transits:
        a, b = rmap.regions[t.a], rmap.regions[t.b]
        assert a.assembly_mode == b.assembly_mode
        diff = [j for j in range(3) if a.working_mode[j] != b.working_mode[j]]
        assert diff == [index[t.flipped]]
        assert t.kinds and all(FLIPPED_SIGN[k] == t.flipped for k in t.kinds)
        assert a.component == b.component


def test_transit_cells_sit_on_the_serial_surface():
    """Cells marked as transits for a flip hold a zero of that serial measure: its signs at
    the cell's corners (forward kinematics) differ, or a sample in it is within the cell's
    variation of zero."""
    design = DESIGNS["singularity-free"]
    rmap = R.region_map(design, n=128)
    rng = np.random.default_rng(5)
    for j in range(3):
        k3, k2 = np.nonzero(rmap.transit_cells[0, j] > 0)
        pick = rng.choice(len(k3), min(len(k3), 60), replace=False)
        q = _cell_samples(rmap, k3[pick], k2[pick], rng, per_cell=16)
        m = forward_batch(design, q, "+").serial_measures[:, j].reshape(len(pick), 16)
        # a straddling cell has both signs, or values small against serial_min
        assert np.all(
            (m.min(axis=1) <= 0.0) & (m.max(axis=1) >= 0.0) | (np.abs(m).min(axis=1) < 0.05)
        )


def test_cache_returns_the_same_read_only_map():
    a = R.region_map(Design.default(), n=32)
    assert R.region_map(Design.default(), Margins(), 32) is a
    assert not a.status.flags.writeable and not a.labels.flags.writeable
    assert R.region_map(Design.default(), Margins(kappa_max=5.0), 32) is not a


def test_cache_keeps_at_most_its_bytes(monkeypatch):
    """The LRU cache drops the least recently used map beyond its byte budget and does not
    keep a map larger than the budget."""
    caching.clear("regions")
    a = R.region_map(Design.default(), n=64)
    monkeypatch.setattr(R._CACHE, "max_bytes", int(1.5 * caching.nbytes_of(a)))
    b = R.region_map(Design.paper_optimum(), n=64)
    assert R.region_map(Design.paper_optimum(), n=64) is b
    assert R.region_map(Design.default(), n=64) is not a  # dropped for b
    big = R.region_map(Design.default(), n=128)
    assert R.region_map(Design.default(), n=128) is not big  # never kept
    caching.clear("regions")


def test_coverage_areas_match_the_jacobian_integral():
    """Area of each certified region's image two ways: the Cartesian raster of
    :func:`cartesian_coverage` (inverse kinematics) and the sum over its cells of
    |det d(u, w)/d(theta2, theta3)| h2 h3 by finite differences (direct kinematics)."""
    design = DESIGNS["singularity-free"]
    rmap = R.region_map(design, n=128)
    cov = C.cartesian_coverage(rmap, 400)
    h = 1e-6
    for region in rmap.regions:
        if region.valid_cells < 500:
            continue
        ai, mi = "+-".index(region.assembly_mode), WORKING_MODES.index(region.working_mode)
        k3, k2 = np.nonzero(
            (rmap.labels[ai, mi] == region.label) & (rmap.status[ai, mi] == R.VALID)
        )
        q = np.stack([np.zeros(len(k3)), rmap.theta2[k2], rmap.theta3[k3]], axis=1)
        dq2, dq3 = np.array([0.0, h, 0.0]), np.array([0.0, 0.0, h])

        def uw(qq, asm=region.assembly_mode):
            fb = forward_batch(design, qq, asm)
            return np.stack([fb.p[:, 1], fb.w], axis=1)

        j2 = (uw(q + dq2) - uw(q - dq2)) / (2 * h)
        j3 = (uw(q + dq3) - uw(q - dq3)) / (2 * h)
        jac = np.abs(j2[:, 0] * j3[:, 1] - j2[:, 1] * j3[:, 0]).sum() * rmap.h2 * rmap.h3
        assert cov.area([region.id]) == pytest.approx(jac, rel=0.04)


@pytest.mark.parametrize("name", ["singularity-free", "paper-optimum", "mode-change", "general"])
def test_coverage_volume_with_loose_margins_is_the_closed_form(name):
    """With margins that exclude almost nothing, the volume swept by all certified regions
    of one assembly mode (Coverage.volume, Pappus over the folded raster) is the closed-form
    workspace volume (lens volumes of the two hollow balls, erratum 5) within 1 %."""
    from planner.analysis.workspace import closed_form_volume

    design = DESIGNS[name]
    rmap = R.region_map(design, Margins(kappa_max=1e4, serial_min=1e-3), 256)
    cov = C.cartesian_coverage(rmap, 400)
    for asm in "+-":
        ids = [r.id for r in rmap.regions if r.assembly_mode == asm]
        assert cov.volume(ids) == pytest.approx(closed_form_volume(design), rel=0.01)
    limited = C.cartesian_coverage(R.region_map(DESIGNS["limits"], n=32), 32)
    with pytest.raises(InputError):
        limited.volume([0])


def test_twice_as_large_holds_in_the_section_of_the_paper_optimum_only():
    """The paper's claim (section 3.3) on its optimum: in the linkage plane the certified
    regions of a union-graph component cover twice what its convex (or non-convex) pair
    covers, but the 3-D volume swept as theta1 turns is the same (the second half of the
    section is the first's mirror about AB, i.e. the same points half a turn later)."""
    rmap = R.region_map(Design.paper_optimum(), n=256)
    cov = C.cartesian_coverage(rmap, 300)
    mine = [r for r in rmap.regions if r.assembly_mode == "+" and r.valid_cells]
    for comp in {r.component for r in mine}:
        ids = [r.id for r in mine if r.component == comp]
        for pair in (("+-+", "-+-"), ("++-", "--+")):
            sub = [r.id for r in mine if r.component == comp and r.working_mode in pair]
            assert cov.area(ids) / cov.area(sub) == pytest.approx(2.0, rel=0.02)
            assert cov.volume(ids) / cov.volume(sub) == pytest.approx(1.0, rel=0.01)


# ----------------------------------------------------------------------------- proofs
def _centre(rmap, ai, mode, component):
    """A surely valid cell centre of a region of ``mode`` in ``component`` (q with theta1 0)."""
    mi = WORKING_MODES.index(mode)
    for region in rmap.regions_of("+-"[ai], mode):
        if region.component == component and region.valid_cells > 20:
            k3, k2 = np.nonzero(
                (rmap.labels[ai, mi] == region.label) & (rmap.status[ai, mi] == R.VALID)
            )
            k = len(k3) // 2
            return np.array([0.0, rmap.theta2[k2[k]], rmap.theta3[k3[k]]])
    raise AssertionError("no such region")


def test_joint_limits_cut_a_connected_design_and_the_proof_says_so():
    """A box of joint limits cuts the general design's assembly mode '-' in two: postures
    in the two parts are proven apart, the same postures under full-turn limits are not,
    and the planner does not join them."""
    full = R.region_map(Design(0.3, 0.3, 0.4), n=128)
    cut = R.region_map(CUT, n=128)
    big = [r for r in cut.regions if r.assembly_mode == "-" and r.valid_cells > 200]
    comps = sorted({r.component for r in big})
    assert len(comps) == 2
    ends = []
    for comp in comps:
        region = next(r for r in big if r.component == comp)
        ends.append(_centre(cut, 1, region.working_mode, comp))
    start, goal = ends
    assert R.prove_disconnected(cut, start, goal, "-")
    assert R.prove_disconnected(cut, goal, start, "-")
    assert not R.prove_disconnected(full, start, goal, "-")
    result = plan(
        CUT,
        JointPosture(start, "-"),
        JointPosture(goal, "-"),
        options=PlanOptions(time_budget_s=0.3, seed=3, region_map=False),  # the search alone
    )
    assert not result.solved


def test_literal_limits_disconnect_the_paper_optimum():
    """The optimum's regions are diagonal bands cut by the literal +-pi limits (and by the
    C = D and CD-stretched bands): its map has more than one component per assembly mode,
    and postures in two of them are proven apart."""
    rmap = R.region_map(Design.paper_optimum(), n=128)
    comps = sorted(
        {r.component for r in rmap.regions if r.assembly_mode == "+" and r.valid_cells > 20}
    )
    assert len(comps) >= 2
    a = next(r for r in rmap.regions if r.component == comps[0] and r.valid_cells > 20)
    b = next(r for r in rmap.regions if r.component == comps[1] and r.valid_cells > 20)
    qa = _centre(rmap, 0, a.working_mode, comps[0])
    qb = _centre(rmap, 0, b.working_mode, comps[1])
    assert R.prove_disconnected(rmap, qa, qb, "+")
    assert R.prove_disconnected(rmap, qa, np.stack([qb, qb]), "+")
    assert not R.prove_disconnected(rmap, qa, np.stack([qb, qa]), "+")


def test_never_proven_outside_the_box_or_for_invalid_postures():
    """The map proves nothing about a posture outside the joint box or in no region: paired
    with a posture of the other component, which an in-box posture of its own component is
    proven apart from (the positive counterpart), it is not proven apart, in either role or
    among goal candidates, and the witness says why (no cell for an out-of-box (theta2,
    theta3); no region at all). Each out-of-box posture lies beyond the edge of a cell of the
    first component, so a map that clamped it into the box would claim a proof.

    Mutants caught (the old test, two pairs against an invalid goal, passed all five):
    ``prove_disconnected`` returning False; the theta1 limit dropped from ``_components_at``;
    ``locate`` clamping (theta2, theta3) into the box; an empty set of regions taken as
    proven apart (``if comps & start`` for a goal, ``if start is None`` for the start)."""
    rmap = R.region_map(CUT, n=128)
    big = [r for r in rmap.regions if r.assembly_mode == "-" and r.valid_cells > 200]
    comps = sorted({r.component for r in big})
    a, b = (
        _centre(rmap, 1, next(r for r in big if r.component == c).working_mode, c) for c in comps
    )
    assert R.prove_disconnected(rmap, a, b, "-")  # the positive counterpart, and its witness:
    assert {r.component for r in R.regions_at(rmap, a, "-")} == {comps[0]}
    assert {r.component for r in R.regions_at(rmap, b, "-")} == {comps[1]}
    lo, hi = CUT.joint_min, CUT.joint_max
    outside = {
        "theta1": [hi[0] + 0.5, a[1], a[2]],
        "theta2": [a[0], hi[1] + 0.3, a[2]],
        "theta3": [a[0], a[1], lo[2] - 0.3],
    }
    for joint, q in outside.items():
        # beyond the edge of a cell of a's component (where a clamping map would put it)
        edge = np.clip(q, np.asarray(lo) + 1e-9, np.asarray(hi) - 1e-9)
        assert {r.component for r in R.regions_at(rmap, edge, "-")} == {comps[0]}, joint
        assert R.regions_at(rmap, q, "-") == (), joint
        if joint != "theta1":  # theta1 has no cell axis: locate ignores it
            assert R.locate(rmap, q) is None, joint
        assert not R.prove_disconnected(rmap, q, b, "-"), joint
        assert not R.prove_disconnected(rmap, b, q, "-"), joint
        assert not R.prove_disconnected(rmap, b, np.stack([a, q]), "-"), joint
    invalid = np.array([0.0, 0.0, -2.0])  # inside the box, in no region of assembly mode '-'
    assert R.locate(rmap, invalid) is not None and R.regions_at(rmap, invalid, "-") == ()
    for other in (a, b):
        assert not R.prove_disconnected(rmap, invalid, other, "-")
        assert not R.prove_disconnected(rmap, other, invalid, "-")
    assert not R.prove_disconnected(rmap, a, np.stack([b, invalid]), "-")


def _random_valid(design, rng, count):
    """Random postures valid in some working mode of assembly mode '+' or '-'."""
    out = []
    while len(out) < count:
        q = rng.uniform(design.joint_min, design.joint_max)
        asm = "+-"[int(rng.integers(2))]
        fb = forward_batch(design, q, asm)
        if not fb.ok[0]:
            continue
        signs = fb.working_mode_signs[0]
        if np.any(signs == 0):
            continue
        mode = "".join("+" if s > 0 else "-" for s in signs)
        if ValidityChecker(design, Margins(), (), asm, mode).is_valid(q[None])[0]:
            out.append((q, asm))
    return out


def seeded_queries(count, seed=0):
    """(design, start, goal, assembly mode) queries over four designs, both postures valid."""
    rng = np.random.default_rng(seed)
    designs = [
        Design.default(),
        Design.paper_optimum(),
        Design(0.6, 0.25, 0.45),
        Design(0.3, 0.3, 0.4),
    ]
    out = []
    for k in range(count):
        design = designs[k % len(designs)]
        ((qa, asm),) = _random_valid(design, rng, 1)
        while True:
            ((qb, asm_b),) = _random_valid(design, rng, 1)
            if asm_b == asm:
                break
        out.append((design, qa, qb, asm))
    return out


def test_no_false_proof_on_solved_queries():
    """Seeded queries planned with planner.planning.plan: no solved one is proven
    disconnected (zero false proofs), and some unsolved ones are."""
    solved = proven = 0
    for k, (design, qa, qb, asm) in enumerate(seeded_queries(48, seed=11)):
        rmap = R.region_map(design, n=128)
        claim = R.prove_disconnected(rmap, qa, qb, asm)
        if claim:
            proven += 1
            continue  # proven pairs are not planned here (the planner spends its budget)
        result = plan(
            design,
            JointPosture(qa, asm),
            JointPosture(qb, asm),
            options=PlanOptions(time_budget_s=0.25, seed=1 + k),
        )
        solved += result.solved
    assert solved > 10
    assert proven > 0


def test_proven_queries_are_not_solved():
    """The other half of the check: queries the map proves disconnected are handed to the
    planner's search alone (``region_map=False``: the planner's own proof would answer at
    once), which must never solve one (a solved proven query is a false proof)."""
    checked = 0
    for k, (design, qa, qb, asm) in enumerate(seeded_queries(60, seed=12)):
        rmap = R.region_map(design, n=128)
        if not R.prove_disconnected(rmap, qa, qb, asm):
            continue
        result = plan(
            design,
            JointPosture(qa, asm),
            JointPosture(qb, asm),
            options=PlanOptions(time_budget_s=0.1, seed=1 + k, region_map=False),
        )
        assert not result.solved, (design, qa, qb, asm)
        checked += 1
        if checked >= 8:
            break
    assert checked > 0
