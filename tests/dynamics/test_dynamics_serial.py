"""The serial counterpart (planner.dynamics.serial) against its energy: M as the Hessian of
the kinetic energy and the power balance of its torques, both from finite differences of the
arm's 3-D body motion (joint centres from the product's ``link_points``, never from M)."""

from __future__ import annotations

import numpy as np
import pytest

from planner import Design, link_points
from planner.dynamics import Inertia, LinkInertia
from planner.dynamics.serial import SerialArm, serial_coordinates, serial_motion

ODD = Inertia(
    LinkInertia(0.7, 0.3, 0.004, 0.0075),
    LinkInertia(1.1, 0.65, 0.02, 0.001),
    0.8,
    0.03,
    (0.002, 0.001, 0.003),
)
ARMS = {
    "default": SerialArm(Design.default(), Inertia.default(Design.default())),
    "odd": SerialArm(Design(L0=0.3, L1=0.25, L2=0.45), ODD, elbow_mass=0.9, base_inertia=0.01),
}


def _bodies(arm: SerialArm, qs: np.ndarray):
    """A, C, P (N, 3) in 3-D and the frames (N, 2, 3, 3) of AC and CP: columns
    [e_link, k x e_link, k], k the plane's normal."""
    passive = np.stack([qs[:, 1] + qs[:, 2], np.zeros(len(qs))], axis=1)
    pts = link_points(arm.design, qs, passive)  # rows A, B, C, D, P; leg B unused
    a, c, p = pts[:, 0], pts[:, 2], pts[:, 4]
    t1 = qs[:, 0]
    k = np.stack([np.sin(t1), np.zeros_like(t1), np.cos(t1)], axis=1)
    frames = []
    for x0, x1 in ((a, c), (c, p)):
        e = (x1 - x0) / np.linalg.norm(x1 - x0, axis=1, keepdims=True)
        frames.append(np.stack([e, np.cross(k, e), k], axis=2))
    return (a, c, p), np.stack(frames, axis=1)


def _masses(arm: SerialArm, a, c, p):
    i = arm.inertia
    return [(i.proximal.mass, a + i.proximal.com * (c - a)),
            (i.distal.mass, c + i.distal.com * (p - c)),
            (arm.elbow_mass, c), (i.payload_mass, p)]  # fmt: skip


def _kinetic(arm: SerialArm, qm: np.ndarray, qp: np.ndarray, q0: np.ndarray, h: float):
    """Kinetic energy of the motion through q0 with postures qm, qp at -h, +h."""
    (am, cm, pm), rm = _bodies(arm, qm)
    (ap, cp, pp), rp = _bodies(arm, qp)
    _, r0 = _bodies(arm, q0)
    qd = (qp - qm) / (2 * h)
    ke = 0.5 * arm.base_inertia * qd[:, 0] ** 2 + 0.5 * np.sum(arm.inertia.rotor_array * qd**2, 1)
    for (m, xm), (_, xp) in zip(_masses(arm, am, cm, pm), _masses(arm, ap, cp, pp), strict=True):
        ke += 0.5 * m * np.sum(((xp - xm) / (2 * h)) ** 2, axis=1)
    for j, link in enumerate((arm.inertia.proximal, arm.inertia.distal)):
        w_skew = (rp[:, j] - rm[:, j]) / (2 * h) @ np.swapaxes(r0[:, j], 1, 2)
        omega = np.stack([w_skew[:, 2, 1], w_skew[:, 0, 2], w_skew[:, 1, 0]], axis=1)
        body = np.einsum("nji,nj->ni", r0[:, j], omega)
        ke += 0.5 * (link.I_axial * body[:, 0] ** 2 + link.I_perp * np.sum(body[:, 1:] ** 2, 1))
    return ke


def _potential(arm: SerialArm, qs: np.ndarray, g: np.ndarray) -> np.ndarray:
    (a, c, p), _ = _bodies(arm, qs)
    return -sum(m * (x @ g) for m, x in _masses(arm, a, c, p))


@pytest.mark.parametrize("name", sorted(ARMS))
def test_serial_mass_matrix_is_the_kinetic_energy_hessian(name: str) -> None:
    """M_ij = (T(e_i + e_j) - T(e_i - e_j)) / 2 with T from central differences (h = 1e-6)
    of the bodies' 3-D motion; to 1e-7 of |M| (the differences are good to ~1e-10)."""
    arm = ARMS[name]
    qs = np.random.default_rng(3).uniform([-3, 0.2, -2.8], [3, 2.9, 2.8], size=(40, 3))
    h, eye = 1e-6, np.eye(3)

    def ke(direction: np.ndarray) -> np.ndarray:
        return _kinetic(arm, qs - h * direction, qs + h * direction, qs, h)

    ref = np.empty((len(qs), 3, 3))
    for i in range(3):
        for j in range(3):
            ref[:, i, j] = (ke(eye[i] + eye[j]) - ke(eye[i] - eye[j])) / 2
    m = arm.mass_matrix(qs)
    scale = np.max(np.abs(m), axis=(1, 2))[:, None, None]
    np.testing.assert_array_less(np.abs(m - ref) / scale, 1e-7)
    assert np.all(np.linalg.eigvalsh(m) > 0)


@pytest.mark.parametrize("name", sorted(ARMS))
def test_serial_torques_balance_the_power(name: str) -> None:
    """sum(tau qd) = dE/dt along a smooth motion (E = T + V from the bodies' finite
    differences), to 1e-5 of the largest power term, as for the five-bar."""
    arm = ARMS[name]
    g = np.array([0.5, -1.0, -9.81])
    rng = np.random.default_rng(11)
    q0 = np.array([0.3, 1.4, 0.9])
    amp, om, ph = (
        rng.uniform(-0.3, 0.3, (3, 3)),
        rng.uniform(1, 4, (3, 3)),
        rng.uniform(0, 6, (3, 3)),
    )

    def q(t):
        return q0 + np.sum(amp * np.sin(om * t[:, None, None] + ph), axis=1)

    def qd(t):
        return np.sum(amp * om * np.cos(om * t[:, None, None] + ph), axis=1)

    def qdd(t):
        return np.sum(-amp * om**2 * np.sin(om * t[:, None, None] + ph), axis=1)

    def energy(t, h=1e-5):
        return _kinetic(arm, q(t - h), q(t + h), q(t), h) + _potential(arm, q(t), g)

    t = np.linspace(0.1, 2.0, 60)
    tau = arm.inverse_dynamics(q(t), qd(t), qdd(t), gravity=g)
    power = np.sum(tau * qd(t), axis=1)
    hh = 1e-4
    de_dt = (energy(t + hh) - energy(t - hh)) / (2 * hh)
    scale = np.max(np.abs(tau * qd(t)))
    np.testing.assert_allclose(power, de_dt, rtol=0, atol=1e-5 * scale)
    assert scale > 1.0  # a real motion, not a trivial one


def test_serial_arm_is_leg_a_of_the_five_bar() -> None:
    """In serial_coordinates of a five-bar posture the arm's P is the five-bar's P."""
    from planner import forward_batch

    design = Design.default()
    arm = ARMS["default"]
    q = np.array([[0.2, 2.0, 1.0], [-1.0, 1.7, 0.6]])
    fb = forward_batch(design, q, "+")
    qs = serial_coordinates(fb.q, fb.passive)
    uw = arm.points(qs)["P"]
    p = np.stack([uw[:, 1] * np.cos(q[:, 0]), uw[:, 0], -uw[:, 1] * np.sin(q[:, 0])], axis=1)
    np.testing.assert_allclose(p, fb.p, atol=1e-12)
    assert arm.base_inertia == pytest.approx(arm.inertia.base_inertia / 2)


def test_serial_motion_is_the_derivative_of_leg_a() -> None:
    """serial_motion's rates against central differences in time of the forward kinematics'
    passive angle along a smooth motion (h = 1e-4 s: 1e-7 for the rates, 1e-5 for the
    accelerations, against values of order 1)."""
    from planner import forward_batch

    design = Design.default()
    q0, amp, om = np.array([0.1, 2.0, 1.0]), np.array([0.3, 0.2, -0.25]), np.array([1.3, 2.1, 0.7])

    def q(t):
        return q0 + amp * np.sin(om * t[:, None])

    def serial_q(t):
        fb = forward_batch(design, q(t), "+")
        return serial_coordinates(fb.q, fb.passive)

    t, h = np.linspace(0.0, 3.0, 25), 1e-4
    qd = amp * om * np.cos(om * t[:, None])
    qdd = -amp * om**2 * np.sin(om * t[:, None])
    qs, qsd, qsdd = serial_motion(design, q(t), qd, qdd)
    np.testing.assert_allclose(qs, serial_q(t), atol=1e-12)
    np.testing.assert_allclose(qsd, (serial_q(t + h) - serial_q(t - h)) / (2 * h), atol=1e-7)
    fd2 = (serial_q(t + h) - 2 * serial_q(t) + serial_q(t - h)) / h**2
    np.testing.assert_allclose(qsdd, fd2, atol=1e-5)
    assert np.max(np.abs(qsdd[:, 2])) > 0.1
