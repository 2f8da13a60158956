"""The validity checker against independent routes: kinematics.conditioning and
serial_measures for the margins, dense link sampling for clearance, dense sampling of motions
for the motion certificate, and finite differences for its Lipschitz constants."""

from __future__ import annotations

import numpy as np
import pytest
from planning_factories import LINKS, reference_clearance, reference_measures

from planner.design import Design
from planner.exceptions import InputError
from planner.geometry import Box, Capsule, Sphere
from planner.validity import Margins, ValidityChecker, densify

DESIGNS = [Design.default(), Design.paper_optimum(), Design(0.3, 0.25, 0.45, link_radius=0.03)]
OBSTACLES = [
    Sphere([0.35, 0.1, 0.3], 0.12),
    Box([0.0, 0.0, -0.6], [2.0, 2.0, 0.1], [0.9, 0.1, 0.2, 0.0]),
    Capsule([-0.4, -0.3, 0.2], [-0.2, 0.4, 0.5], 0.05),
]


def _reference_valid(design, q, asm, mode, margins, obstacles, k=400):
    ok, kappa, serial, clear = reference_measures(design, q, asm, mode, obstacles, k)
    lim = np.all((q >= design.joint_min) & (q <= design.joint_max), axis=1)
    with np.errstate(invalid="ignore"):
        return (
            lim
            & ok
            & (kappa <= margins.kappa_max)
            & (serial >= margins.serial_min)
            & (clear >= margins.clearance)
        )


@pytest.mark.parametrize("design", DESIGNS, ids=["sing-free", "paper", "other"])
@pytest.mark.parametrize(("asm", "mode"), [("+", "+-+"), ("+", "+++"), ("-", "-+-"), ("-", "+-+")])
def test_state_measures_match_kinematics_and_sampling(design, asm, mode):
    rng = np.random.default_rng(3)
    q = rng.uniform(-np.pi, np.pi, (300, 3))
    margins = Margins(kappa_max=6.0, serial_min=0.1, clearance=0.02)
    chk = ValidityChecker(design, margins, OBSTACLES, asm, mode)
    rep = chk.check_states(q)
    ok, kappa, serial, clear = reference_measures(design, q, asm, mode, OBSTACLES)
    np.testing.assert_allclose(rep.kappa_A[ok], kappa[ok], rtol=1e-9)
    np.testing.assert_allclose(rep.serial_margin[ok], serial[ok], atol=1e-12)
    # link sampling at 1/400 of a link overestimates the clearance by < link/800
    assert np.all(rep.clearance[ok] <= clear[ok] + 1e-9)
    assert np.all(clear[ok] - rep.clearance[ok] <= max(design.L1, design.L2) / 800 + 1e-9)
    ref = _reference_valid(design, q, asm, mode, margins, OBSTACLES)
    near = np.abs(rep.clearance - margins.clearance) < 2e-3  # sampling can flip these
    assert np.array_equal(rep.valid[~near], ref[~near])
    assert np.array_equal(chk.is_valid(q), rep.valid)


@pytest.mark.parametrize("design", DESIGNS, ids=["sing-free", "paper", "other"])
def test_the_distal_links_clearance_is_measured_on_its_own(design):
    """The measure the certificate bounds per link group (planner.validity._kernels
    M_CLEAR_DIST): exact in full mode, the distal links CP and DP alone (against an
    independent route: kinematics and segment distances); relaxed (as the certificate
    measures), a lower bound of it that keeps at least half of its margin, never below the
    all-links measure."""
    from planner.validity._kernels import M_CLEAR, M_CLEAR_DIST, N_MEASURES, evaluate_many

    rng = np.random.default_rng(31)
    q = rng.uniform(-np.pi, np.pi, (400, 3))
    margins = Margins(kappa_max=6.0, clearance=0.02)
    obstacles = [*OBSTACLES, Sphere([0.12, -0.25, 0.0], 0.03)]  # near A: the proximal AC
    chk = ValidityChecker(design, margins, obstacles, "+", "+-+", serial_rules=False)
    full = np.empty((len(q), N_MEASURES))
    evaluate_many(q, chk._prm, *chk._packed, True, full)
    distal = reference_clearance(design, q, "+", obstacles, LINKS[2:])
    closed = np.isfinite(distal) & (full[:, M_CLEAR] > -np.inf)
    assert closed.sum() > 100
    got = full[closed, M_CLEAR_DIST] + margins.clearance
    np.testing.assert_allclose(got, distal[closed], atol=1e-9)
    assert np.all(full[closed, M_CLEAR] <= full[closed, M_CLEAR_DIST])
    assert np.any(full[closed, M_CLEAR] < full[closed, M_CLEAR_DIST] - 0.05)  # a proximal link
    relaxed = np.empty_like(full)
    evaluate_many(q, chk._prm, *chk._packed, False, relaxed)
    valid = closed & (relaxed[:, 0] == 0)
    assert valid.sum() > 50
    true, low = full[valid, M_CLEAR_DIST], relaxed[valid, M_CLEAR_DIST]
    capped = np.minimum(true, 0.25)  # nothing is measured beyond clearance + 0.25 m
    assert np.all(low <= true + 1e-12)
    assert np.all(low >= 0.5 * capped - 1e-12)
    assert np.all(relaxed[valid, M_CLEAR] <= low)


def test_reasons_are_the_first_broken_rule():
    d = Design(0.5, 0.2, 0.6, joint_min=(-1, -np.pi, -np.pi), joint_max=(1, np.pi, np.pi))
    chk = ValidityChecker(d, Margins(), [Sphere([0.0, 0.0, 0.6], 0.1)], "+", "+-+")
    q_ok = np.array([0.5, 2.0, 1.0])
    assert chk.check_states(q_ok).reason.tolist() == ["valid"]
    assert chk.check_states([1.5, 2.0, 1.0]).reason.tolist() == ["joint_limits"]
    assert chk.explain([1.5, 2.0, 1.0]).startswith("joint_limits: q[0] = 1.5 rad")
    assert chk.with_mode("+++").check_states(q_ok).reason.tolist() == ["working_mode"]
    # rotating the plane onto the sphere at +z: theta1 = -pi/2 puts w along +z
    chk2 = ValidityChecker(Design.default(), Margins(), [Sphere([0.0, 0.0, 0.6], 0.1)], "+", "+-+")
    r = chk2.check_states([-np.pi / 2 + 0.05, 2.0, 1.0])
    assert r.reason.tolist() == ["clearance"] and r.clearance[0] < 0.01
    assert "clearance" in chk2.explain([-np.pi / 2 + 0.05, 2.0, 1.0])


def test_kappa_band_is_the_kappa_margin():
    # states sweeping through C = D region: the reason kappa_max appears exactly where the
    # kinematics' kappa_A exceeds the bound
    d = Design.paper_optimum()
    chk = ValidityChecker(d, Margins(kappa_max=4.0, serial_min=0.01), [], "+", "+-+")
    t3 = np.linspace(-np.pi, np.pi, 5001)
    q = np.stack([np.zeros_like(t3), np.full_like(t3, 2.0), t3], axis=1)
    rep = chk.check_states(q)
    ok, kappa, _, _ = reference_measures(d, q, "+", "+-+", [])
    assert np.any(rep.reason == "kappa_max")
    np.testing.assert_array_equal(rep.reason[ok] == "kappa_max", kappa[ok] > 4.0)


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(kappa_max=1.0),
        dict(serial_min=0.0),
        dict(serial_min=1.0),
        dict(clearance=-0.1),
        dict(kappa_max=float("nan")),
        dict(clearance="x"),
    ],
)
def test_bad_margins_name_the_field(kwargs):
    field = next(iter(kwargs))
    with pytest.raises(InputError, match=f"margins.{field}"):
        Margins(**kwargs)


def test_bad_checker_arguments():
    with pytest.raises(InputError, match="working_mode"):
        ValidityChecker(Design.default(), Margins(), [], "+", "+x+")
    with pytest.raises(InputError, match="assembly_mode"):
        ValidityChecker(Design.default(), Margins(), [], "0", "+-+")
    chk = ValidityChecker(Design.default(), Margins(), [], "+", "+-+")
    with pytest.raises(InputError, match="q must"):
        chk.check_states([[0.0, np.nan, 1.0]])
    with pytest.raises(InputError, match="shape"):
        chk.is_valid([0.0, 1.0])


@pytest.mark.parametrize("design", DESIGNS[:2], ids=["sing-free", "paper"])
def test_certified_motions_are_valid_when_sampled_densely(design):
    """Every motion the certificate accepts is valid at a 1e-3 rad sampling by the
    independent reference; with a coarse step far above every feature the certificate still
    rejects motions through obstacles (it is not a sampling)."""
    rng = np.random.default_rng(8)
    margins = Margins(kappa_max=8.0, serial_min=0.05, clearance=0.01)
    accepted = rejected = 0
    for asm, mode in [("+", "+-+"), ("-", "-+-"), ("+", "+++")]:
        for coarse in (0.05, 10.0):
            chk = ValidityChecker(design, margins, OBSTACLES, asm, mode, coarse_step=coarse)
            q = rng.uniform(-np.pi, np.pi, (3000, 3))
            good = q[chk.is_valid(q)]
            for a, b in zip(good[:-1:2][:12], good[1::2][:12], strict=False):
                b = a + 1.2 * (b - a) / max(np.abs(b - a).max(), 1.2)  # motions up to 1.2 rad
                if not chk.check_states(b).valid[0]:
                    continue
                if chk.check_motion(a, b).valid:
                    accepted += 1
                    dense = densify(np.stack([a, b]), 1e-3)
                    assert _reference_valid(design, dense, asm, mode, margins, OBSTACLES, 0).all()
                else:
                    rejected += 1
    assert accepted > 10 and rejected >= 3


def test_motion_into_an_obstacle_between_samples_is_rejected():
    d = Design.default()
    chk = ValidityChecker(
        d, Margins(), [Sphere([0.0, 0.0, -0.55], 0.03)], "+", "+-+", coarse_step=100.0
    )
    a = np.array([1.2, 2.0, 1.0])
    b = np.array([1.9, 2.0, 1.0])
    assert chk.check_states(np.stack([a, b])).valid.all()
    mid = np.array([np.pi / 2, 2.0, 1.0])  # the plane passes the sphere on its way
    assert not chk.check_states(mid).valid[0]
    rep = chk.check_motion(a, b)
    assert not rep.valid and rep.reason == "clearance"
    assert chk.check_path(np.stack([a, b])).bad_motion == 0


@pytest.mark.parametrize("design", DESIGNS[:2], ids=["sing-free", "paper"])
def test_lipschitz_rates_bound_finite_differences(design):
    """The constants of the certificate bound the measured change of each margin."""
    from planner.validity._kernels import M_CLEAR_DIST, N_MEASURES, evaluate_many, rates

    rng = np.random.default_rng(2)
    margins = Margins(kappa_max=6.0)
    chk = ValidityChecker(design, margins, OBSTACLES, "+", "+-+")
    worst = 0.0
    for _ in range(60):
        a = rng.uniform(-np.pi, np.pi, 3)
        dq = rng.normal(size=3) * 0.5
        t = np.linspace(0, 1, 2001)
        q = a + t[:, None] * dq
        out = np.empty((len(q), N_MEASURES))
        evaluate_many(q, chk._prm, *chk._packed, True, out)
        inside = out[:, 1] >= 0  # kappa band holds: the rates apply
        bounds = rates(dq[0], dq[1], dq[2], chk._prm)
        # d-margin, serial, every link's clearance, the distal links' clearance (that rate too)
        cols = (1, 2, 3, M_CLEAR_DIST)
        for j, rate in zip(cols, (*bounds[:3], bounds[2]), strict=True):
            g = out[:, j]
            both = inside[1:] & inside[:-1] & np.isfinite(g[1:]) & np.isfinite(g[:-1])
            if both.any():
                slope = np.abs(np.diff(g))[both] / (t[1] - t[0])
                worst = max(worst, float((slope / rate).max()))
                assert np.all(slope <= rate * (1 + 1e-6) + 1e-9)
    assert worst > 0.05  # the bounds are not vacuous


@pytest.mark.parametrize("design", DESIGNS, ids=["sing-free", "paper", "other"])
def test_local_lipschitz_rates_bound_finite_differences(design):
    """The certificate's rates on a piece (planner.validity._kernels.rates_at: the apex sine
    bounded on the piece, the links' distance from the axis AB bounded from the piece's
    ends) bound the measured change of each margin inside that piece, and are tighter than
    the motion's global rates somewhere."""
    from planner.validity._kernels import (
        M_AXIS,
        M_CLEAR_DIST,
        M_KAPPA,
        N_MEASURES,
        evaluate_many,
        rates,
        rates_at,
    )

    rng = np.random.default_rng(21)
    chk = ValidityChecker(design, Margins(kappa_max=6.0), OBSTACLES, "+", "+-+")
    tighter = slower = 0
    for _ in range(60):
        a = rng.uniform(-np.pi, np.pi, 3)
        dq = rng.normal(size=3) * 0.5
        t = np.linspace(0, 1, 2001)
        qs = a + t[:, None] * dq
        out = np.empty((len(t), N_MEASURES))
        evaluate_many(qs, chk._prm, *chk._packed, True, out)
        for _ in range(6):
            i, j = sorted(rng.choice(len(t), 2, replace=False))
            piece = out[i : j + 1]
            if not (piece[:, 1] >= 0).all():
                continue  # the kappa band breaks inside: no rate applies
            kappa = piece[:, M_KAPPA]
            s_min = float((2.0 / (kappa + 1.0 / kappa)).min()) * (1 - 1e-9)  # |sin apex|
            w = t[j] - t[i]
            local = rates_at(*dq, chk._prm, s_min, piece[0, M_AXIS], piece[-1, M_AXIS], w)
            glob = rates(*dq, chk._prm)
            tighter += local[2] < 0.9 * glob[2]
            slower += local[3] < 0.5 * local[2]
            # the proximal links' clearance (an independent route: kinematics and segment
            # distances) changes at most at the proximal rate
            prox = reference_clearance(design, qs[i : j + 1], "+", OBSTACLES, LINKS[:2])
            series = (piece[:, 1], piece[:, 2], piece[:, 3], piece[:, M_CLEAR_DIST], prox)
            for g, rate in zip(series, (*local[:3], local[2], local[3]), strict=True):
                slope = np.abs(np.diff(g)) / (t[1] - t[0])
                ok = np.isfinite(slope)
                assert np.all(slope[ok] <= rate * (1 + 1e-6) + 1e-9), (slope.max(), rate)
    assert tighter > 20
    assert slower > 20  # the proximal links' rate is the smaller one, often by half


def test_check_path_diagnostics():
    d = Design.default()
    chk = ValidityChecker(d, Margins(), [Sphere([0.3, 0.3, 0.3], 0.1)], "+", "+-+")
    w = np.array([[0.0, 2.0, 1.0], [0.3, 2.1, 1.1], [0.6, 2.2, 1.0]])
    rep = chk.check_path(w)
    assert rep.valid and rep.bad_motion == -1
    dense = densify(w, 0.02)
    _, kappa, serial, clear = reference_measures(d, dense, "+", "+-+", chk.obstacles)
    assert rep.max_kappa_A == pytest.approx(kappa.max(), rel=1e-9)
    assert rep.min_serial_margin == pytest.approx(serial.min(), abs=1e-12)
    assert rep.min_clearance == pytest.approx(clear.min(), abs=1e-3)
    assert rep.length == pytest.approx(np.linalg.norm(np.diff(w, axis=0), axis=1).sum())


def test_check_path_clearance_is_the_least_over_its_samples_among_many_obstacles():
    """The diagnostics visit their samples coarse ones first (planner.validity._kernels
    path_extremes): the least clearance is still the least of the same samples, each
    measured alone by the per-posture report, exactly."""
    d = Design.default()
    rng = np.random.default_rng(4)
    centres = rng.uniform(-0.9, 0.9, (400, 3))
    centres = centres[np.linalg.norm(centres, axis=1) > 0.75]
    spheres = [Sphere(c, 0.01) for c in centres]
    chk = ValidityChecker(d, Margins(), spheres, "+", "+-+")
    w = np.array([[-1.0, 2.0, 1.0], [0.4, 2.3, 1.2], [1.5, 2.1, 0.9]])
    rep = chk.check_path(w)
    assert rep.valid
    states = chk.check_states(densify(w, 0.02))
    assert rep.min_clearance == pytest.approx(float(states.clearance.min()), rel=1e-12)
    assert rep.max_kappa_A == pytest.approx(float(states.kappa_A.max()), rel=1e-12)


def test_check_path_extremes_skip_no_sample_that_could_lower_the_clearance():
    """The diagnostics' second pass skips a sample's clearance where the certificate's
    Lipschitz bound keeps it above the running minimum (planner.validity._path_kernels):
    over long certified paths through a cloud of small obstacles (most samples skipped), the
    extremes are those of every sample measured alone, to the bit."""
    d = Design.default()
    rng = np.random.default_rng(8)
    centres = rng.uniform(-1.0, 1.0, (3000, 3))
    centres = centres[np.linalg.norm(centres, axis=1) > 0.8]
    chk = ValidityChecker(d, Margins(), [Sphere(c, 0.005) for c in centres], "+", "+-+")
    paths = 0
    while paths < 6:
        w = np.column_stack(
            [rng.uniform(-2.5, 2.5, 4), rng.uniform(1.2, 2.8, 4), rng.uniform(0.2, 1.8, 4)]
        )
        if not chk.check_states(w).valid.all():
            continue
        rep = chk.check_path(w)
        if not rep.valid:
            continue
        paths += 1
        states = chk.check_states(densify(w, 0.02))
        assert rep.min_clearance == float(states.clearance.min())
        assert rep.max_kappa_A == float(states.kappa_A.max())
        assert rep.min_serial_margin == float(states.serial_margin.min())


def _small_spheres(rng: np.random.Generator) -> ValidityChecker:
    """The default design in modes (+, +-+) among 300 spheres of 2 cm drawn by ``rng``:
    clutter where many motions are refused and many certified."""
    centres = rng.uniform(-0.9, 0.9, (300, 3))
    spheres = [Sphere(c, 0.02) for c in centres]
    return ValidityChecker(Design.default(), Margins(), spheres, "+", "+-+")


def test_an_extension_is_certified_as_its_motion_is():
    """certify_extension (the search's extension test, its new posture evaluated first,
    the tree node's measures given) and certify_between (both ends' measures given) give
    certify_motion's verdict on every motion, from valid and from invalid postures; a broken
    rule of the end posture is the extension's own reason, and the extension leaves the end's
    measures, as measure_posture gives them, for the tree to keep."""
    from planner.validity import (
        MIN_CERTIFIED_STEP,
        N_MEASURES,
        REASONS,
        certify_between,
        certify_extension,
        certify_motion,
        measure_posture,
    )

    rng = np.random.default_rng(12)
    chk = _small_spheres(rng)
    starts = rng.uniform([-2.5, 1.0, 0.2], [2.5, 3.0, 2.0], (400, 3))
    valid = chk.is_valid(starts)
    starts = np.concatenate([starts[valid][:60], starts[~valid][:10]])
    verdicts = {True: 0, False: 0}
    kit = (*chk.packed,)
    for qa in starts:
        ma = np.empty(N_MEASURES)
        measure_posture(qa, chk.params, *kit, ma)
        assert (ma[0] == 0) == bool(chk.is_valid(qa[None])[0])
        for qb in qa + rng.normal(scale=0.3, size=(5, 3)):
            tail = (chk.coarse_step, MIN_CERTIFIED_STEP)
            mb, mb_own = np.empty(N_MEASURES), np.empty(N_MEASURES)
            full = certify_motion(qa, qb, chk.params, *kit, *tail, False)[0]
            measure_posture(qb, chk.params, *kit, mb_own)
            between = certify_between(qa, qb, ma, mb_own, chk.params, *kit, *tail)[0]
            assert (between == 0) == (full == 0)
            if ma[0] != 0:
                continue  # a search extends from valid nodes only
            ext = certify_extension(qa, qb, ma, mb, chk.params, *kit, *tail)
            assert (ext == 0) == (full == 0)
            np.testing.assert_array_equal(mb, mb_own)
            if not chk.is_valid(qb[None])[0]:
                assert REASONS[ext] == chk.check_states(qb).reason[0]
            verdicts[ext == 0] += 1
    assert min(verdicts.values()) > 20  # both verdicts were met


def test_a_motion_blocked_near_a_hint_is_refused_there():
    """blocked_near probes the posture of a motion nearest to a hint (its projection in
    joint space): True only where that posture breaks a rule by the per-posture report, and
    then the certificate refuses the motion; False at the ends and for a motion of no
    length."""
    from planner.validity import (
        MIN_CERTIFIED_STEP,
        N_MEASURES,
        REASONS,
        blocked_near,
        certify_motion,
    )

    rng = np.random.default_rng(13)
    chk = _small_spheres(rng)
    kit = (chk.params, *chk.packed)
    out = np.empty(N_MEASURES)
    blocked = 0
    for _ in range(300):
        qa = rng.uniform([-2.5, 1.0, 0.2], [2.5, 3.0, 2.0])
        qb = qa + rng.normal(scale=0.4, size=3)
        hint = qa + rng.uniform(-0.2, 1.2) * (qb - qa) + rng.normal(scale=0.05, size=3)
        t = float(np.dot(hint - qa, qb - qa) / np.dot(qb - qa, qb - qa))
        got = blocked_near(qa, qb, hint, *kit, out)
        if not 0.0 < t < 1.0:
            assert not got
            continue
        probe = qa + t * (qb - qa)
        assert got == (not chk.is_valid(probe[None])[0])
        if got:
            blocked += 1
            assert chk.check_states(probe).reason[0] == REASONS[int(out[0])]
            assert certify_motion(qa, qb, *kit, chk.coarse_step, MIN_CERTIFIED_STEP, False)[0] != 0
    assert blocked > 30
    assert not blocked_near(qa, qa.copy(), qa, *kit, out)


def test_serial_rules_off_keeps_the_other_rules():
    """A motion onto a serial singularity (leg A stretched) is certified for kappa and
    clearance with the serial rules off, and refused with them on."""
    from planner.kinematics import forward_batch

    d = Design.default()
    far = np.array([-np.pi / 2, 2.0, 1.0])  # the arm's plane turned to contain +z
    chk = ValidityChecker(d, Margins(), [Sphere(forward_batch(d, far, "+").p[0], 0.05)], "+", "+-+")
    off = chk.with_mode("+-+", serial_rules=False)
    a = np.array([0.0, 2.0, 1.0])
    # bisect theta2 towards the first posture whose leg-A measure vanishes
    t2 = np.linspace(2.0, -np.pi, 20001)
    q = np.stack([np.zeros_like(t2), t2, np.ones_like(t2)], axis=1)
    _, _, serial, _ = reference_measures(d, q, "+", "+-+", [])
    k = int(np.argmax(~(serial > 0)))
    assert k > 0
    b = q[k - 1]
    assert chk.check_states(b).reason[0] in ("serial_min", "working_mode")
    assert off.check_states(b).valid[0]
    assert not chk.check_motion(a, b).valid
    assert off.check_motion(a, b).valid
    assert off.check_states(far).reason[0] == "clearance"


def test_the_loop_closes_by_one_rule_in_kinematics_and_validity():
    """Around a stretched CD (|CD| = 2 L2), forward kinematics and the validity rules agree
    posture by posture on whether the loop closes (one closure, one ASSEMBLY_TOL), and the
    boundary lies where |CD|^2 = 4 L2^2 (1 + ASSEMBLY_TOL), computed here in numpy."""
    from planner.constants import ASSEMBLY_TOL
    from planner.kinematics import forward_batch

    d = Design(0.5, 0.4, 0.6)  # |CD| reaches L0 + 2 L1 = 1.3 > 2 L2 = 1.2
    # theta2 = pi puts C at u = -0.65; |CD| = 2 L2 at cos(theta3) = 0.47 / 0.72
    t3 = np.arccos(0.47 / 0.72) + np.arange(-600, 600) * 1e-14
    q = np.stack([np.zeros_like(t3), np.full_like(t3, np.pi), t3], axis=1)
    cu, cw = -d.L0 / 2 + d.L1 * np.cos(q[:, 1]), d.L1 * np.sin(q[:, 1])
    du, dw = d.L0 / 2 + d.L1 * np.cos(q[:, 2]), d.L1 * np.sin(q[:, 2])
    expected = (du - cu) ** 2 + (dw - cw) ** 2 <= 4 * d.L2**2 * (1 + ASSEMBLY_TOL)
    assert 0 < expected.sum() < len(q)  # the scan crosses the boundary
    closes = forward_batch(d, q, "+").ok
    reason = ValidityChecker(d, Margins(), [], "+", "+-+").check_states(q).reason
    assert np.array_equal(closes, expected)
    assert np.array_equal(reason != "assembly", expected)
    assert set(reason[expected]) == {"kappa_max"}  # stretched: kappa(A) is unbounded


def test_motion_test_is_the_certificate_of_check_motion():
    """The callable OMPL's motion validator runs gives check_motion's verdict, motion by
    motion, accepting some motions and rejecting others."""
    rng = np.random.default_rng(5)
    chk = ValidityChecker(Design.default(), Margins(), OBSTACLES, "+", "+-+")
    test = chk.motion_test()
    starts = rng.uniform(-np.pi, np.pi, (400, 3))
    starts = starts[chk.is_valid(starts)]
    verdicts = []
    for a in starts:
        b = a + rng.normal(size=3) * 0.4
        want = chk.check_motion(a, b).valid
        assert test(a.copy(), b) == want
        assert chk.motion_valid(a, b) == want
        verdicts.append(want)
    assert 0 < sum(verdicts) < len(verdicts)


def test_a_checker_family_packs_its_obstacles_once(monkeypatch):
    """``with_mode`` derives checkers of the other modes from one packing of the obstacles
    (a plan with mode changes builds up to eight), and they check alike."""
    from planner.validity import checker as checker_module

    ValidityChecker(Design.default(), Margins(), [], "+", "+++")  # the kernels warm first
    calls = []
    real = checker_module.pack_obstacles
    monkeypatch.setattr(checker_module, "pack_obstacles", lambda obs: calls.append(1) or real(obs))
    obstacles = [Sphere([0.55, -0.02, -0.38], 0.1)]
    base = ValidityChecker(Design.default(), Margins(), obstacles, "+", "+++")
    family = [base.with_mode(m) for m in ("+-+", "++-", "+--")]
    assert len(calls) == 1
    q = np.random.default_rng(3).uniform(-np.pi, np.pi, (500, 3))
    for chk in family:
        fresh = ValidityChecker(Design.default(), Margins(), obstacles, "+", chk.working_mode)
        a, b = chk.check_states(q), fresh.check_states(q)
        assert np.array_equal(a.clearance, b.clearance) and np.array_equal(a.valid, b.valid)
