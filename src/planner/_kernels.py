"""Compiled per-posture loops behind the vectorised kinematics (numba).

Private: :mod:`planner.kinematics` validates inputs and wraps these. One fused loop per
quantity keeps every intermediate in registers instead of a temporary array per numpy
operation; angles are left to numpy's SIMD ``arctan2``, which beats a scalar ``atan2`` in
the loop by far (``benchmarks/kinematics.py`` measures the result).
Formulas and frames are those of ``docs/conventions.md``. Tolerances come in as arguments, never
as module globals: numba's on-disk cache would freeze a global's value at compile time.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


def read_only(a: object, dtype: type = float) -> np.ndarray:
    """``a`` as a kernel takes an input array: C-contiguous, of ``dtype``, read-only (a view:
    no copy when ``a`` already is a C-contiguous array of that type).

    numba compiles one machine code per combination of argument types, and an array's
    writability is part of its type: a kernel fed a writable array by one caller and a
    read-only one (a frozen or cached array, a ``broadcast_to`` view) by another compiles
    twice (2-10 s each, and ``planner warm-up`` covers only the combination it passed).
    Passing every input array through this makes one signature serve every caller; outputs
    stay fresh writable arrays. (The validity kernels, which compiled planners call with
    writable postures, take writable postures instead: ``ValidityChecker`` copies them.)"""
    view: np.ndarray = np.ascontiguousarray(a, dtype=dtype).view()
    view.flags.writeable = False
    return view


@njit(cache=True, nogil=True, error_model="numpy")
def close_loop(L0, L1, L2, theta2, theta3, branch, assembly_tol):  # pragma: no cover - compiled
    """The five-bar loop closure of one posture, in the loop's plane (u along AB, w along
    e(theta1)); the one copy that the kinematics and the validity kernels share.

    C = A + L1 e(theta2), D = B + L1 e(theta3); P is the apex of the isosceles triangle C-P-D
    over the base CD, on the side ``branch`` (+1 or -1, the assembly mode). The loop closes
    when 0 < |CD|^2 <= 4 L2^2 (1 + ``assembly_tol``) (:data:`planner.constants.ASSEMBLY_TOL`:
    the slack keeps a stretched CD that round-off puts a hair beyond 2 L2 assembled).

    Returns
    -------
    (closes, cu, cw, du, dw, pu, pw, d2) : bool and floats
        Whether the loop closes; C, D and P in (u, w), m; d2 = |CD|^2, m^2. Where the loop
        does not close (also for NaN input), P is NaN.
    """
    half = 0.5 * L0
    cu = -half + L1 * math.cos(theta2)
    cw = L1 * math.sin(theta2)
    du = half + L1 * math.cos(theta3)
    dw = L1 * math.sin(theta3)
    eu = du - cu
    ew = dw - cw
    d2 = eu * eu + ew * ew
    if not (d2 > 0.0 and d2 <= 4.0 * L2 * L2 * (1.0 + assembly_tol)):
        return False, cu, cw, du, dw, np.nan, np.nan, d2
    h2 = L2 * L2 - 0.25 * d2
    s = branch * math.sqrt(h2 / d2) if h2 > 0.0 else 0.0
    pu = 0.5 * (cu + du) - s * ew
    pw = 0.5 * (cw + dw) + s * eu
    return True, cu, cw, du, dw, pu, pw, d2


@njit(cache=True, nogil=True, error_model="numpy")
def forward_kernel(
    L0, L1, L2, q, branch, assembly_tol, p, dy, dx, w_out, ok
):  # pragma: no cover - compiled
    """Direct kinematics of N postures in one assembly branch each (+1 or -1).

    Writes P (N, 3), the in-plane coordinate w (N,), whether the loop closes (N,), and the
    in-plane vectors C->P and D->P as (dy, dx) pairs (N, 2) each, so that the caller gets
    (theta4, theta5) = arctan2(dy, dx) from numpy's SIMD arctan2 (much faster than a scalar
    atan2 here). A posture with C = D or |CD| > 2 L2 has ``ok = False`` and NaN outputs
    (:func:`close_loop`).
    """
    n = q.shape[0]
    for i in range(n):
        t1 = q[i, 0]
        closes, cu, cw, du, dw, pu, pw, _ = close_loop(
            L0, L1, L2, q[i, 1], q[i, 2], branch[i], assembly_tol
        )
        if not closes:
            ok[i] = False
            p[i, 0] = p[i, 1] = p[i, 2] = np.nan
            dy[i, 0] = dy[i, 1] = dx[i, 0] = dx[i, 1] = np.nan
            w_out[i] = np.nan
            continue
        dy[i, 0] = pw - cw
        dx[i, 0] = pu - cu
        dy[i, 1] = pw - dw
        dx[i, 1] = pu - du
        p[i, 0] = pw * math.cos(t1)
        p[i, 1] = pu
        p[i, 2] = -pw * math.sin(t1)
        w_out[i] = pw
        ok[i] = True


@njit(cache=True, nogil=True, error_model="numpy")
def inverse_kernel(
    L0, L1, L2, p, reach_tol, sign_tol, axis_tol, ys, xs, ok, degenerate
):  # pragma: no cover - compiled
    """Inverse kinematics of N points, as in-plane vectors whose angles the caller takes with
    numpy's SIMD arctan2.

    For point i, axis side a (0: w = +r, 1: w = -r), leg g (0: A, 1: B) and elbow side e
    (0: sin(distal - proximal) > 0, 1: < 0), ``(ys, xs)[i, a, g, e, 0]`` is the proximal link
    vector (A->C or B->D) and ``[..., 1]`` the distal one (C->P or D->P); ``ok[i, a, g, e]``
    says that this leg solution exists and is not a duplicate (on a serial singularity the two
    elbow sides meet and only e = 0 is kept; on the axis only a = 0 is kept).
    ``degenerate[i]``: P is a pivot with L1 = L2, the leg angle is undetermined; nothing is ok.
    ``axis_tol`` is relative to the reach L1 + L2 (:data:`planner.constants.AXIS_TOL`).
    """
    n = p.shape[0]
    half = 0.5 * L0
    axis_dist = axis_tol * (L1 + L2)  # m
    l1l2 = L1 * L2
    for i in range(n):
        x = p[i, 0]
        pu = p[i, 1]
        z = p[i, 2]
        r = math.sqrt(x * x + z * z)
        on_axis = r <= axis_dist
        if on_axis:
            r = 0.0
        degenerate[i] = False
        for a in range(2):
            pw = r if a == 0 else -r
            for g in range(2):
                base = -half if g == 0 else half
                au = pu - base
                dist = math.sqrt(au * au + pw * pw)
                cos_a = (
                    (L1 * L1 + dist * dist - L2 * L2) / (2.0 * L1 * dist) if dist > 0.0 else np.nan
                )
                reach = dist > 0.0 and abs(cos_a) <= 1.0 + reach_tol
                if dist <= axis_dist and abs(L1 - L2) <= axis_dist:
                    degenerate[i] = True
                if reach:
                    cos_a = min(1.0, max(-1.0, cos_a))
                    sin_a = math.sqrt(1.0 - cos_a * cos_a)
                    ux = au / dist
                    uy = pw / dist
                for e in range(2):
                    if not reach:
                        ok[i, a, g, e] = False
                        ys[i, a, g, e, 0] = ys[i, a, g, e, 1] = np.nan
                        xs[i, a, g, e, 0] = xs[i, a, g, e, 1] = np.nan
                        continue
                    # proximal angle = phi - side * alpha, side = +1 for e = 0
                    sn = -sin_a if e == 0 else sin_a
                    cx = L1 * (ux * cos_a - uy * sn)
                    cy = L1 * (uy * cos_a + ux * sn)
                    px = au - cx
                    py = pw - cy
                    ys[i, a, g, e, 0] = cy
                    xs[i, a, g, e, 0] = cx
                    ys[i, a, g, e, 1] = py
                    xs[i, a, g, e, 1] = px
                    measure = (cx * py - cy * px) / l1l2
                    dup = (e == 1 and abs(measure) <= sign_tol) or (a == 1 and on_axis)
                    ok[i, a, g, e] = not dup
        if degenerate[i]:
            for a in range(2):
                for g in range(2):
                    for e in range(2):
                        ok[i, a, g, e] = False


@njit(cache=True, nogil=True, error_model="numpy")
def conditioning_kernel(L1, L2, q, passive, w, out):  # pragma: no cover - compiled
    """Per posture (flat N): out[:, 0..5] = kappa_A, kappa_B, |w|/(L1+L2), |sin(t4-t2)|,
    |sin(t5-t3)|, distance of t4-t5 to the nearest multiple of pi. NaN in, NaN out."""
    n = q.shape[0]
    reach = L1 + L2
    for i in range(n):
        delta = passive[i, 0] - passive[i, 1]
        s = abs(math.sin(delta))
        c = abs(math.cos(delta))
        if delta != delta:
            out[i, 0] = np.nan
        elif s > 0.0:
            out[i, 0] = (1.0 + c) / s
        else:
            out[i, 0] = np.inf
        b0 = L2 * abs(w[i])
        sa = abs(math.sin(passive[i, 0] - q[i, 1]))
        sb = abs(math.sin(passive[i, 1] - q[i, 2]))
        b1 = L1 * L2 * sa
        b2 = L1 * L2 * sb
        lo = min(b0, min(b1, b2))
        hi = max(b0, max(b1, b2))
        if lo != lo or hi != hi:
            out[i, 1] = np.nan
        elif lo > 0.0:
            out[i, 1] = hi / lo
        else:
            out[i, 1] = np.inf
        out[i, 2] = abs(w[i]) / reach
        out[i, 3] = sa
        out[i, 4] = sb
        folded = delta % math.pi
        out[i, 5] = min(folded, math.pi - folded)


@njit(cache=True, nogil=True, error_model="numpy")
def forward_velocity_kernel(
    L0, L1, L2, q, qd, branch, assembly_tol, p, v, ok
):  # pragma: no cover - compiled
    """P (N, 3) and its velocity dP/dt (N, 3) for postures q (N, 3) moving at qd (N, 3)
    (:func:`velocity_of` per posture). ``ok`` is False where the loop does not close (P and
    v NaN) or CD is stretched (v NaN, the velocity is unbounded there)."""
    for i in range(q.shape[0]):
        state, p0, p1, p2, v0, v1, v2 = velocity_of(
            L0,
            L1,
            L2,
            q[i, 0],
            q[i, 1],
            q[i, 2],
            qd[i, 0],
            qd[i, 1],
            qd[i, 2],
            branch[i],
            assembly_tol,
        )
        p[i, 0], p[i, 1], p[i, 2] = p0, p1, p2
        v[i, 0], v[i, 1], v[i, 2] = v0, v1, v2
        ok[i] = state == 2


@njit(cache=True, nogil=True, error_model="numpy")
def velocity_of(
    L0, L1, L2, t1, t2, t3, qd0, qd1, qd2, branch, assembly_tol
):  # pragma: no cover - compiled
    """P and its velocity dP/dt for one posture (t1, t2, t3) moving at (qd0, qd1, qd2), by
    differentiating :func:`close_loop`: with C' = L1 e'(theta2) theta2', D' likewise,
    e = D - C, d2 = |e|^2 and s = branch sqrt(L2^2 / d2 - 1/4) (so 2 s s' = -L2^2 d2' / d2^2,
    d2' = 2 e.e'), P_plane' = (C' + D') / 2 + s' R e + s R e' (R the quarter turn
    (u, w) -> (-w, u)); in 3-D, P = (w cos theta1, u, -w sin theta1).

    Returns (state, P, v): state 0 where the loop does not close (P and v NaN), 1 where CD is
    stretched (s = 0: P is there, v NaN), 2 otherwise."""
    nan = np.nan
    closes, cu, cw, du, dw, pu, pw, d2 = close_loop(L0, L1, L2, t2, t3, branch, assembly_tol)
    if not closes:
        return 0, nan, nan, nan, nan, nan, nan
    c1, s1 = math.cos(t1), math.sin(t1)
    p0, p1, p2 = pw * c1, pu, -pw * s1
    eu, ew = du - cu, dw - cw
    h2 = L2 * L2 - 0.25 * d2
    s = branch * math.sqrt(h2 / d2) if h2 > 0.0 else 0.0
    if s == 0.0:  # CD stretched: P is there, its velocity unbounded
        return 1, p0, p1, p2, nan, nan, nan
    cu_d = -L1 * math.sin(t2) * qd1
    cw_d = L1 * math.cos(t2) * qd1
    du_d = -L1 * math.sin(t3) * qd2
    dw_d = L1 * math.cos(t3) * qd2
    eu_d, ew_d = du_d - cu_d, dw_d - cw_d
    d2_d = 2.0 * (eu * eu_d + ew * ew_d)
    s_d = -L2 * L2 * d2_d / (2.0 * s * d2 * d2)
    pu_d = 0.5 * (cu_d + du_d) - s_d * ew - s * ew_d
    pw_d = 0.5 * (cw_d + dw_d) + s_d * eu + s * eu_d
    return 2, p0, p1, p2, pw_d * c1 - pw * s1 * qd0, pu_d, -pw_d * s1 - pw * c1 * qd0


@njit(cache=True, nogil=True)
def count_at_most_from(grid, v, hint):  # pragma: no cover - compiled
    """How many of the increasing ``grid`` are <= v: ``np.searchsorted(grid, v, "right")``
    for a number v (NaN, which numpy sorts last: all of them). ``hint`` is a count at most
    this one (that of the number before, for increasing numbers): a few steps on from it,
    where a bisection's branches are a guess each, then a bisection of the rest; a hint
    above the count, or out of range, is ignored. The same count whatever the hint."""
    n = grid.shape[0]
    if v != v:
        return n
    lo = 0
    if 0 <= hint <= n and (hint == 0 or grid[hint - 1] <= v):
        for _ in range(8):
            if hint == n or grid[hint] > v:
                return hint
            hint += 1
        lo = hint
    hi = n
    while lo < hi:
        mid = (lo + hi) // 2
        if grid[mid] <= v:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True, nogil=True)
def count_at_most(grid, v):  # pragma: no cover - compiled
    """:func:`count_at_most_from` with no hint."""
    return count_at_most_from(grid, v, -1)
