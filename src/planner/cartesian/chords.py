"""Chord bounds of a straight tool path: how far P strays from the Cartesian line along a
straight joint motion, and how far a timing blend may cut a corner.

Between two consecutive joint waypoints of :func:`planner.cartesian.plan.plan_cartesian`
the robot moves on the straight joint segment, whose P leaves the Cartesian line;
:func:`chord_deviation_bound` bounds that deviation from above (a second-derivative bound,
:func:`second_derivative_bound`, proved in its docstring), and the plan splits a piece until
the bound is within its share of the tolerance. :func:`blend_allowance` gives each joint
vertex the blend the timing may use while P stays within the rest of the tolerance. Every
bound rests on the least apex sine |sin(theta4 - theta5)| over a piece, from the range of
|CD| (:func:`cd_length`) along it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from planner import _kernels
from planner.constants import ASSEMBLY_TOL
from planner.design import Design
from planner.exceptions import InputError

__all__ = ["blend_allowance", "cd_length", "chord_deviation_bound", "second_derivative_bound"]


def cd_length(design: Design, q: np.ndarray) -> np.ndarray:
    """|CD| of postures q (M, 3), m (depends on theta2, theta3 only)."""
    half = design.L0 / 2
    du = half + design.L1 * np.cos(q[:, 2]) - (-half + design.L1 * np.cos(q[:, 1]))
    dw = design.L1 * (np.sin(q[:, 2]) - np.sin(q[:, 1]))
    return np.hypot(du, dw)


def _apex_sine_over(lo_cd: np.ndarray, hi_cd: np.ndarray, design: Design) -> np.ndarray:
    """Least |sin(theta4 - theta5)| over postures with lo_cd <= |CD| <= hi_cd (m); 0 where
    the range may leave (0, 2 L2).

    With r = |CD| / (2 L2) = sin(gamma / 2), gamma the apex angle of the isosceles triangle
    C-P-D, |sin(theta4 - theta5)| = sin(gamma) = 2 r sqrt(1 - r^2), which is concave in gamma
    on [0, pi]: its least value over an interval of gamma is at an end.
    """
    lo = np.asarray(lo_cd) / (2.0 * design.L2)
    hi = np.asarray(hi_cd) / (2.0 * design.L2)
    ok = (lo > 0.0) & (hi < 1.0)
    lo_c, hi_c = np.clip(lo, 0.0, 1.0), np.clip(hi, 0.0, 1.0)
    s_lo = 2.0 * lo_c * np.sqrt(1.0 - lo_c**2)
    s_hi = 2.0 * hi_c * np.sqrt(1.0 - hi_c**2)
    return np.where(ok, np.minimum(s_lo, s_hi), 0.0)


def _cd_range(cd_a, cd_b, rate_cd):
    """Range of |CD| on straight joint pieces with end values cd_a, cd_b (m) along which |CD|
    is ``rate_cd``-Lipschitz in the piece parameter t in [0, 1]: the two cones from the ends
    give |CD|(t) in [(cd_a + cd_b - rate) / 2, (cd_a + cd_b + rate) / 2] (C and D move on
    their circles by at most L1 |dq2| and L1 |dq3|, so rate = L1 (|dq2| + |dq3|))."""
    return 0.5 * (cd_a + cd_b - rate_cd), 0.5 * (cd_a + cd_b + rate_cd)


def _apex_sine_lower(design: Design, cd_a, cd_b, rate_cd) -> np.ndarray:
    """Least |sin(theta4 - theta5)| on pieces (see :func:`_cd_range`, :func:`_apex_sine_over`)."""
    lo, hi = _cd_range(cd_a, cd_b, rate_cd)
    return _apex_sine_over(lo, hi, design)


def second_derivative_bound(
    design: Design, q_a: np.ndarray, q_b: np.ndarray, w_a: np.ndarray, w_b: np.ndarray
) -> np.ndarray:
    """Upper bound of |d^2 P / dt^2|, m, along the straight joint motions
    q(t) = q_a + t (q_b - q_a), t in [0, 1], for M pieces at once.

    Parameters
    ----------
    q_a, q_b : shape (M, 3), rad -- the ends of each piece.
    w_a, w_b : shape (M,), m -- in-plane distance of P from the axis AB at the ends.

    Returns
    -------
    shape (M,), m; ``inf`` where the apex sine may vanish on the piece.

    Derivation, with dq = q_b - q_a and s a lower bound of |sin(theta4 - theta5)| on the
    piece (:func:`_apex_sine_lower`):

    * C moves on its circle: |C'| = L1 |dq2|, |C''| = L1 dq2^2 (D likewise with dq3);
    * the loop C + L2 e4 = D + L2 e5 differentiated and dotted with e5 gives
      |theta4'| <= |D' - C'| / (L2 s) <= r = L1 (|dq2| + |dq3|) / (L2 s) (theta5 likewise), and
      differentiated twice, |theta4''| <= (L1 (dq2^2 + dq3^2) + 2 L2 r^2) / (L2 s) = a;
    * in the plane, P = C + L2 e4: |P'| <= L1 |dq2| + L2 r = v and
      |P''| <= L1 dq2^2 + L2 a + L2 r^2 (the same through D; the smaller is taken);
    * in 3-D, P = u y + w e(theta1) with theta1 linear in t: P'' = (u'' y + w'' e) +
      2 w' dq1 e' - w dq1^2 e, so |P''| <= |P''_plane| + 2 v |dq1| + |w|max dq1^2 with
      |w| <= max(|w_a|, |w_b|) + v / 2 (w is v-Lipschitz, the cone bound).
    """
    q_a = np.atleast_2d(q_a)
    q_b = np.atleast_2d(q_b)
    dq = q_b - q_a
    a0, a2, a3 = np.abs(dq[:, 0]), np.abs(dq[:, 1]), np.abs(dq[:, 2])
    L1, L2 = design.L1, design.L2
    rate_cd = L1 * (a2 + a3)
    s = _apex_sine_lower(design, cd_length(design, q_a), cd_length(design, q_b), rate_cd)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = rate_cd / (L2 * s)
        acc = (L1 * (a2**2 + a3**2) + 2 * L2 * r**2) / (L2 * s)
        v = np.minimum(L1 * a2, L1 * a3) + L2 * r
        p2 = np.minimum(L1 * a2**2, L1 * a3**2) + L2 * acc + L2 * r**2
        w_max = np.maximum(np.abs(w_a), np.abs(w_b)) + 0.5 * v
        bound = p2 + 2 * v * a0 + w_max * a0**2
    return np.where(s > 0.0, bound, np.inf)


def chord_deviation_bound(
    design: Design,
    q_a: np.ndarray,
    q_b: np.ndarray,
    w_a: np.ndarray,
    w_b: np.ndarray,
    line_a: np.ndarray,
    line_b: np.ndarray,
    assembly_mode: str,
    *,
    subdivisions: int = 8,
) -> np.ndarray:
    """Upper bound, m, on the distance of P from the Cartesian segment line_a line_b along the
    straight joint motions q(t) = q_a + t (q_b - q_a), t in [0, 1], for M pieces at once.

    Parameters
    ----------
    q_a, q_b : shape (M, 3), rad -- the ends of each piece (inverse kinematics of line_a,
        line_b).
    w_a, w_b : shape (M,), m -- in-plane distance of P from the axis AB at the ends.
    line_a, line_b : shape (M, 3), m -- the points of the polyline the ends stand for (both
        on one straight segment of it).
    assembly_mode : '+' | '-'
    subdivisions : int, m >= 1 -- P is evaluated at t = i / m.

    Returns
    -------
    shape (M,), m; ``inf`` where the bound does not hold (the apex sine may vanish, or an
    evaluated posture does not assemble).

    Proof. Let f(t) = P(q(t)) - (P_a + t (P_b - P_a)), P_a, P_b the forward kinematics of
    the ends, so f(0) = f(1) = 0 and f'' = P''. On each [t_i, t_i+1] (t_i = i / m), f minus
    its linear interpolation L vanishes at both ends, so for every unit vector e,
    |e.(f - L)(t)| <= (t - t_i)(t_i+1 - t) max|f''| / 2 <= max|P''| / (8 m^2)
    (:func:`second_derivative_bound`), and |L(t)| <= max(|f(t_i)|, |f(t_i+1)|) (a convex
    combination). So |f(t)| <= max_i |f(t_i)| + max|P''| / (8 m^2). The chord point
    P_a + t (P_b - P_a) is within max(|P_a - line_a|, |P_b - line_b|) of the segment
    line_a line_b (the distance to a convex set is convex), which is added.
    """
    m = int(subdivisions)
    if m < 1:
        raise InputError(f"subdivisions must be >= 1, got {subdivisions!r}")
    q_a, q_b = np.atleast_2d(q_a), np.atleast_2d(q_b)
    if assembly_mode not in ("+", "-"):
        raise InputError(f"assembly_mode must be '+' or '-', got {assembly_mode!r}")
    n = q_a.shape[0]
    out = np.empty(n)
    if n == 0:
        return out
    ro = _kernels.read_only
    _chord_bound_kernel(
        design.L0,
        design.L1,
        design.L2,
        1.0 if assembly_mode == "+" else -1.0,
        ASSEMBLY_TOL,
        m,
        ro(q_a),
        ro(q_b),
        ro(np.broadcast_to(w_a, (n,))),
        ro(np.broadcast_to(w_b, (n,))),
        ro(np.broadcast_to(line_a, (n, 3))),
        ro(np.broadcast_to(line_b, (n, 3))),
        ro(cd_length(design, q_a)),  # numpy's cos and sin, as second_derivative_bound's
        ro(cd_length(design, q_b)),
        out,
    )
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _chord_bound_kernel(
    L0, L1, L2, branch, tol, m, q_a, q_b, w_a, w_b, line_a, line_b, cd_a, cd_b, out
):  # pragma: no cover - compiled
    """:func:`chord_deviation_bound` piece by piece, in one compiled pass: P at t = k / m on
    each piece (:func:`planner._kernels.forward_kernel`'s loop closure), the largest distance
    from its chord, the ends' distances from the line, plus :func:`second_derivative_bound`
    (its formulas with ``|CD|`` at the ends given) over ``8 m^2``; inf where a posture does
    not assemble or the bound is not finite. The same arithmetic in the same order as the
    vectorised form (checked bit for bit in ``tests/planning/test_cartesian.py``)."""
    p = np.empty((m + 1, 3))
    for i in range(q_a.shape[0]):
        dq0 = q_b[i, 0] - q_a[i, 0]
        dq1 = q_b[i, 1] - q_a[i, 1]
        dq2 = q_b[i, 2] - q_a[i, 2]
        closes = True
        for k in range(m + 1):
            tk = k / m
            t1 = q_a[i, 0] + tk * dq0
            ok, _, _, _, _, pu, pw, _ = _kernels.close_loop(
                L0, L1, L2, q_a[i, 1] + tk * dq1, q_a[i, 2] + tk * dq2, branch, tol
            )
            if not ok:
                closes = False
                break
            p[k, 0] = pw * math.cos(t1)
            p[k, 1] = pu
            p[k, 2] = -pw * math.sin(t1)
        if not closes:
            out[i] = np.inf
            continue
        f = 0.0
        for k in range(m + 1):
            tk = k / m
            d2 = 0.0
            for j in range(3):
                e = p[k, j] - (p[0, j] + tk * (p[m, j] - p[0, j]))
                d2 += e * e
            f = max(f, math.sqrt(d2))
        ea, eb = 0.0, 0.0
        for j in range(3):
            ea += (p[0, j] - line_a[i, j]) * (p[0, j] - line_a[i, j])
            eb += (p[m, j] - line_b[i, j]) * (p[m, j] - line_b[i, j])
        ends = max(math.sqrt(ea), math.sqrt(eb))
        # second_derivative_bound, one piece
        a0, a2, a3 = abs(dq0), abs(dq1), abs(dq2)
        rate_cd = L1 * (a2 + a3)
        lo = 0.5 * (cd_a[i] + cd_b[i] - rate_cd) / (2.0 * L2)
        hi = 0.5 * (cd_a[i] + cd_b[i] + rate_cd) / (2.0 * L2)
        s = 0.0
        if lo > 0.0 and hi < 1.0:
            lo_c, hi_c = min(max(lo, 0.0), 1.0), min(max(hi, 0.0), 1.0)
            s = min(2.0 * lo_c * math.sqrt(1.0 - lo_c**2), 2.0 * hi_c * math.sqrt(1.0 - hi_c**2))
        if not s > 0.0:
            out[i] = np.inf
            continue
        r = rate_cd / (L2 * s)
        acc = (L1 * (a2**2 + a3**2) + 2 * L2 * r**2) / (L2 * s)
        v = min(L1 * a2, L1 * a3) + L2 * r
        p2 = min(L1 * a2**2, L1 * a3**2) + L2 * acc + L2 * r**2
        w_max = max(abs(w_a[i]), abs(w_b[i])) + 0.5 * v
        m2 = p2 + 2 * v * a0 + w_max * a0**2
        bound = f + m2 / (8.0 * m * m) + ends
        out[i] = bound if math.isfinite(bound) else np.inf


def blend_allowance(
    design: Design, q: np.ndarray, budget: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Joint-space blend allowance (rad) per vertex of a joint polyline q (N, 3) that keeps P
    of every blended posture within ``budget`` (N,) m of P of its nearest planned posture.

    A blended posture q_b lies within ``dev`` (Euclidean, rad) of a posture q_n on one of the
    two segments next to its vertex, so |P(q_b) - P(q_n)| <= G dev, G the largest gain
    |dP / dsigma| along unit joint directions near those segments:
    ``G <= sqrt(reach^2 + (L1 + L1 / s)^2 + (L1 / s)^2)`` (the terms of
    :func:`second_derivative_bound`'s first derivatives: |w| <= reach for theta1, L1 and the
    passive rate L1 / s for theta2, L1 / s for theta3, by Cauchy-Schwarz), with s the least
    apex sine on those segments widened by the motion of |CD| within ``dev``
    (at most L1 sqrt(2) dev). Since G >= 2 L1, ``dev <= budget / (2 L1)``, which is the
    widening used. The end vertices get 0.

    Returns
    -------
    dev : shape (N,), rad
    gain : shape (N,), m/rad -- the G used (inf at the ends).
    """
    q = np.atleast_2d(q)
    n = q.shape[0]
    dev = np.zeros(n)
    gain = np.full(n, np.inf)
    if n < 3:
        return dev, gain
    L1 = design.L1
    widen = math.sqrt(2.0) * L1 * np.asarray(budget)[1:-1] / (2 * L1)  # m of |CD|
    cd = cd_length(design, q)
    dq = np.diff(q, axis=0)
    rate = L1 * (np.abs(dq[:, 1]) + np.abs(dq[:, 2]))
    # |CD| range over the two segments of each interior vertex, widened
    lo_seg, hi_seg = _cd_range(cd[:-1], cd[1:], rate)
    lo = np.minimum(lo_seg[:-1], lo_seg[1:]) - widen
    hi = np.maximum(hi_seg[:-1], hi_seg[1:]) + widen
    s = _apex_sine_over(lo, hi, design)
    with np.errstate(divide="ignore"):
        g = np.sqrt(design.reach**2 + (L1 + L1 / s) ** 2 + (L1 / s) ** 2)
    inner = np.maximum(np.asarray(budget)[1:-1], 0.0) / g
    dev[1:-1] = np.where(s > 0, np.minimum(inner, np.asarray(budget)[1:-1] / (2 * L1)), 0.0)
    gain[1:-1] = g
    return dev, gain
