"""Inverse dynamics of the closed chain in actuated coordinates, vectorised over N postures.

The derivation is in ``docs/dynamics.md``. In short: the five bodies (two proximal links, two
distal links, the payload at P; plus the turning base and the rotors) are written in the
frame of the linkage plane ``(e, y, k)`` that turns with theta1. The loop closure
``C + L2 a(theta4) = D + L2 a(theta5)`` gives the passive rates and accelerations in closed
form (divided by ``L2 sin(theta5 - theta4)``: a parallel singularity is where they blow up).
Each body's Newton-Euler wrench ``(m (a - g), I alpha + omega x I omega)`` is projected on the
actuated coordinates by its velocity Jacobians (virtual work: the loop's constraint forces do
no work on motions that keep it closed), so

    tau = M(q) qdd + h(q, qd),   h = (velocity-product terms) + (gravity terms).

``M`` is assembled from the same projection with unit accelerations, no velocity and no
gravity (three evaluations), so it is exactly the matrix of the torques computed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.constants import KAPPA_SOLVABLE
from planner.design import Design
from planner.dynamics.inertia import Inertia, check_gravity
from planner.exceptions import InputError
from planner.kinematics import forward_batch

__all__ = [
    "DynamicsBatch",
    "inverse_dynamics",
    "mass_matrix",
]


def _rates(name: str, value: object, n: int) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numbers, got {value!r}", field=name) from exc
    arr = np.atleast_2d(arr)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"{name} must have shape (N, 3), got {np.shape(value)}", field=name)
    if arr.shape[0] != n:
        raise InputError(f"{name} must have {n} rows (one per posture of q), got {arr.shape[0]}",
                         field=name)  # fmt: skip
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be finite (no NaN or infinity)", field=name)
    return arr


@dataclass(frozen=True, eq=False)
class _Kin:
    """Positions, passive angles and first-order kinematics of N postures (internal)."""

    q: np.ndarray  # (N, 3)
    t4: np.ndarray
    t5: np.ndarray
    s: np.ndarray  # sin(theta5 - theta4), 0 where not ok
    jt4: np.ndarray  # (N, 3): d theta4 / d q
    jt5: np.ndarray
    ok: np.ndarray  # assembled and kappa(A) <= KAPPA_SOLVABLE
    kappa: np.ndarray


def _kinematics(design: Design, q: np.ndarray, assembly_mode: object) -> _Kin:
    batch = forward_batch(design, q, assembly_mode)
    t4 = batch.passive[:, 0]
    t5 = batch.passive[:, 1]
    d = t5 - t4
    s = np.sin(d)
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = (1.0 + np.abs(np.cos(d))) / np.abs(s)
    ok = batch.ok & (kappa <= KAPPA_SOLVABLE)
    s = np.where(ok, s, 1.0)
    t4 = np.where(ok, t4, 0.0)
    t5 = np.where(ok, t5, 0.0)
    q2 = batch.q
    k = design.L1 / (design.L2 * s)
    # d theta4 / d q_j = -+ L1 (n_j . a5) / (L2 s), n_j . a_i = sin(theta_i - theta_j)
    jt4 = np.zeros_like(q2)
    jt5 = np.zeros_like(q2)
    jt4[:, 1] = -k * np.sin(t5 - q2[:, 1])
    jt4[:, 2] = k * np.sin(t5 - q2[:, 2])
    jt5[:, 1] = -k * np.sin(t4 - q2[:, 1])
    jt5[:, 2] = k * np.sin(t4 - q2[:, 2])
    return _Kin(q2, t4, t5, s, jt4, jt5, ok, kappa)


def _forces(
    design: Design,
    inertia: Inertia,
    kin: _Kin,
    qd: np.ndarray,
    qdd: np.ndarray,
    gravity: np.ndarray,
) -> np.ndarray:
    """Generalised forces (N, 3) of the motion (q, qd, qdd) under ``gravity``."""
    l0, l1, l2 = design.L0, design.L1, design.L2
    q = kin.q
    t1, t2, t3, t4, t5 = q[:, 0], q[:, 1], q[:, 2], kin.t4, kin.t5
    d1, d2, d3 = qd[:, 0], qd[:, 1], qd[:, 2]
    dd1, dd2, dd3 = qdd[:, 0], qdd[:, 1], qdd[:, 2]
    c2, s2, c3, s3 = np.cos(t2), np.sin(t2), np.cos(t3), np.sin(t3)
    c4, s4, c5, s5 = np.cos(t4), np.sin(t4), np.cos(t5), np.sin(t5)
    # passive rates and accelerations from the loop closure (docs/dynamics.md, eq. P)
    d4 = kin.jt4[:, 1] * d2 + kin.jt4[:, 2] * d3
    d5 = kin.jt5[:, 1] * d2 + kin.jt5[:, 2] * d3
    # R2 = L1 (dd3 n3 - d3^2 a3 - dd2 n2 + d2^2 a2) + L2 (d4^2 a4 - d5^2 a5), (u, w) parts
    r2u = l1 * (-dd3 * s3 - d3**2 * c3 + dd2 * s2 + d2**2 * c2) + l2 * (d4**2 * c4 - d5**2 * c5)
    r2w = l1 * (dd3 * c3 - d3**2 * s3 - dd2 * c2 + d2**2 * s2) + l2 * (d4**2 * s4 - d5**2 * s5)
    ls = l2 * kin.s
    dd4 = (r2u * c5 + r2w * s5) / ls
    dd5 = (r2u * c4 + r2w * s4) / ls
    # gravity in the plane's frame (e, y, k)
    ct1, st1 = np.cos(t1), np.sin(t1)
    g_e = gravity[0] * ct1 - gravity[2] * st1
    g_y = gravity[1]
    g_k = gravity[0] * st1 + gravity[2] * ct1
    tau = np.zeros_like(q)
    tau[:, 0] += inertia.base_inertia * dd1
    tau += inertia.rotor_array * qdd
    prox, dist = inertia.proximal, inertia.distal
    half = l0 / 2

    def translation(m, u, w, du, dw, ddu, ddw, ju, jw):  # type: ignore[no-untyped-def]
        # F = m (a - g) in (e, y, k); tau_j = F . dv/dqd_j (v = du y + dw e - w d1 k)
        f_e = m * (ddw - w * d1**2 - g_e)
        f_y = m * (ddu - g_y)
        f_k = m * (-(2 * dw * d1 + w * dd1) - g_k)
        tau[:] += ju * f_y[:, None] + jw * f_e[:, None]
        tau[:, 0] += -w * f_k

    def rotation(link, phi, dphi, ddphi, jphi):  # type: ignore[no-untyped-def]
        # omega = d1 y - dphi k, alpha = dd1 y - ddphi k - dphi d1 e; link direction
        # e_link = (sin phi, cos phi, 0); I = I_perp Id + dI e_link e_link^T
        cp, sp = np.cos(phi), np.sin(phi)
        di = link.I_axial - link.I_perp
        e_alpha = -sp * dphi * d1 + cp * dd1
        e_omega = cp * d1
        mo_y = link.I_perp * dd1 + di * e_alpha * cp - di * e_omega * dphi * sp
        mo_k = -link.I_perp * ddphi - di * e_omega * d1 * sp
        tau[:, 0] += mo_y
        tau[:] += -jphi * mo_k[:, None]

    # proximal links: pivot A (u = -L0/2) with theta2, pivot B (+L0/2) with theta3
    for sign, c, s, d, dd, j in ((-1.0, c2, s2, d2, dd2, 1), (1.0, c3, s3, d3, dd3, 2)):
        a = prox.com * l1
        ju = np.zeros_like(q)
        jw = np.zeros_like(q)
        ju[:, j] = -a * s
        jw[:, j] = a * c
        translation(prox.mass, sign * half + a * c, a * s, -a * s * d, a * c * d,
                    a * (-dd * s - d**2 * c), a * (dd * c - d**2 * s), ju, jw)  # fmt: skip
        jphi = np.zeros_like(q)
        jphi[:, j] = 1.0
        rotation(prox, t2 if j == 1 else t3, d, dd, jphi)
    # distal links (C with theta4, D with theta5) and the payload at P (on the C side)
    legs = (
        (-1.0, c2, s2, d2, dd2, 1, c4, s4, t4, d4, dd4, kin.jt4),
        (1.0, c3, s3, d3, dd3, 2, c5, s5, t5, d5, dd5, kin.jt5),
    )
    for sign, c, s, d, dd, j, cp, sp, phi, dp, ddp, jp in legs:
        bodies = [(dist.mass, dist.com * l2, dist)]
        if j == 1:
            bodies.append((inertia.payload_mass, l2, None))
        for m, b, link in bodies:
            ju = -b * sp[:, None] * jp
            jw = b * cp[:, None] * jp
            ju[:, j] += -l1 * s
            jw[:, j] += l1 * c
            u = sign * half + l1 * c + b * cp
            w = l1 * s + b * sp
            du = -l1 * s * d - b * sp * dp
            dw = l1 * c * d + b * cp * dp
            ddu = l1 * (-dd * s - d**2 * c) + b * (-ddp * sp - dp**2 * cp)
            ddw = l1 * (dd * c - d**2 * s) + b * (ddp * cp - dp**2 * sp)
            translation(m, u, w, du, dw, ddu, ddw, ju, jw)
            if link is not None:
                rotation(link, phi, dp, ddp, jp)
    return tau


@dataclass(frozen=True, eq=False)
class DynamicsBatch:
    """Inverse dynamics of N postures.

    Attributes
    ----------
    tau : shape (N, 3), N m -- actuator torques producing the motion (NaN where not ``ok``)
    mass_matrix : shape (N, 3, 3), kg m^2 (and kg m for mixed entries) -- M(q), symmetric
        positive definite where ``ok``; NaN elsewhere
    ok : shape (N,), bool -- the posture assembles and kappa(A) <= KAPPA_SOLVABLE
    kappa_A : shape (N,) -- kappa(A) of each posture (inf when parallel-singular or not
        assembled)
    """

    tau: np.ndarray
    mass_matrix: np.ndarray | None
    ok: np.ndarray
    kappa_A: np.ndarray


def inverse_dynamics(
    design: Design,
    inertia: Inertia,
    q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    *,
    assembly_mode: object = "+",
    gravity: object = (0.0, 0.0, -9.81),
    with_mass_matrix: bool = False,
) -> DynamicsBatch:
    """Actuator torques ``tau = M(q) qdd + h(q, qd)`` of N motions of the closed chain.

    Parameters
    ----------
    design, inertia : the robot
    q, qd, qdd : shape (N, 3) or (3,): rad, rad/s, rad/s^2 (actuated joints)
    assembly_mode : '+' | '-' | array of +1/-1 (N,)
    gravity : shape (3,), m/s^2, base frame
    with_mass_matrix : also return M(q) (three more projections)

    Returns
    -------
    DynamicsBatch
        Where a posture does not assemble, or is parallel-singular (kappa(A) above
        :data:`~planner.constants.KAPPA_SOLVABLE`: M grows like kappa(A)^2 there and the
        torques of a finite motion are undefined at the singularity itself), ``ok`` is False
        and ``tau`` and ``mass_matrix`` are NaN.
    """
    g = check_gravity(gravity)
    kin = _kinematics(design, q, assembly_mode)
    n = kin.q.shape[0]
    qd2 = _rates("qd", qd, n)
    qdd2 = _rates("qdd", qdd, n)
    tau = _forces(design, inertia, kin, qd2, qdd2, g)
    tau[~kin.ok] = np.nan
    m = _mass_matrix_of(design, inertia, kin) if with_mass_matrix else None
    return DynamicsBatch(tau, m, kin.ok, np.where(kin.ok, kin.kappa, np.inf))


def _mass_matrix_of(design: Design, inertia: Inertia, kin: _Kin) -> np.ndarray:
    """M(q), shape (N, 3, 3), of kinematics already computed (column j: the torques of a unit
    acceleration of joint j at rest without gravity), symmetrised."""
    n = kin.q.shape[0]
    zero = np.zeros((n, 3))
    g0 = np.zeros(3)
    m = np.empty((n, 3, 3))
    for j in range(3):
        unit = np.zeros((n, 3))
        unit[:, j] = 1.0
        m[:, :, j] = _forces(design, inertia, kin, zero, unit, g0)
    m = 0.5 * (m + np.swapaxes(m, 1, 2))  # symmetric by construction, exactly so to rounding
    m[~kin.ok] = np.nan
    return m


def mass_matrix(
    design: Design, inertia: Inertia, q: np.ndarray, *, assembly_mode: object = "+"
) -> np.ndarray:
    """M(q) of N postures, shape (N, 3, 3) (NaN where not ``ok``, see
    :func:`inverse_dynamics`)."""
    return _mass_matrix_of(design, inertia, _kinematics(design, q, assembly_mode))
