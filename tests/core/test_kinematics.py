"""Kinematics checked against independent routes: loop-closure geometry written out in 3-D,
finite differences, numpy's SVD, the paper's closed forms (with the errata)."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner import (
    WORKING_MODES,
    AssemblyError,
    Design,
    DesignError,
    InputError,
    Manipulator,
    SingularPostureError,
    conditioning,
    forward_batch,
    inverse_batch,
    link_points,
)
from planner.kinematics import wrap_angle

DESIGNS = [
    Design.default(),
    Design.paper_optimum(),
    Design(L0=0.3, L1=0.25, L2=0.4),
    Design(L0=1.0, L1=0.3, L2=0.5),  # L0 > 2 L1
    Design(L0=0.0, L1=0.2, L2=0.5),
]


def pivots(design: Design) -> tuple[np.ndarray, np.ndarray]:
    return np.array([0.0, -design.L0 / 2, 0.0]), np.array([0.0, design.L0 / 2, 0.0])


def reference_points(design: Design, q: np.ndarray, passive: np.ndarray) -> dict[str, np.ndarray]:
    """Joint centres written out from the conventions, one posture, in 3-D (independent of the
    library: rotation of the in-plane frame by an explicit rotation matrix about +y)."""
    t1, t2, t3 = q
    t4, _ = passive
    # rotation about +y by theta1 maps the x axis to e(theta1) = (cos, 0, -sin)
    rot = np.array([[math.cos(t1), 0, math.sin(t1)], [0, 1, 0], [-math.sin(t1), 0, math.cos(t1)]])
    a, b = pivots(design)

    # plane axes at theta1 = 0: u along +y, w along +x
    def lift(u: float, w: float) -> np.ndarray:
        return rot @ np.array([w, u, 0.0])

    c = a + lift(design.L1 * math.cos(t2), design.L1 * math.sin(t2))
    d = b + lift(design.L1 * math.cos(t3), design.L1 * math.sin(t3))
    p = c + lift(design.L2 * math.cos(t4), design.L2 * math.sin(t4))
    return {"A": a, "B": b, "C": c, "D": d, "P": p}


def random_q(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.uniform(-math.pi, math.pi, size=(n, 3))


# ------------------------------------------------------------------ design
@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"L0": float("nan"), "L1": 1, "L2": 1}, "L0"),
        ({"L0": 0, "L1": 0, "L2": 1}, "L1"),
        ({"L0": 0, "L1": 1, "L2": -1}, "L2"),
        ({"L0": -0.1, "L1": 1, "L2": 1}, "L0"),
        ({"L0": 0, "L1": 1, "L2": float("inf")}, "L2"),
        ({"L0": 0, "L1": 1e9, "L2": 1}, "L1"),
        ({"L0": "x", "L1": 1, "L2": 1}, "L0"),
        ({"L0": 0, "L1": 1, "L2": 1, "link_radius": -1}, "link_radius"),
        (
            {"L0": 0, "L1": 1, "L2": 1, "joint_min": (0, 0, 1), "joint_max": (1, 1, 1)},
            ("joint_min", 2),
        ),
        ({"L0": 0, "L1": 1, "L2": 1, "joint_min": (0, 0)}, "joint_min"),
        ({"L0": 0, "L1": 1, "L2": 1, "joint_min": "abc"}, "joint_min"),
        ({"L0": 0, "L1": 1, "L2": 1, "joint_max": (1, 1, float("nan"))}, "joint_max"),
        ({"L0": 0, "L1": 1, "L2": 1, "joint_max": (1, 1, 100)}, ("joint_max", 2)),
        ({"L0": 0, "L1": 1, "L2": 1, "joint_min": (-100, 0, 0)}, ("joint_min", 0)),
    ],
)
def test_design_rejects_bad_numbers_naming_the_field(kwargs, field):
    """A :class:`DesignError` whose message names the field and whose ``field`` is its wire
    name (an index for one joint limit, the path a request's ``loc`` writes), kept across a
    pickle (errors cross from the worker processes so). Mutant caught: any ``field=`` dropped
    from the raises in ``planner.design`` (the old test matched the message only, with
    ``field`` None in every case)."""
    with pytest.raises(DesignError) as info:
        Design(**kwargs)
    name = field if isinstance(field, str) else f"{field[0]}[{field[1]}]"
    assert name in str(info.value)
    assert info.value.field == field
    assert pickle.loads(pickle.dumps(info.value)).field == field


def test_presets_satisfy_their_claims():
    opt = Design.paper_optimum()
    assert opt.L0 == 0 and opt.L1 == opt.L2
    free = Design.singularity_free()
    assert 2 * free.L1 < free.L0 < 2 * (free.L2 - free.L1)
    assert Design.default() == free


# ------------------------------------------------------------------ forward kinematics
@pytest.mark.parametrize("design", DESIGNS, ids=lambda d: f"L0={d.L0},L1={d.L1},L2={d.L2}")
def test_forward_closes_the_loop_in_3d(design):
    """Every returned posture has |AC| = |BD| = L1, |CP| = |DP| = L2, P in the turned plane,
    points equal to an independent construction, and the assembly sign it claims."""
    rng = np.random.default_rng(1)
    m = Manipulator(design)
    seen = 0
    for q in random_q(rng, 300):
        for post in m.forward(q):
            seen += 1
            ref = reference_points(design, post.q, post.passive)
            for name in "ABCDP":
                np.testing.assert_allclose(post.points[name], ref[name], atol=1e-12)
            pts = post.points
            assert np.linalg.norm(pts["C"] - pts["A"]) == pytest.approx(design.L1, abs=1e-12)
            assert np.linalg.norm(pts["D"] - pts["B"]) == pytest.approx(design.L1, abs=1e-12)
            assert np.linalg.norm(pts["P"] - pts["C"]) == pytest.approx(design.L2, abs=1e-12)
            assert np.linalg.norm(pts["P"] - pts["D"]) == pytest.approx(design.L2, abs=1e-12)
            np.testing.assert_allclose(post.p, pts["P"], atol=1e-12)
            cross = np.cross(pts["P"] - pts["C"], pts["P"] - pts["D"])
            # planar angles grow from u (+y) towards w (e): positive rotation is about y x e
            e = np.array([math.cos(q[0]), 0.0, -math.sin(q[0])])
            expected = "+" if cross @ np.cross([0.0, 1.0, 0.0], e) > 0 else "-"
            assert post.assembly_mode == expected
            np.testing.assert_array_equal(post.q, q)  # literal, not wrapped
    assert seen > 100


def test_forward_two_one_or_no_postures():
    d = Design(L0=0.4, L1=0.3, L2=0.3)
    m = Manipulator(d)
    assert {p.assembly_mode for p in m.forward([0.1, 1.2, 1.9])} == {"+", "-"}
    # legs pointing apart: |CD| = L0 + 2 L1 = 1.0 > 2 L2 = 0.6
    assert m.forward([0.0, math.pi, 0.0]) == []
    with pytest.raises(AssemblyError, match="does not assemble"):
        m.posture([0.0, math.pi, 0.0], "+")
    # CD exactly stretched: |CD| = 2 L2 -> one posture, P the midpoint of CD
    theta = math.acos((2 * d.L2 - d.L0) / (2 * d.L1))  # C, D symmetric above the axis
    q = [0.0, math.pi - theta, theta]
    found = m.forward(q)
    assert len(found) == 1 and found[0].assembly_mode == "0"
    np.testing.assert_allclose(
        found[0].p, (found[0].points["C"] + found[0].points["D"]) / 2, atol=1e-7
    )


def test_forward_with_c_on_d_has_no_posture():
    m = Manipulator(Design.paper_optimum())  # L0 = 0: C = D whenever theta2 = theta3
    assert m.forward([0.3, 0.7, 0.7]) == []
    with pytest.raises(AssemblyError, match="C on D"):
        m.posture([0.3, 0.7, 0.7], "+")


def test_posture_rejects_non_finite_and_bad_shapes():
    m = Manipulator()
    with pytest.raises(InputError, match="finite"):
        m.forward([0.0, float("nan"), 0.0])
    with pytest.raises(InputError, match="shape"):
        m.forward([0.0, 1.0])
    with pytest.raises(InputError, match="assembly_mode"):
        m.posture([0.0, 0.0, 0.0], "x")  # type: ignore[arg-type]


# ------------------------------------------------------------------ inverse kinematics
@st.composite
def design_and_point(draw):
    l1 = draw(st.floats(0.05, 1.0))
    l2 = draw(st.floats(0.05, 1.0))
    l0 = draw(st.floats(0.0, 1.0))
    design = Design(L0=l0, L1=l1, L2=l2)
    q = np.array([draw(st.floats(-math.pi, math.pi)) for _ in range(3)])
    return design, q


@settings(max_examples=300, deadline=None, derandomize=True)
@given(design_and_point())
def test_inverse_of_forward_contains_q_and_recovers_p(case):
    design, q = case
    m = Manipulator(design)
    for post in m.forward(q):
        to_pivot = min(np.linalg.norm(post.p - a) for a in pivots(design))
        if to_pivot == 0.0 and design.L1 == design.L2:  # erratum 6: the leg angle is free
            with pytest.raises(SingularPostureError):
                m.inverse(post.p)
            continue
        if to_pivot < 1e-9 * design.reach:  # ill-conditioned: nothing to compare
            continue
        sols = m.inverse(post.p)
        assert post.working_mode in {s.working_mode for s in sols} or "0" in post.working_mode
        for s in sols:  # every IK posture lands on P and has the mode of its slot
            np.testing.assert_allclose(s.p, post.p, atol=1e-12)
            again = m.posture(s.q, s.assembly_mode) if s.assembly_mode != "0" else None
            if again is not None:
                np.testing.assert_allclose(
                    again.p, post.p, atol=1e-8 * design.reach
                )  # IK rounding grows near singularities
        match = [s for s in sols if s.working_mode == post.working_mode]
        if match and "0" not in post.working_mode:
            np.testing.assert_allclose(wrap_angle(match[0].q - post.q), 0, atol=1e-7)


def test_generic_points_have_exactly_eight_solutions():
    rng = np.random.default_rng(7)
    for design in DESIGNS:
        b = forward_batch(design, random_q(rng, 2000), "+")
        p = b.p[b.ok & ~np.all(b.working_mode_signs == 0, axis=1)]  # not the base point (err. 6)
        ib = inverse_batch(design, p)
        counts = ib.ok.sum(axis=1)
        assert np.all(counts == 8), design
        # every slot's own mode is its label, and every slot lands on P
        labels = np.array(WORKING_MODES)
        for k in range(8):
            signs = ib.working_mode_signs[:, k]
            got = np.array(["".join("+" if s > 0 else "-" for s in row) for row in signs])
            assert np.all(got == labels[k])
        # forward of every IK posture returns P (except C = D ones: P is undetermined there)
        branch = ib.assembly_mode_signs.reshape(-1)
        regular = branch != 0
        assert regular.mean() > 0.45
        back = forward_batch(design, ib.q.reshape(-1, 3)[regular], branch[regular])
        np.testing.assert_allclose(back.p, ib.p.reshape(-1, 3)[regular], atol=1e-10)


def test_unreachable_points_give_an_empty_list():
    m = Manipulator(Design.default())
    assert m.inverse([5.0, 0.0, 0.0]) == []
    assert m.inverse([0.0, 0.0, 0.0]) == []  # inside both inner shells (|L1 - L2| = 0.4 > 0.25)


def test_point_on_axis_has_four_solutions_with_zero_axis_sign():
    d = Design(L0=0.3, L1=0.3, L2=0.4)
    m = Manipulator(d)
    sols = m.inverse([0.0, 0.0, 0.0], theta1_on_axis=0.7)
    assert len(sols) == 4
    assert {s.working_mode for s in sols} == {"0++", "0+-", "0-+", "0--"}
    for s in sols:
        assert s.q[0] == pytest.approx(0.7)
        np.testing.assert_allclose(s.p, [0.0, 0.0, 0.0], atol=1e-12)
        assert m.conditioning(s).P_on_axis == pytest.approx(0.0, abs=1e-15)


def test_stretched_and_folded_legs_are_serial_singular():
    d = Design(L0=0.3, L1=0.3, L2=0.4)
    m = Manipulator(d)
    a = np.array([0.0, -0.15, 0.0])
    # P at distance L1 + L2 from A along a direction: leg A stretched
    direction = np.array([math.cos(0.3), math.sin(0.3), 0.0])
    p = a + (d.L1 + d.L2) * direction
    sols = m.inverse(p)
    assert sols and all(s.working_mode[1] == "0" for s in sols)
    assert len(sols) == 4
    for s in sols:
        assert m.conditioning(s).leg_A < 1e-7
        assert math.cos(s.passive[0] - s.q[1]) > 0  # stretched: theta4 = theta2
    # folded: |AP| = L2 - L1
    p = a + (d.L2 - d.L1) * direction
    sols = m.inverse(p)
    assert sols and all(s.working_mode[1] == "0" for s in sols)
    assert all(math.cos(s.passive[0] - s.q[1]) < 0 for s in sols)


def test_base_point_of_the_paper_optimum_is_degenerate():
    """Erratum 6: with L0 = 0 and L1 = L2, P = A = B for half of the (theta2, theta3) plane."""
    m = Manipulator(Design.paper_optimum())
    with pytest.raises(SingularPostureError):
        m.inverse([0.0, 0.0, 0.0])
    found = m.forward([0.2, 0.3, 1.4])
    base = [p for p in found if np.linalg.norm(p.p) < 1e-12]
    assert len(base) == 1
    c = m.conditioning(base[0])
    assert c.P_on_axis < 1e-12 and c.leg_A < 1e-12 and c.leg_B < 1e-12
    assert math.isinf(c.kappa_B)
    assert base[0].working_mode == "000"


def test_angles_outside_pi_are_handled():
    m = Manipulator(Design.default())
    q = np.array([0.4, -0.3, 0.5])
    shifted = q + np.array([2 * math.pi, -2 * math.pi, 4 * math.pi])
    a, b = m.posture(q, "+"), m.posture(shifted, "+")
    np.testing.assert_allclose(a.p, b.p, atol=1e-12)
    np.testing.assert_array_equal(b.q, shifted)  # kept literal
    assert np.all(np.abs(b.passive) <= math.pi)
    sols = m.inverse(b.p)
    assert all(np.all((s.q > -math.pi) & (s.q <= math.pi)) for s in sols)
    assert wrap_angle(-math.pi) == pytest.approx(math.pi)
    assert wrap_angle(3 * math.pi) == pytest.approx(math.pi)


# ------------------------------------------------------------------ Jacobians
def numeric_dp_dq(m: Manipulator, q: np.ndarray, mode: str, h: float = 1e-6) -> np.ndarray:
    jac = np.zeros((3, 3))
    for j in range(3):
        dq = np.zeros(3)
        dq[j] = h
        jac[:, j] = (m.posture(q + dq, mode).p - m.posture(q - dq, mode).p) / (2 * h)
    return jac


@pytest.mark.parametrize("design", DESIGNS[:4], ids=lambda d: f"L0={d.L0},L1={d.L1},L2={d.L2}")
def test_jacobians_match_finite_differences(design):
    rng = np.random.default_rng(3)
    m = Manipulator(design)
    checked = 0
    for q in random_q(rng, 200):
        for post in m.forward(q):
            c = m.conditioning(post)
            if c.kappa_A > 1e3 or min(c.leg_A, c.leg_B) < 1e-3:
                continue
            a, b = m.jacobians(post)
            jac = numeric_dp_dq(m, post.q, post.assembly_mode)
            np.testing.assert_allclose(a @ jac, b, atol=1e-7 * design.reach**2)
            qd = rng.normal(size=3)
            np.testing.assert_allclose(m.cartesian_velocity(post, qd), jac @ qd, atol=1e-6)
            checked += 1
    assert checked > 50


def test_cartesian_velocity_refuses_parallel_singularity():
    d = Design(L0=0.4, L1=0.3, L2=0.3)
    m = Manipulator(d)
    theta = math.acos((2 * d.L2 - d.L0) / (2 * d.L1))
    post = m.forward([0.0, math.pi - theta, theta])[0]  # CD stretched
    with pytest.raises(SingularPostureError):
        m.cartesian_velocity(post, [0.1, 0.2, 0.3])


# ------------------------------------------------------------------ conditioning
def test_kappa_matches_svd_and_eq6_and_the_paper_where_it_holds():
    rng = np.random.default_rng(5)
    for design in DESIGNS[:4]:
        m = Manipulator(design)
        for q in random_q(rng, 100):
            for post in m.forward(q):
                a, b = m.jacobians(post)
                c = m.conditioning(post)
                sv = np.linalg.svd(a, compute_uv=False)
                assert c.kappa_A == pytest.approx(sv[0] / sv[-1], rel=1e-6)
                delta = post.passive[0] - post.passive[1]
                cos = math.cos(delta)
                expected = design.L2**2 * np.array([[1, 0, 0], [0, 1, cos], [0, cos, 1]])
                np.testing.assert_allclose(a @ a.T, expected, atol=1e-12)
                wrapped = float(wrap_angle(delta))
                if abs(wrapped) <= math.pi / 2:
                    assert c.kappa_A == pytest.approx(1 / abs(math.tan(wrapped / 2)), rel=1e-9)
                else:  # the paper's form drops below 1 there (erratum 2)
                    assert 1 / abs(math.tan(wrapped / 2)) < 1 <= c.kappa_A
                diag = np.abs(np.diag(b))
                if diag.min() == 0.0:
                    assert math.isinf(c.kappa_B)
                else:
                    assert c.kappa_B == pytest.approx(diag.max() / diag.min(), rel=1e-9)
                # parallel margin: angular distance of delta to k*pi
                k = round(delta / math.pi)
                assert c.parallel == pytest.approx(abs(delta - k * math.pi), abs=1e-12)


def reference_a(design: Design, q: np.ndarray, passive: np.ndarray) -> np.ndarray:
    """A = [L2 k^T; (p - c)^T; (p - d)^T] of eq. (3) from :func:`reference_points`, with k
    the plane normal e(theta1) x y."""
    pts = reference_points(design, q, passive)
    e = np.array([math.cos(q[0]), 0.0, -math.sin(q[0])])
    k = np.cross(e, [0.0, 1.0, 0.0])
    return np.stack([design.L2 * k, pts["P"] - pts["C"], pts["P"] - pts["D"]])


def test_a_is_singular_only_at_k_pi_erratum_1():
    """Erratum 1 (section 2.5): eq. (6) gives det(A A^T) = L2^6 (1 - cos^2(theta4 - theta5)),
    so |det A| = L2^3 |sin(theta4 - theta5)|: A is singular only at theta4 - theta5 = k pi
    and best at odd multiples of pi/2, where the paper says it is singular."""
    rng = np.random.default_rng(21)
    seen_right_angle = seen_near_pi = 0
    for design in DESIGNS[:4]:
        b = forward_batch(design, random_q(rng, 4000), "+")
        for i in np.flatnonzero(b.ok)[:1500]:
            delta = b.passive[i, 0] - b.passive[i, 1]
            det = abs(np.linalg.det(reference_a(design, b.q[i], b.passive[i])))
            assert det == pytest.approx(design.L2**3 * abs(math.sin(delta)), abs=1e-12)
            if abs(math.cos(delta)) < 0.01:  # delta within 0.01 rad of +-pi/2
                assert det > 0.999 * design.L2**3
                seen_right_angle += 1
            if abs(math.sin(delta)) < 0.01:  # delta near k pi
                assert det < 0.011 * design.L2**3
                seen_near_pi += 1
    assert seen_right_angle > 10 and seen_near_pi > 3


def test_isotropy_follows_theta4_minus_theta5_not_theta3_minus_theta4_erratum_3():
    """Erratum 3 (section 3.4): kappa(A) = 1 where |theta4 - theta5| = pi/2 (mod pi), while
    |theta3 - theta4| = pi/2 says nothing about it. kappa from numpy's SVD of A."""
    design = Design(L0=0.3, L1=0.25, L2=0.4)
    b = forward_batch(design, random_q(np.random.default_rng(22), 200_000), "+")
    ok = b.ok
    t3, t4, t5 = b.q[ok, 2], b.passive[ok, 0], b.passive[ok, 1]
    right = np.flatnonzero(np.abs(np.cos(t4 - t5)) < 1e-3)
    paper = np.flatnonzero(np.abs(np.cos(t3 - t4)) < 1e-3)
    assert len(right) > 20 and len(paper) > 20

    def kappa(i: int) -> float:
        a = reference_a(design, b.q[ok][i], b.passive[ok][i])
        sv = np.linalg.svd(a, compute_uv=False)
        return float(sv[0] / sv[-1])

    assert max(kappa(i) for i in right[:50]) < 1.0021  # isotropic up to the 1e-3 window
    worst = max(kappa(i) for i in paper[:200])
    assert worst > 2.0  # the paper's condition admits badly conditioned postures


def test_isotropy_at_right_angle():
    d = Design.default()
    m = Manipulator(d)
    rng = np.random.default_rng(11)
    best = min(
        (
            abs(abs(float(wrap_angle(p.passive[0] - p.passive[1]))) - math.pi / 2),
            m.conditioning(p).kappa_A,
        )
        for q in random_q(rng, 400)
        for p in m.forward(q)
    )
    assert best[0] < 0.05 and best[1] < 1.06


def test_paper_optimum_equal_sign_modes_are_parallel_singular():
    d = Design.paper_optimum()
    rng = np.random.default_rng(2)
    b = forward_batch(d, random_q(rng, 500), "+")
    keep = b.ok & (np.linalg.norm(b.p, axis=1) > 1e-6)
    ib = inverse_batch(d, b.p[keep])
    cond = conditioning(d, ib.q, ib.passive, ib.w)
    signs = ib.working_mode_signs
    same = (signs[..., 1] == signs[..., 2]) & ib.ok
    diff = (signs[..., 1] != signs[..., 2]) & ib.ok
    assert same.sum() > 100 and diff.sum() > 100
    assert np.all(cond.kappa_A[same] > 1e6)  # C = D
    pts = link_points(d, ib.q, ib.passive)
    np.testing.assert_allclose(pts[same][:, 2], pts[same][:, 3], atol=1e-9)
    assert np.median(cond.kappa_A[diff]) < 10


def test_vectorised_and_scalar_forms_agree():
    d = Design(L0=0.3, L1=0.25, L2=0.4)
    m = Manipulator(d)
    rng = np.random.default_rng(9)
    q = random_q(rng, 200)
    for mode in "+-":
        b = forward_batch(d, q, mode)
        cond = conditioning(d, b.q, b.passive, b.w)
        for i in range(len(q)):
            found = [p for p in m.forward(q[i]) if p.assembly_mode == mode]
            assert bool(b.ok[i]) == bool(found)
            if found:
                np.testing.assert_allclose(found[0].p, b.p[i], atol=1e-14)
                np.testing.assert_allclose(found[0].passive, b.passive[i], atol=1e-14)
                c = m.conditioning(found[0])
                assert c.kappa_A == pytest.approx(cond.kappa_A[i], rel=1e-12)
                assert c.leg_B == pytest.approx(cond.leg_B[i], rel=1e-12)
    ib = inverse_batch(d, b.p[b.ok][:20])
    for i in range(20):
        sols = m.inverse(b.p[b.ok][i])
        assert [s.working_mode for s in sols] == [
            WORKING_MODES[k] for k in np.flatnonzero(ib.ok[i])
        ]


def test_batch_inputs_are_validated():
    d = Design.default()
    with pytest.raises(InputError, match="q must have shape"):
        forward_batch(d, np.zeros((4, 2)), "+")
    with pytest.raises(InputError, match="finite"):
        inverse_batch(d, np.array([[0.0, np.inf, 0.0]]))
    with pytest.raises(InputError, match="assembly_mode"):
        forward_batch(d, np.zeros((2, 3)), np.array([1, 0]))


def test_mode_signs_inverts_mode_label():
    from planner.kinematics import mode_label, mode_signs

    for label in [*WORKING_MODES, "0+-", "000", "+", "-"]:
        assert mode_label(mode_signs(label)) == label
    np.testing.assert_array_equal(mode_signs("+-0"), [1, -1, 0])


@pytest.mark.parametrize("design", [Design.default(), Design(0.6, 0.25, 0.45)])
def test_inverse_in_mode_is_one_slot_of_inverse_batch(design):
    """inverse_in_mode(p, slot) gives slot ``slot`` of inverse_batch exactly (q, passive,
    w, ok, degenerate, assembly signs), also on the axis and at a pivot; and where ok, its
    posture's forward kinematics is P again, in that working mode."""
    from planner.kinematics import inverse_in_mode, mode_signs

    rng = np.random.default_rng(5)
    p = rng.uniform(-1.0, 1.0, (3000, 3))
    p[:20, 0] = p[:20, 2] = 0.0  # on the axis AB
    p[20:30] = [0.0, -design.L0 / 2, 0.0]  # at A
    ib = inverse_batch(design, p)
    for slot, mode in enumerate(WORKING_MODES):
        q, passive, w, ok, degenerate, signs = inverse_in_mode(design, p, slot)
        np.testing.assert_array_equal(q, ib.q[:, slot])
        np.testing.assert_array_equal(passive, ib.passive[:, slot])
        np.testing.assert_array_equal(w, ib.w[:, slot])
        np.testing.assert_array_equal(ok, ib.ok[:, slot])
        np.testing.assert_array_equal(degenerate, ib.degenerate)
        np.testing.assert_array_equal(signs, ib.assembly_mode_signs[:, slot])
        good = ok & ~degenerate
        assert good.sum() > 100
        for asm in ("+", "-"):
            sel = good & (signs == (1 if asm == "+" else -1))
            fb = forward_batch(design, q[sel], asm)
            np.testing.assert_allclose(fb.p, p[sel], atol=1e-9)
            sg = fb.working_mode_signs
            off_singular = np.all(sg != 0, axis=1)
            assert np.all(sg[off_singular] == mode_signs(mode))


@pytest.mark.parametrize("design", DESIGNS[:4], ids=lambda d: f"L0={d.L0},L1={d.L1},L2={d.L2}")
def test_forward_velocity_matches_the_jacobians_and_finite_differences(design):
    """forward_velocity (the loop closure differentiated, batched) against two routes: the
    Jacobians' A v = B qd of Manipulator.cartesian_velocity, and central differences of
    forward_batch; P itself is forward_batch's bitwise."""
    from planner.kinematics import forward_velocity

    rng = np.random.default_rng(4)
    m = Manipulator(design)
    q_all, qd_all, asm_all, ref = [], [], [], []
    for q in random_q(rng, 200):
        for post in m.forward(q):
            c = m.conditioning(post)
            if c.kappa_A > 1e3:
                continue
            qd = rng.normal(size=3)
            q_all.append(post.q)
            qd_all.append(qd)
            asm_all.append(1 if post.assembly_mode == "+" else -1)
            ref.append(m.cartesian_velocity(post, qd))
    q, qd, asm = np.array(q_all), np.array(qd_all), np.array(asm_all)
    assert len(q) > 50
    p, v, ok = forward_velocity(design, q, qd, asm)
    assert ok.all()
    np.testing.assert_array_equal(p, forward_batch(design, q, asm).p)
    scale = np.linalg.norm(np.array(ref), axis=1, keepdims=True) + design.reach
    np.testing.assert_allclose(v / scale, np.array(ref) / scale, atol=1e-9)
    h = 1e-6
    fd = (forward_batch(design, q + h * qd, asm).p - forward_batch(design, q - h * qd, asm).p) / (
        2 * h
    )
    np.testing.assert_allclose(v / scale, fd / scale, atol=1e-6)
    # at rest the velocity is zero; postures that do not close are refused as forward_batch
    # refuses them
    _, v0, _ = forward_velocity(design, q[:3], np.zeros((3, 3)), asm[:3])
    assert np.all(v0 == 0.0)
    qr = np.array(list(random_q(rng, 500)))
    closes = forward_batch(design, qr, "+").ok
    np.testing.assert_array_equal(forward_velocity(design, qr, np.ones_like(qr), "+")[2], closes)


def test_single_postures_are_the_vectorised_forms_bit_for_bit() -> None:
    """``Manipulator.forward`` / ``inverse`` build their few postures in plain floats
    (kinematics._postures): every point, mode and the assembly mode equal, to the bit, what
    the vectorised functions give for the same joints (link_points, the batch's signs)."""
    from planner.kinematics import mode_label

    rng = np.random.default_rng(7)
    checked = 0
    for design in (Design.default(), Design.singularity_free()):
        m = Manipulator(design)
        for _ in range(300):
            q = rng.uniform(-3.2, 3.2, 3)
            p = rng.uniform(-0.7, 0.7, 3)
            forward = forward_batch(design, np.stack([q, q]), np.array([1.0, -1.0]))
            inverse = inverse_batch(design, p)
            for batch, found in ((forward, m.forward(q)), (inverse, m.inverse(p))):
                ok = batch.ok.reshape(-1)
                q_ok = batch.q.reshape(-1, 3)[ok]
                passive = batch.passive.reshape(-1, 2)[ok]
                points = link_points(design, q_ok, passive)
                working = batch.working_mode_signs.reshape(-1, 3)[ok]
                assembly = batch.assembly_mode_signs.reshape(-1)[ok]
                if batch is forward and len(found) == 1 and ok.sum() == 2:
                    ok_rows = [0]  # both assembly modes met: forward keeps the first
                else:
                    ok_rows = list(range(len(found)))
                    assert len(found) == int(ok.sum())
                for i, post in zip(ok_rows, found, strict=True):
                    assert np.array_equal(np.stack([post.points[k] for k in "ABCDP"]), points[i])
                    assert post.working_mode == mode_label(working[i])
                    assert post.assembly_mode == mode_label(assembly[i])
                    assert np.array_equal(post.q, q_ok[i])
                    checked += 1
    assert checked > 500


def test_within_limits_of_one_posture_is_the_array_rule() -> None:
    """One posture's limit check (plain floats) answers as the array rule, on the boundary
    and with NaN too."""
    design = Design(
        L0=0.5,
        L1=0.2,
        L2=0.6,
        link_radius=0.02,
        joint_min=(-1.0, 0.0, 0.5),
        joint_max=(1.0, 2.0, 3.0),
    )
    m = Manipulator(design)
    rng = np.random.default_rng(3)
    qs = [*rng.uniform(-3.5, 3.5, (2000, 3)), np.array([-1.0, 0.0, 3.0]), np.array([1.0, 2.0, 0.5])]
    qs.append(np.array([0.0, np.nan, 1.0]))
    answers = set()
    for q in qs:
        expected = bool((q >= design.joint_min).all() and (q <= design.joint_max).all())
        assert m.within_limits(q) == expected
        assert m.within_limits(q.tolist()) == expected
        answers.add(expected)
    assert answers == {True, False}


def test_one_posture_is_the_batch_route_bit_for_bit() -> None:
    """``Manipulator.posture`` builds its one posture without the batch's arrays
    (kinematics._one_posture): every array, point and mode equal, to the bit, what the batch
    route gives (forward_batch, then kinematics._postures) for the same joints, in both
    assembly modes, and an AssemblyError exactly where the batch's loop does not close."""
    from planner.kinematics import _postures

    rng = np.random.default_rng(11)
    built = refused = 0
    # the last: the loop does not close for about half the joints (|CD| up to 1.0 > 2 L2)
    for design in (Design.default(), Design.singularity_free(), Design(L0=0.4, L1=0.3, L2=0.3)):
        m = Manipulator(design)
        qs = rng.uniform(-3.2, 3.2, (300, 3))
        for mode in ("+", "-"):
            batch = forward_batch(design, qs, mode)
            for i, q in enumerate(qs):
                if not batch.ok[i]:
                    with pytest.raises(AssemblyError):
                        m.posture(q, mode)
                    refused += 1
                    continue
                one = forward_batch(design, q, mode)  # the batch route for this q alone
                (expected,) = _postures(one)
                post = m.posture(q, mode)
                for name in ("q", "passive", "p"):
                    got, want = getattr(post, name), getattr(expected, name)
                    assert got.tobytes() == want.tobytes(), name
                    assert getattr(batch, name)[i].tobytes() == want.tobytes(), name
                    assert not got.flags.writeable
                for k in "ABCDP":
                    assert post.points[k].tobytes() == expected.points[k].tobytes(), k
                assert post.working_mode == expected.working_mode
                assert post.assembly_mode == expected.assembly_mode
                assert post.w == expected.w
                built += 1
    assert built > 1200 and refused > 100
