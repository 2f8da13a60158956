"""The inverse dynamics against the robot's energy (tests/dynamics/dynamics_reference.py):
the power balance along random smooth motions and the mass matrix as the kinetic energy's
Hessian, both from finite differences of the forward kinematics, never from M."""

from __future__ import annotations

import numpy as np
import pytest
from dynamics_reference import energy_along, mass_matrix_by_polarisation, random_postures

from planner import Design, forward_batch
from planner.dynamics import Inertia, LinkInertia, inverse_dynamics, mass_matrix

DESIGNS = {
    "default": Design.default(),
    "paper-optimum": Design.paper_optimum(),
    "skewed": Design(L0=0.3, L1=0.25, L2=0.45, link_radius=0.015),
}
#: An inertia whose every term differs (COMs off centre, a fat link's axial moment near its
#: bound) so that no term hides behind a symmetry of the defaults.
ODD = Inertia(
    proximal=LinkInertia(0.7, 0.3, 0.004, 0.0075),
    distal=LinkInertia(1.1, 0.65, 0.02, 0.001),
    payload_mass=0.8,
    base_inertia=0.03,
    rotor=(0.002, 0.001, 0.003),
)


def _motion(seed: int, q0: np.ndarray):
    """A smooth motion q(t) = q0 + sum of 3 sines per joint (amplitudes <= 0.12 rad), with
    its exact qd and qdd."""
    rng = np.random.default_rng(seed)
    amp = rng.uniform(-0.04, 0.04, size=(3, 3))
    om = rng.uniform(0.5, 4.0, size=(3, 3))
    ph = rng.uniform(0, 2 * np.pi, size=(3, 3))

    def q(t: np.ndarray) -> np.ndarray:
        return q0 + np.sum(amp * np.sin(om * t[:, None, None] + ph), axis=1)

    def qd(t: np.ndarray) -> np.ndarray:
        return np.sum(amp * om * np.cos(om * t[:, None, None] + ph), axis=1)

    def qdd(t: np.ndarray) -> np.ndarray:
        return np.sum(-amp * om**2 * np.sin(om * t[:, None, None] + ph), axis=1)

    return q, qd, qdd


@pytest.mark.parametrize("name", sorted(DESIGNS))
@pytest.mark.parametrize("mode", ["+", "-"])
@pytest.mark.parametrize("inertia_kind", ["default", "odd"])
def test_power_balance_along_random_motions(name: str, mode: str, inertia_kind: str) -> None:
    """sum(tau qd) = dE/dt (kinetic + potential), E from the bodies' finite-difference
    velocities. Tolerance 1e-5 of the largest power term: the velocities' central differences
    (h = 1e-5 s) are good to ~1e-10 relative, and dE/dt's (h = 1e-4 s) carries the rounding of
    E, ~1e-11 E / 1e-4, i.e. ~1e-7 relative; 1e-5 leaves room and still catches any wrong
    term (a dropped Coriolis term or a sign is of order 1)."""
    design = DESIGNS[name]
    inertia = Inertia.default(design) if inertia_kind == "default" else ODD
    g = np.array([0.7, -2.0, -9.81])  # gravity off the axes: every component acts
    checked = 0
    for seed, q0 in enumerate(random_postures(design, mode, 6, seed=11, kappa_max=8.0)):
        q, qd, qdd = _motion(seed, q0)
        t = np.linspace(0.0, 2.0, 41)
        if not np.all(forward_batch(design, q(np.linspace(-0.1, 2.1, 400)), mode).ok):
            continue
        tau = inverse_dynamics(
            design, inertia, q(t), qd(t), qdd(t), assembly_mode=mode, gravity=g
        ).tau
        power = np.sum(tau * qd(t), axis=1)
        h = 1e-4
        de_dt = (
            energy_along(design, inertia, mode, q, t + h, g)
            - energy_along(design, inertia, mode, q, t - h, g)
        ) / (2 * h)
        scale = np.max(np.abs(tau * qd(t))) + 1e-12
        np.testing.assert_allclose(power, de_dt, rtol=0, atol=1e-5 * scale)
        checked += 1
    assert checked >= 3


@pytest.mark.parametrize("name", sorted(DESIGNS))
@pytest.mark.parametrize("mode", ["+", "-"])
def test_mass_matrix_is_the_hessian_of_the_kinetic_energy(name: str, mode: str) -> None:
    """M(q) against the Hessian in qd of T from finite differences of the bodies (step 1e-6
    rad: truncation ~1e-12, rounding ~1e-10 of each velocity); tolerance 1e-7 of |M|. Also
    symmetric positive definite, and the same from inverse_dynamics(with_mass_matrix)."""
    design = DESIGNS[name]
    q = random_postures(design, mode, 40, seed=5)
    for inertia in (Inertia.default(design), ODD):
        m = mass_matrix(design, inertia, q, assembly_mode=mode)
        ref = mass_matrix_by_polarisation(design, inertia, mode, q)
        scale = np.max(np.abs(ref), axis=(1, 2))[:, None, None]
        assert np.all(np.abs(m - ref) <= 1e-7 * scale)
        np.testing.assert_array_equal(m, np.swapaxes(m, 1, 2))
        assert np.all(np.linalg.eigvalsh(m) > 0)
        batch = inverse_dynamics(
            design,
            inertia,
            q,
            np.zeros_like(q),
            np.zeros_like(q),
            assembly_mode=mode,
            with_mass_matrix=True,
        )
        np.testing.assert_array_equal(batch.mass_matrix, m)


def test_torques_split_as_m_qdd_plus_h() -> None:
    """tau(q, qd, qdd) = M(q) qdd + tau(q, qd, 0): the torques are affine in qdd with the
    mass matrix as slope (to rounding)."""
    design = DESIGNS["skewed"]
    q = random_postures(design, "+", 50, seed=2)
    rng = np.random.default_rng(3)
    qd, qdd = rng.normal(size=q.shape), rng.normal(size=q.shape) * 5
    full = inverse_dynamics(design, ODD, q, qd, qdd, with_mass_matrix=True)
    h = inverse_dynamics(design, ODD, q, qd, np.zeros_like(q)).tau
    np.testing.assert_allclose(
        full.tau,
        np.einsum("nij,nj->ni", full.mass_matrix, qdd) + h,
        atol=1e-10 * np.max(np.abs(full.tau)),
    )


def test_gravity_torque_is_the_gradient_of_the_potential() -> None:
    """At rest, tau = dV/dq (V = -sum m g.x from the joint centres), by central differences."""
    from dynamics_reference import potential_energy

    design = DESIGNS["default"]
    inertia = Inertia.default(design)
    g = np.array([0.0, 0.0, -9.81])
    q = random_postures(design, "-", 30, seed=8)
    tau = inverse_dynamics(design, inertia, q, 0 * q, 0 * q, assembly_mode="-").tau
    h = 1e-6
    grad = np.stack(
        [
            (
                potential_energy(design, inertia, "-", q + h * e, g)
                - potential_energy(design, inertia, "-", q - h * e, g)
            )
            / (2 * h)
            for e in np.eye(3)
        ],
        axis=1,
    )
    np.testing.assert_allclose(tau, grad, atol=1e-7)


def _stretched_theta3(design: Design, t2: float) -> float:
    """A theta3 where |CD| = 2 L2 (CD stretched), approached from the assembled side: a scan
    for the sign change of |CD| - 2 L2, then bisection; the returned value assembles."""

    def gap(t3: np.ndarray) -> np.ndarray:
        du = design.L0 + design.L1 * (np.cos(t3) - np.cos(t2))
        dw = design.L1 * (np.sin(t3) - np.sin(t2))
        return np.hypot(du, dw) - 2 * design.L2

    ts = np.linspace(t2, t2 + 2 * np.pi, 4001)
    k = int(np.argmax((gap(ts[:-1]) < 0) & (gap(ts[1:]) >= 0)))
    lo, hi = ts[k], ts[k + 1]
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if gap(np.array(mid)) < 0 else (lo, mid)
    return float(lo)


def test_singular_and_unassembled_postures_are_flagged() -> None:
    """A posture that does not assemble, or sits on a parallel singularity (C = D on the
    paper's optimum), has ok False and NaN torques; approaching the CD-stretched singularity,
    the largest eigenvalue of M grows like kappa(A)^2 (the passive rates like 1 / sin)."""
    design = Design.paper_optimum()
    inertia = Inertia.default(design)
    q = np.array([[0.0, 1.0, 1.0], [0.0, 0.0, np.pi], [0.0, 1.0, 1.3]])
    b = inverse_dynamics(design, inertia, q, 0 * q, 0 * q, with_mass_matrix=True)
    assert b.ok.tolist() == [False, False, True]
    assert np.all(np.isnan(b.tau[:2])) and np.all(np.isnan(b.mass_matrix[:2]))
    assert np.all(np.isfinite(b.tau[2]))
    design = Design(L0=0.5, L1=0.3, L2=0.35)  # L0 + 2 L1 > 2 L2: CD can be stretched
    t3 = _stretched_theta3(design, 2.5)
    near = np.array([[0.2, 2.5, t3 - 1e-4], [0.2, 2.5, t3 - 1e-6]])
    nb = inverse_dynamics(
        design, Inertia.default(design), near, 0 * near, 0 * near, with_mass_matrix=True
    )
    assert np.all(nb.ok)
    top = np.linalg.eigvalsh(nb.mass_matrix)[:, -1]
    assert nb.kappa_A[1] > 5 * nb.kappa_A[0]
    growth = (top[1] / top[0]) / (nb.kappa_A[1] / nb.kappa_A[0]) ** 2
    assert 0.5 < growth < 2.0
