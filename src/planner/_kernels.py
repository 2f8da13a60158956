"""Compiled per-posture loops behind the vectorised kinematics (numba).

Private: :mod:`planner.kinematics` validates inputs and wraps these. One fused loop per
quantity keeps every intermediate in registers; the same maths in plain numpy allocates a
temporary array per operation and runs about three times slower (``benchmarks/kinematics.py``).
Formulas and frames are those of ``CONVENTIONS.md``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from planner.constants import ASSEMBLY_TOL, REACH_TOL

_PI = math.pi
_TWO_PI = 2.0 * math.pi


@njit(cache=True, inline="always")
def _wrap(x: float) -> float:
    """Angle in (-pi, pi]."""
    return _PI - ((_PI - x) % _TWO_PI)


@njit(cache=True, nogil=True, error_model="numpy")
def forward_kernel(L0, L1, L2, q, branch, p, passive, w_out, ok):  # pragma: no cover - compiled
    """Direct kinematics of N postures in one assembly branch each (+1 or -1).

    Writes P (N, 3), (theta4, theta5) (N, 2), the in-plane coordinate w (N,) and whether the
    loop closes (N,). A posture with C = D or |CD| > 2 L2 has ``ok = False`` and NaN outputs.
    """
    n = q.shape[0]
    half = 0.5 * L0
    lim = 4.0 * L2 * L2 * (1.0 + ASSEMBLY_TOL)
    for i in range(n):
        t1 = q[i, 0]
        cu = -half + L1 * math.cos(q[i, 1])
        cw = L1 * math.sin(q[i, 1])
        du = half + L1 * math.cos(q[i, 2])
        dw = L1 * math.sin(q[i, 2])
        eu = du - cu
        ew = dw - cw
        d2 = eu * eu + ew * ew
        if d2 > lim or d2 == 0.0 or not (d2 == d2):
            ok[i] = False
            p[i, 0] = p[i, 1] = p[i, 2] = np.nan
            passive[i, 0] = passive[i, 1] = np.nan
            w_out[i] = np.nan
            continue
        h2 = L2 * L2 - 0.25 * d2
        s = branch[i] * math.sqrt(h2 / d2) if h2 > 0.0 else 0.0
        pu = 0.5 * (cu + du) - s * ew
        pw = 0.5 * (cw + dw) + s * eu
        passive[i, 0] = math.atan2(pw - cw, pu - cu)
        passive[i, 1] = math.atan2(pw - dw, pu - du)
        p[i, 0] = pw * math.cos(t1)
        p[i, 1] = pu
        p[i, 2] = -pw * math.sin(t1)
        w_out[i] = pw
        ok[i] = True


@njit(cache=True, inline="always")
def _leg(base_u, L1, L2, pu, pw, side):
    """Actuated angle of one leg reaching (pu, pw) with sign ``side`` of sin(theta_distal -
    theta_proximal); returns (angle, ok)."""
    au = pu - base_u
    r = math.sqrt(au * au + pw * pw)
    if r == 0.0:
        return np.nan, False
    cos_a = (L1 * L1 + r * r - L2 * L2) / (2.0 * L1 * r)
    if cos_a > 1.0:
        if cos_a > 1.0 + REACH_TOL:
            return np.nan, False
        cos_a = 1.0
    elif cos_a < -1.0:
        if cos_a < -1.0 - REACH_TOL:
            return np.nan, False
        cos_a = -1.0
    return _wrap(math.atan2(pw, au) - side * math.acos(cos_a)), True


@njit(cache=True, nogil=True, error_model="numpy")
def inverse_kernel(
    L0, L1, L2, p, theta1_on_axis, q, passive, w_out, ok, degenerate
):  # pragma: no cover
    """Inverse kinematics of N points into the eight working modes.

    Slot k of the second axis is the working mode with signs
    (s_axis, s_A, s_B) = (+1 if k < 4 else -1, +1 if k % 4 < 2 else -1, +1 if k % 2 == 0 else -1).
    A slot that duplicates another (a sign that is 0 at a serial singularity) is ``ok = False``.
    ``degenerate[i]`` marks a point where one leg's angle is undetermined (P = A or P = B with
    L1 = L2): every slot is ``ok = False`` there.
    """
    n = p.shape[0]
    half = 0.5 * L0
    axis_tol = 1e-12 * (L1 + L2)
    for i in range(n):
        x = p[i, 0]
        pu = p[i, 1]
        z = p[i, 2]
        r = math.sqrt(x * x + z * z)
        on_axis = r <= axis_tol
        deg = False
        if on_axis:
            au = pu + half
            bu = pu - half
            deg = abs(au) <= axis_tol or abs(bu) <= axis_tol
        degenerate[i] = deg
        for k in range(8):
            sx = 1.0 if k < 4 else -1.0
            sa = 1.0 if k % 4 < 2 else -1.0
            sb = 1.0 if k % 2 == 0 else -1.0
            q[i, k, 0] = q[i, k, 1] = q[i, k, 2] = np.nan
            passive[i, k, 0] = passive[i, k, 1] = np.nan
            w_out[i, k] = np.nan
            ok[i, k] = False
            if deg or not (r == r) or (on_axis and sx < 0.0):
                continue
            if on_axis:
                t1 = _wrap(theta1_on_axis)
                pw = 0.0
            elif sx > 0.0:
                t1 = math.atan2(-z, x)
                pw = r
            else:
                t1 = math.atan2(z, -x)
                pw = -r
            t2, oka = _leg(-half, L1, L2, pu, pw, sa)
            t3, okb = _leg(half, L1, L2, pu, pw, sb)
            if not (oka and okb):
                continue
            cu = -half + L1 * math.cos(t2)
            cw = L1 * math.sin(t2)
            du = half + L1 * math.cos(t3)
            dw = L1 * math.sin(t3)
            t4 = math.atan2(pw - cw, pu - cu)
            t5 = math.atan2(pw - dw, pu - du)
            q[i, k, 0] = _wrap(t1)
            q[i, k, 1] = t2
            q[i, k, 2] = t3
            passive[i, k, 0] = t4
            passive[i, k, 1] = t5
            w_out[i, k] = pw
            ok[i, k] = True
