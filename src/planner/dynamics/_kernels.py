"""Compiled per-posture loop behind :func:`planner.dynamics.inverse_dynamics` (numba).

Private: :mod:`planner.dynamics.inverse` validates inputs, runs the kinematics and wraps
this. One fused loop keeps every intermediate in registers instead of some 150 temporary
arrays of the same formulas in numpy (``benchmarks/dynamics.py`` measures both). Formulas,
frame and symbols: ``docs/dynamics.md``. Tolerances and inertias come in as arguments, never
as module globals (numba's on-disk cache would freeze them).
"""

from __future__ import annotations

import math

from numba import njit

#: Order of the inertia parameters in ``params``.
PARAMS = (
    "proximal.mass", "proximal.com", "proximal.I_perp", "proximal.I_axial",
    "distal.mass", "distal.com", "distal.I_perp", "distal.I_axial",
    "payload.mass", "base.inertia", "rotor[0]", "rotor[1]", "rotor[2]",
)  # fmt: skip


@njit(cache=True, nogil=True, error_model="numpy")
def _translation(m, w, dw, ddu, ddw, ju1, ju2, jw1, jw2, d1, dd1, ge, gy, gk):  # pragma: no cover
    """Generalised forces of a point mass m at in-plane (u, w): F = m (a - g) projected by
    dv/dqd_j = Ju_j y + Jw_j e - w delta_j1 k (only theta2, theta3 columns of Ju, Jw)."""
    fe = m * (ddw - w * d1 * d1 - ge)
    fy = m * (ddu - gy)
    fk = m * (-(2.0 * dw * d1 + w * dd1) - gk)
    return -w * fk, ju1 * fy + jw1 * fe, ju2 * fy + jw2 * fe


@njit(cache=True, nogil=True, error_model="numpy")
def _rotation(ip, ia, cp, sp, dphi, ddphi, d1, dd1):  # pragma: no cover - compiled
    """(Mo_y, Mo_k) of a link at in-plane angle phi (cos, sin given): Mo = I alpha + omega x
    I omega with omega = d1 y - dphi k, alpha = dd1 y - ddphi k - dphi d1 e."""
    di = ia - ip
    e_alpha = -sp * dphi * d1 + cp * dd1
    e_omega = cp * d1
    mo_y = ip * dd1 + di * e_alpha * cp - di * e_omega * dphi * sp
    mo_k = -ip * ddphi - di * e_omega * d1 * sp
    return mo_y, mo_k


@njit(cache=True, nogil=True, error_model="numpy")
def inverse_kernel(L1, L2, params, q, passive, ok, qd, qdd, g, out):  # pragma: no cover
    """Actuator torques ``out`` (N, 3) of motions (q, qd, qdd) (N, 3) with passive angles
    (N, 2), under gravity g (3,); rows with ``ok`` False are NaN. Per posture, three steps:
    the passive joints' motion (:func:`_passive_motion`), then the forces of the proximal
    links (:func:`_proximal_forces`) and of the distal links with the payload
    (:func:`_distal_forces`), added to the base's and rotors' inertia."""
    m1, f1, ip1, ia1 = params[0], params[1], params[2], params[3]
    m2, f2, ip2, ia2 = params[4], params[5], params[6], params[7]
    mp, ib, r1, r2, r3 = params[8], params[9], params[10], params[11], params[12]
    for i in range(q.shape[0]):
        if not ok[i]:
            out[i, 0] = out[i, 1] = out[i, 2] = math.nan
            continue
        t1, t2, t3 = q[i, 0], q[i, 1], q[i, 2]
        t4, t5 = passive[i, 0], passive[i, 1]
        d1, d2, d3 = qd[i, 0], qd[i, 1], qd[i, 2]
        dd1, dd2, dd3 = qdd[i, 0], qdd[i, 1], qdd[i, 2]
        c2, s2, c3, s3 = math.cos(t2), math.sin(t2), math.cos(t3), math.sin(t3)
        c4, s4, c5, s5 = math.cos(t4), math.sin(t4), math.cos(t5), math.sin(t5)
        j42, j43, j52, j53, d4, d5, dd4, dd5 = _passive_motion(
            L1, L2, c2, s2, c3, s3, c4, s4, c5, s5, d2, d3, dd2, dd3
        )
        ct1, st1 = math.cos(t1), math.sin(t1)
        ge = g[0] * ct1 - g[2] * st1
        gy = g[1]
        gk = g[0] * st1 + g[2] * ct1
        # the base's and rotors' inertia, then the links' forces added in turn
        tau = (ib * dd1 + r1 * dd1, r2 * dd2, r3 * dd3)
        tau = _proximal_forces(
            tau, L1, m1, f1, ip1, ia1, c2, s2, c3, s3, d2, d3, dd2, dd3, d1, dd1, ge, gy, gk
        )
        out[i, 0], out[i, 1], out[i, 2] = _distal_forces(
            tau,
            L1,
            L2,
            m2,
            f2,
            ip2,
            ia2,
            mp,
            (c2, s2, d2, dd2, c4, s4, d4, dd4, j42, j43),
            (c3, s3, d3, dd3, c5, s5, d5, dd5, j52, j53),
            d1,
            dd1,
            ge,
            gy,
            gk,
        )


@njit(cache=True, nogil=True, error_model="numpy", inline="always")  # no call per posture
def _passive_motion(
    L1, L2, c2, s2, c3, s3, c4, s4, c5, s5, d2, d3, dd2, dd3
):  # pragma: no cover - compiled
    """The passive joints' step of :func:`inverse_kernel`: their Jacobians (eq. P)
    d theta4 / d q2, q3 and d theta5 / d q2, q3, velocities and accelerations, from the
    cosines and sines of theta2 .. theta5 and the active velocities and accelerations.
    Returns (j42, j43, j52, j53, d4, d5, dd4, dd5)."""
    ls = L2 * (s5 * c4 - c5 * s4)  # L2 sin(theta5 - theta4)
    k = L1 / ls
    # passive Jacobians (eq. P): d theta4 / d q2, q3 and d theta5 / d q2, q3
    j42 = -k * (s5 * c2 - c5 * s2)
    j43 = k * (s5 * c3 - c5 * s3)
    j52 = -k * (s4 * c2 - c4 * s2)
    j53 = k * (s4 * c3 - c4 * s3)
    d4 = j42 * d2 + j43 * d3
    d5 = j52 * d2 + j53 * d3
    r2u = L1 * (-dd3 * s3 - d3 * d3 * c3 + dd2 * s2 + d2 * d2 * c2)
    r2u += L2 * (d4 * d4 * c4 - d5 * d5 * c5)
    r2w = L1 * (dd3 * c3 - d3 * d3 * s3 - dd2 * c2 + d2 * d2 * s2)
    r2w += L2 * (d4 * d4 * s4 - d5 * d5 * s5)
    dd4 = (r2u * c5 + r2w * s5) / ls
    dd5 = (r2u * c4 + r2w * s4) / ls
    return j42, j43, j52, j53, d4, d5, dd4, dd5


@njit(cache=True, nogil=True, error_model="numpy", inline="always")  # no call per posture
def _proximal_forces(
    tau, L1, m1, f1, ip1, ia1, c2, s2, c3, s3, d2, d3, dd2, dd3, d1, dd1, ge, gy, gk
):  # pragma: no cover - compiled
    """The proximal links' step of :func:`inverse_kernel`: ``tau`` (3,) plus the
    generalised forces of the two proximal links (mass ``m1`` at ``f1`` L1, inertias
    ``ip1``, ``ia1``) turning with theta2 and theta3, under gravity (ge, gy, gk) in the
    loop's frame (added term by term, in the order of the formulas)."""
    tau1, tau2, tau3 = tau
    a = f1 * L1
    x1, x2, x3 = _translation(
        m1,
        a * s2,
        a * c2 * d2,
        a * (-dd2 * s2 - d2 * d2 * c2),
        a * (dd2 * c2 - d2 * d2 * s2),
        -a * s2,
        0.0,
        a * c2,
        0.0,
        d1,
        dd1,
        ge,
        gy,
        gk,
    )
    tau1 += x1
    tau2 += x2
    tau3 += x3
    x1, x2, x3 = _translation(
        m1,
        a * s3,
        a * c3 * d3,
        a * (-dd3 * s3 - d3 * d3 * c3),
        a * (dd3 * c3 - d3 * d3 * s3),
        0.0,
        -a * s3,
        0.0,
        a * c3,
        d1,
        dd1,
        ge,
        gy,
        gk,
    )
    tau1 += x1
    tau2 += x2
    tau3 += x3
    my, mk = _rotation(ip1, ia1, c2, s2, d2, dd2, d1, dd1)
    tau1 += my
    tau2 -= mk
    my, mk = _rotation(ip1, ia1, c3, s3, d3, dd3, d1, dd1)
    tau1 += my
    tau3 -= mk
    return tau1, tau2, tau3


@njit(cache=True, nogil=True, error_model="numpy", inline="always")  # no call per posture
def _distal_forces(
    tau, L1, L2, m2, f2, ip2, ia2, mp, side_c, side_d, d1, dd1, ge, gy, gk
):  # pragma: no cover - compiled
    """The distal links' step of :func:`inverse_kernel`: ``tau`` (3,) plus the generalised
    forces of the two distal links (mass ``m2`` at ``f2`` L2, inertias ``ip2``, ``ia2``) and
    the payload ``mp`` at P, under gravity (ge, gy, gk) in the loop's frame. ``side_c`` and
    ``side_d``: (cos, sin, velocity, acceleration) of the proximal joint, the same of the
    passive one and its Jacobian (2,), on the C side (theta2, theta4) and on the D side
    (theta3, theta5)."""
    tau1, tau2, tau3 = tau
    # distal links (C side with theta4, D side with theta5) and the payload at P
    for side in range(2):
        c, s, d, dd, cp, sp, dp, ddp, jp2, jp3 = side_c if side == 0 else side_d
        for body in range(2 if side == 0 else 1):
            m, b = (m2, f2 * L2) if body == 0 else (mp, L2)
            ju2 = -b * sp * jp2
            ju3 = -b * sp * jp3
            jw2 = b * cp * jp2
            jw3 = b * cp * jp3
            if side == 0:
                ju2 -= L1 * s
                jw2 += L1 * c
            else:
                ju3 -= L1 * s
                jw3 += L1 * c
            w = L1 * s + b * sp
            dw = L1 * c * d + b * cp * dp
            ddu = L1 * (-dd * s - d * d * c) + b * (-ddp * sp - dp * dp * cp)
            ddw = L1 * (dd * c - d * d * s) + b * (ddp * cp - dp * dp * sp)
            x1, x2, x3 = _translation(m, w, dw, ddu, ddw, ju2, ju3, jw2, jw3, d1, dd1, ge, gy, gk)
            tau1 += x1
            tau2 += x2
            tau3 += x3
            if body == 0:
                my, mk = _rotation(ip2, ia2, cp, sp, dp, ddp, d1, dd1)
                tau1 += my
                tau2 -= jp2 * mk
                tau3 -= jp3 * mk
    return tau1, tau2, tau3
