"""The compiled kernels of the validity rules (numba), over many postures at once.

Private: :class:`planner.validity.ValidityChecker` validates inputs, packs a design, its
margins and modes into the parameter vector ``prm`` (layout ``P_*``) and the obstacles into
:func:`planner.geometry.pack_obstacles` arrays, and calls these. One posture's measures go
into a vector of layout ``M_*``; rule codes are ``R_*``, named by :data:`REASONS`. The rules,
their order and the motion certificate (:mod:`planner.validity._certificate`, over these
measures and rates) are explained in :mod:`planner.validity` and
:meth:`planner.validity.ValidityChecker.check_motion`.

The loop closure is :func:`planner._kernels.close_loop`, shared with the kinematics. Its
tolerance (:data:`planner.constants.ASSEMBLY_TOL`) comes in through ``prm[P_ASSEMBLY_TOL]``,
not as a global: numba's on-disk cache would freeze a global's value at compile time. numba's
cache of these kernels is keyed on this file only: after editing a kernel of another module
that they call (``close_loop``, :func:`planner.geometry.segment_min_distance`), clear the
cache (``__pycache__/*.nbi``, ``*.nbc``) or touch this file.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from planner._kernels import close_loop
from planner.constants import ASSEMBLY_TOL
from planner.geometry import segment_min_distance
from planner.kinematics import mode_signs

if TYPE_CHECKING:
    from planner.design import Design
    from planner.validity.margins import Margins

#: Reason codes of the kernels, index -> rule name (0 means valid).
REASONS: tuple[str, ...] = (
    "valid",
    "joint_limits",
    "assembly",
    "kappa_max",
    "working_mode",
    "serial_min",
    "clearance",
)
R_LIMITS, R_ASSEMBLY, R_KAPPA, R_MODE, R_SERIAL, R_CLEAR = 1, 2, 3, 4, 5, 6

# parameter vector layout
P_L0, P_L1, P_L2, P_RAD = 0, 1, 2, 3
P_LO, P_HI = 4, 7  # 3 each
P_BRANCH, P_SIGNS = 10, 11  # signs: 3
P_KAPPA, P_SERIAL, P_CLEAR, P_DLO, P_DHI, P_SERIAL_ON = 14, 15, 16, 17, 18, 19
P_ASSEMBLY_TOL = 20
N_PARAMS = 21


def pack_params(
    design: Design, margins: Margins, assembly_mode: str, working_mode: str, *, serial_rules: bool
) -> np.ndarray:
    """The parameter vector ``prm`` (layout ``P_*``, read-only) of one design, its margins
    and modes: what every kernel of this module reads instead of Python objects.
    ``serial_rules`` False turns rules 4 and 5 off (:class:`planner.validity.ValidityChecker`)."""
    lo, hi = margins.cd_range
    prm = np.empty(N_PARAMS)
    prm[P_L0], prm[P_L1], prm[P_L2] = design.L0, design.L1, design.L2
    prm[P_RAD] = design.link_radius
    prm[P_LO : P_LO + 3] = design.joint_min
    prm[P_HI : P_HI + 3] = design.joint_max
    prm[P_BRANCH] = mode_signs(assembly_mode)[0]
    prm[P_SIGNS : P_SIGNS + 3] = mode_signs(working_mode)
    prm[P_KAPPA], prm[P_SERIAL], prm[P_CLEAR] = (
        margins.kappa_max,
        margins.serial_min,
        margins.clearance,
    )
    prm[P_DLO], prm[P_DHI] = lo, hi
    prm[P_SERIAL_ON] = 1.0 if serial_rules else 0.0
    prm[P_ASSEMBLY_TOL] = ASSEMBLY_TOL
    prm.flags.writeable = False
    return prm


# measure vector layout (per state)
# (M_AXIS: the largest distance of a link point from the axis AB, m: what the turn theta1
# moves a link by, the local bound of the certificate's clearance rate, rates_at;
# M_CLEAR_DIST: the clearance margin of the distal links CP and DP alone, >= M_CLEAR: the
# certificate bounds the proximal links AC and BD, which move slower, with their own rate.
# M_DMARGIN .. M_CLEAR_DIST are contiguous: the certificate keeps them per piece end)
(
    M_REASON,
    M_DMARGIN,
    M_SERIAL,
    M_CLEAR,
    M_AXIS,
    M_CLEAR_DIST,
    M_KAPPA,
    M_SERIAL_RAW,
    M_CLEAR_RAW,
) = range(9)
N_MEASURES = 9
#: The measures a certificate keeps per piece end (M_DMARGIN .. M_CLEAR_DIST).
_KEPT = M_CLEAR_DIST - M_DMARGIN + 1


@njit(cache=True)
def evaluate(
    q0,
    q1,
    q2,
    prm,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    full,
    out,
):  # pragma: no cover
    """Measures of one posture into ``out`` (layout ``M_*``).

    Margins are signed (>= 0 where that rule holds): d-margin in m of |CD| to its kappa band,
    serial margin (min signed measure - serial_min), clearance margin (m). With ``full``
    False the evaluation stops at the first broken rule (unset entries are -inf), the
    clearance rule included: where it breaks, the clearance is that of the first obstacle
    found too close (negative margin, not the least one); elsewhere it is a lower bound
    that keeps at least half of the margin up to clearance + 0.25 m (enough for the rule
    and the motion certificates, which stop at any broken rule).
    """
    evaluate_bounded(
        q0,
        q1,
        q2,
        prm,
        spheres,
        capsules,
        boxes,
        sphere_nodes,
        capsule_nodes,
        box_nodes,
        sphere_grid,
        full,
        np.inf,
        out,
    )


@njit(cache=True, inline="always")  # into evaluate and path_extremes: no call per posture
def evaluate_bounded(
    q0,
    q1,
    q2,
    prm,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    full,
    clear_upper,
    out,
):  # pragma: no cover
    """:func:`evaluate`; in ``full`` mode the clearance is exact only where it is below
    ``clear_upper`` (a value >= ``clear_upper`` otherwise), for running minima; with
    ``clear_upper`` = -inf it is not measured (-inf; the other rules' measures are)."""
    L0, L1, L2 = prm[P_L0], prm[P_L1], prm[P_L2]
    for k in range(N_MEASURES):
        out[k] = -np.inf
    out[M_REASON] = 0.0
    reason = 0
    if not (
        q0 >= prm[P_LO]
        and q1 >= prm[P_LO + 1]
        and q2 >= prm[P_LO + 2]
        and q0 <= prm[P_HI]
        and q1 <= prm[P_HI + 1]
        and q2 <= prm[P_HI + 2]
    ):
        reason = R_LIMITS
        if not full:
            out[M_REASON] = reason
            return
    closes, cu, cw, du, dw, pu, pw, d2 = close_loop(
        L0, L1, L2, q1, q2, prm[P_BRANCH], prm[P_ASSEMBLY_TOL]
    )
    if not closes:
        out[M_REASON] = reason if reason else R_ASSEMBLY
        return
    d = math.sqrt(d2)
    out[M_AXIS] = max(abs(cw), max(abs(dw), abs(pw)))  # a link's points lie between its ends
    # kappa band on |CD|
    dmargin = min(d - 2.0 * L2 * prm[P_DLO], 2.0 * L2 * prm[P_DHI] - d)
    out[M_DMARGIN] = dmargin
    ratio = min(d / (2.0 * L2), 1.0)
    tan_half = ratio / math.sqrt(max(1.0 - ratio * ratio, 0.0)) if ratio < 1.0 else np.inf
    out[M_KAPPA] = max(tan_half, 1.0 / tan_half) if tan_half > 0.0 else np.inf
    if reason == 0 and dmargin < 0.0:
        reason = R_KAPPA
        if not full:
            out[M_REASON] = reason
            return
    # passive angles
    t4 = math.atan2(pw - cw, pu - cu)
    t5 = math.atan2(pw - dw, pu - du)
    m_axis = prm[P_SIGNS] * pw / (L1 + L2)
    m_a = prm[P_SIGNS + 1] * math.sin(t4 - q1)
    m_b = prm[P_SIGNS + 2] * math.sin(t5 - q2)
    serial = min(m_axis, min(m_a, m_b))
    out[M_SERIAL_RAW] = serial
    if prm[P_SERIAL_ON] == 0.0:
        out[M_SERIAL] = np.inf  # rules 4 and 5 off: nothing to certify
    else:
        out[M_SERIAL] = serial - prm[P_SERIAL]
        if reason == 0 and serial <= 0.0:
            reason = R_MODE
        elif reason == 0 and serial < prm[P_SERIAL]:
            reason = R_SERIAL
    if reason and not full:
        out[M_REASON] = reason
        return
    clear, clear_dist = _link_clearance(
        q0,
        prm,
        cu,
        cw,
        du,
        dw,
        pu,
        pw,
        spheres,
        capsules,
        boxes,
        sphere_nodes,
        capsule_nodes,
        box_nodes,
        sphere_grid,
        full,
        clear_upper,
    )
    out[M_CLEAR_RAW] = clear
    out[M_CLEAR] = clear - prm[P_CLEAR]
    out[M_CLEAR_DIST] = clear_dist - prm[P_CLEAR]
    if reason == 0 and out[M_CLEAR] < 0.0:
        reason = R_CLEAR
    out[M_REASON] = reason


@njit(cache=True, inline="always")  # into evaluate_bounded, as that is into its callers
def _link_clearance(
    q0,
    prm,
    cu,
    cw,
    du,
    dw,
    pu,
    pw,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    full,
    clear_upper,
):  # pragma: no cover
    """The clearance step of :func:`evaluate_bounded`: the least distance (m) of the four
    links' surfaces to the obstacles, the links given by the closed loop's in-plane points
    C (cu, cw), D (du, dw) and P (pu, pw) and turned by theta1 = ``q0``. Exact in ``full``
    mode below ``clear_upper``; otherwise relaxed as :func:`evaluate` says. Returns (all
    links, distal links CP and DP alone): the distal links are measured first, so their own
    value is known at no extra walk (the proximal walks only look for closer obstacles)."""
    # links in 3-D: rotate in-plane (u, w) about +y by theta1
    c1, s1 = math.cos(q0), math.sin(q0)
    rad = prm[P_RAD]
    # outside full mode the clearance is exact up to clearance + 0.25 m only: a motion's
    # certificate spends at most ~0.1 m of clearance per coarse step (rate_clear times the
    # step), so larger values certify nothing more, and the obstacle trees stop early
    upper = clear_upper + rad if full else prm[P_CLEAR] + rad + 0.25
    # outside full mode the trees are walked relaxed (planner.geometry.segment_min_distance):
    # the clearance rule is still decided exactly, and a margin above it is known to at
    # least half its size, which is what the certificate's cones need
    relax_from = prm[P_CLEAR] + rad
    relax = 0.0 if full else 0.5
    best = upper
    half = 0.5 * prm[P_L0]
    ends_u = (-half, half, cu, du)
    ends_w = (0.0, 0.0, cw, dw)
    # the distal links first: they reach farthest, so in clutter they are the likelier to
    # break the rule, and a broken rule ends a relaxed check (the others are not measured);
    # no obstacle: nothing to measure (best stays at its cap)
    n_obstacles = spheres.shape[0] + capsules.shape[0] + boxes.shape[0]
    if full and clear_upper == -np.inf:
        n_obstacles = 0  # not measured (evaluate_bounded): best stays -inf
    best_dist = best  # the distal links' own value (k = 0, 1)
    for k in range(4 if n_obstacles > 0 else 0):
        link = (2, 3, 0, 1)[k]
        au, aw = ends_u[link], ends_w[link]
        if link < 2:
            bu, bw = (cu, cw) if link == 0 else (du, dw)
        else:
            bu, bw = pu, pw
        dist = segment_min_distance(
            aw * c1,
            au,
            -aw * s1,
            bw * c1,
            bu,
            -bw * s1,
            spheres,
            capsules,
            boxes,
            sphere_nodes,
            capsule_nodes,
            box_nodes,
            sphere_grid,
            best,
            relax_from,
            relax,
        )
        if dist < best:
            best = dist
            if k < 2:
                best_dist = best
            if relax > 0.0 and best < relax_from:
                break  # the clearance rule is broken: decided (segment_min_distance)
    return best - rad, best_dist - rad


@njit(cache=True)
def evaluate_many(
    q, prm, spheres, capsules, boxes, sphere_nodes, capsule_nodes, box_nodes, sphere_grid, full, out
):  # pragma: no cover
    for i in range(q.shape[0]):
        evaluate(
            q[i, 0],
            q[i, 1],
            q[i, 2],
            prm,
            spheres,
            capsules,
            boxes,
            sphere_nodes,
            capsule_nodes,
            box_nodes,
            sphere_grid,
            full,
            out[i],
        )


@njit(cache=True)
def rates_at(dq0, dq1, dq2, prm, s_min, axis_a, axis_b, w):  # pragma: no cover - compiled
    """Lipschitz bounds over the parameter t of a straight motion q0 + t dq, for the
    d-margin, serial margin and clearance margin, valid on a piece [ta, ta + w] of it where
    |sin(theta4 - theta5)| >= s_min > 0 and whose ends have their link points at most
    ``axis_a`` and ``axis_b`` from the axis AB (measure ``M_AXIS``; the global bound
    L1 + L2 with w = 0 holds on any piece).

    The loop closure C + L2 e(theta4) = D + L2 e(theta5) differentiated and projected on
    e(theta5) gives |dtheta4| <= |dD - dC| / (L2 |sin(theta4 - theta5)|)
    <= L1 (|dtheta2| + |dtheta3|) / (L2 s_min), and the same for theta5. P's in-plane
    velocity also solves (v_P - v_C) . e4 = 0, (v_P - v_D) . e5 = 0, a 2x2 system of unit
    rows at the apex angle: |v_P| <= |(v_C . e4, v_D . e5)| / sqrt(1 - |cos(apex)|)
    <= L1 hypot(|dtheta2|, |dtheta3|) / sqrt(1 - sqrt(1 - s_min^2)); the lesser of the two
    bounds holds. A link point's distance r from the axis changes at most at the in-plane
    speed v, so on the piece r <= (axis_a + axis_b + v w) / 2 (the two cones), and the point
    moves by r |dtheta1| across the plane and v within it (orthogonal: their hypot).

    Returns (rate_cd, rate_serial, rate_clear, rate_prox): rate_clear bounds every link's
    clearance, rate_prox the proximal links' AC and BD alone (their points lie within L1 of
    the axis and move in-plane at most as C or D: with L1 < L2 a few times slower than the
    distal links, which is what lets the certificate take longer pieces where a proximal
    link is the closest, :func:`certify_motion`)."""
    L1, L2 = prm[P_L1], prm[P_L2]
    reach = L1 + L2
    a0, a1, a2 = abs(dq0), abs(dq1), abs(dq2)
    rate_cd = L1 * (a1 + a2)
    r45 = rate_cd / (L2 * s_min)
    rate_serial = max(max(r45 + a1, r45 + a2), (L1 * a1 + L2 * r45) / reach)
    v_c = L1 * a1
    v_d = L1 * a2
    cos_max = math.sqrt(max(1.0 - s_min * s_min, 0.0))
    v_p = min(v_c, v_d) + L2 * r45
    if cos_max < 1.0:
        v_p = min(v_p, L1 * math.hypot(a1, a2) / math.sqrt(1.0 - cos_max))
    v_cd = max(v_c, v_d)
    v_in = max(v_cd, v_p)  # the fastest in-plane motion of a link point
    r = min(reach, 0.5 * (axis_a + axis_b + v_in * w))
    # AC and BD lie within L1 of the axis and move in-plane at most as C or D
    rate_prox = math.hypot(min(L1, r) * a0, v_cd)
    rate_clear = max(rate_prox, math.hypot(r * a0, v_in))
    return rate_cd, rate_serial, rate_clear, rate_prox


@njit(cache=True)
def rates(dq0, dq1, dq2, prm):  # pragma: no cover - compiled
    """:func:`rates_at` valid on the whole motion wherever kappa(A) <= K = kappa_max: there
    |sin(theta4 - theta5)| = (1 + |cos|) / kappa >= 1 / K; every link point within L1 + L2
    of the axis."""
    reach = prm[P_L1] + prm[P_L2]
    return rates_at(dq0, dq1, dq2, prm, 1.0 / prm[P_KAPPA], reach, reach, 0.0)


@njit(cache=True, inline="always")
def sin_apex_min(prm, lb_cd):  # pragma: no cover - compiled
    """Least |sin(theta4 - theta5)| over postures whose |CD| lies in the kappa band shrunk by
    ``lb_cd`` >= 0 at both ends: |CD| = 2 L2 sin(gamma / 2) with gamma the apex angle, and
    sin(gamma) is concave in gamma on [0, pi], so its minimum is at an end of the range."""
    two_l2 = 2.0 * prm[P_L2]
    lo = min(prm[P_DLO] + lb_cd / two_l2, 1.0)
    hi = max(prm[P_DHI] - lb_cd / two_l2, lo)
    # sin(gamma) = 2 sin(gamma/2) cos(gamma/2) = 2 r sqrt(1 - r^2)
    s_lo = 2.0 * lo * math.sqrt(max(1.0 - lo * lo, 0.0))
    s_hi = 2.0 * hi * math.sqrt(max(1.0 - hi * hi, 0.0))
    return min(s_lo, s_hi)
