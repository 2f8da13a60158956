"""Validity of postures and of straight joint-space motions inside one working mode.

A posture q is *valid* for a segment in working mode ``(s_axis, s_A, s_B)`` and assembly mode
``s`` when every rule holds (checked in this order; the first broken one is the *reason*):

1. ``joint_limits``: ``joint_min <= q <= joint_max`` (literal values, never wrapped);
2. ``assembly``: the loop closes (0 < |CD| <= 2 L2); forward kinematics then takes the
   segment's assembly mode;
3. ``kappa_max``: kappa(A) <= ``margins.kappa_max`` (away from parallel singularities);
4. ``working_mode``: every signed serial measure has the segment's sign;
5. ``serial_min``: |w| / (L1 + L2), |sin(theta4 - theta2)| and |sin(theta5 - theta3)| are all
   >= ``margins.serial_min``;
6. ``clearance``: every link capsule (AC, BD, CP, DP, radius ``link_radius``) is at least
   ``margins.clearance`` from every obstacle.

Motions are the straight joint-space segments between two postures. :meth:`ValidityChecker.
check_motion` certifies a whole segment, it does not sample it at a fixed step; the argument
is in its docstring. Everything runs in compiled numba kernels over many states at once.

Why kappa(A) is checked through |CD|: the apex angle of the isosceles triangle C-P-D is
``gamma = |theta4 - theta5|`` (mod pi) and ``|CD| = 2 L2 sin(gamma / 2)``, so (corrected eq. 8)
``kappa(A) = max(cot(gamma/2), tan(gamma/2)) <= K`` exactly when
``|CD| / (2 L2)`` lies in ``[1 / sqrt(1 + K^2), K / sqrt(1 + K^2)]``. |CD| depends on theta2 and
theta3 only and moves by at most ``L1 (|dtheta2| + |dtheta3|)``, a global bound.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np
from numba import njit

from planner.design import Design
from planner.exceptions import InputError
from planner.geometry import Obstacle, PackedObstacles, pack_obstacles, segment_min_distance
from planner.kinematics import ASSEMBLY_MODES, WORKING_MODES, mode_signs

__all__ = [
    "DEFAULT_CLEARANCE",
    "DEFAULT_KAPPA_MAX",
    "DEFAULT_SERIAL_MIN",
    "DIAGNOSTIC_STEP",
    "MIN_CERTIFIED_STEP",
    "REASONS",
    "Margins",
    "MotionReport",
    "PathReport",
    "StateReport",
    "ValidityChecker",
    "assembly_reason",
    "densify",
    "warm_up",
]

#: Default bound on kappa(A): the apex angle C-P-D stays more than 11.4 deg away from 0 and
#: 180 deg, where the Cartesian velocity error gain of the parallel part is at most 10.
DEFAULT_KAPPA_MAX = 10.0
#: Default lower bound on each serial measure: legs at least 2.9 deg from stretched/folded and
#: P at least 5 % of the reach from the axis AB (kappa(B) stays finite and modes cannot flip).
DEFAULT_SERIAL_MIN = 0.05
#: Default least distance between link capsules and obstacles, m.
DEFAULT_CLEARANCE = 0.01
#: Shortest joint-space piece (max-norm, rad) that the motion certificate subdivides to; a
#: motion whose margins cannot be certified at this scale is rejected (conservative).
MIN_CERTIFIED_STEP = 1e-4
#: Default max-norm step (rad) of the first sampling of a motion, before certification
#: subdivides where margins are tight. Any value is sound; this one is tuned for speed.
DEFAULT_COARSE_STEP = 0.08

#: Max-norm step (rad) of the samples along a path whose extremes :meth:`ValidityChecker.
#: check_path` reports (diagnostics only: validity is certified, not sampled).
DIAGNOSTIC_STEP = 0.02

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
_R_LIMITS, _R_ASSEMBLY, _R_KAPPA, _R_MODE, _R_SERIAL, _R_CLEAR = 1, 2, 3, 4, 5, 6


@dataclass(frozen=True, slots=True)
class Margins:
    """Safety margins of a valid posture (``docs/conventions.md``, wire field ``margins``).

    Parameters
    ----------
    kappa_max : float, default :data:`DEFAULT_KAPPA_MAX` (10)
        Upper bound on kappa(A), finite and > 1.
    serial_min : float, default :data:`DEFAULT_SERIAL_MIN` (0.05)
        Lower bound on |w| / (L1 + L2), |sin(theta4 - theta2)|, |sin(theta5 - theta3)|, in
        (0, 1). It must be positive: a zero margin would let a motion touch a serial
        singularity, where the working mode is undefined.
    clearance : float, default :data:`DEFAULT_CLEARANCE` (0.01 m)
        Least distance from every link capsule to every obstacle, m, >= 0.
    """

    kappa_max: float = DEFAULT_KAPPA_MAX
    serial_min: float = DEFAULT_SERIAL_MIN
    clearance: float = DEFAULT_CLEARANCE

    def __post_init__(self) -> None:
        for name in ("kappa_max", "serial_min", "clearance"):
            value = getattr(self, name)
            try:
                value = float(value)
            except (TypeError, ValueError) as exc:
                raise InputError(f"margins.{name} must be a number, got {value!r}") from exc
            if not math.isfinite(value):
                raise InputError(f"margins.{name} must be finite, got {value}")
            object.__setattr__(self, name, value)
        if not self.kappa_max > 1.0:
            raise InputError(f"margins.kappa_max must be > 1, got {self.kappa_max}")
        if not 0.0 < self.serial_min < 1.0:
            raise InputError(f"margins.serial_min must lie in (0, 1), got {self.serial_min}")
        if self.clearance < 0.0:
            raise InputError(f"margins.clearance must be >= 0, got {self.clearance}")

    @property
    def cd_range(self) -> tuple[float, float]:
        """(low, high) bounds on |CD| / (2 L2) equivalent to kappa(A) <= kappa_max."""
        k = self.kappa_max
        r = math.sqrt(1.0 + k * k)
        return 1.0 / r, k / r


# ----------------------------------------------------------------------------- kernels
# parameter vector layout
_P_L0, _P_L1, _P_L2, _P_RAD = 0, 1, 2, 3
_P_LO, _P_HI = 4, 7  # 3 each
_P_BRANCH, _P_SIGNS = 10, 11  # signs: 3
_P_KAPPA, _P_SERIAL, _P_CLEAR, _P_DLO, _P_DHI, _P_SERIAL_ON = 14, 15, 16, 17, 18, 19
_N_PARAMS = 20
# measure vector layout (per state)
_M_REASON, _M_DMARGIN, _M_SERIAL, _M_CLEAR, _M_KAPPA, _M_SERIAL_RAW, _M_CLEAR_RAW = range(7)
_N_MEASURES = 7


@njit(cache=True)
def _evaluate(q0, q1, q2, prm, spheres, capsules, boxes, full, out):  # pragma: no cover
    """Measures of one posture into ``out`` (layout ``_M_*``).

    Margins are signed (>= 0 where that rule holds): d-margin in m of |CD| to its kappa band,
    serial margin (min signed measure - serial_min), clearance margin (m). With ``full``
    False the evaluation stops at the first broken rule (unset entries are -inf) and the
    clearance is exact only below clearance + 1 m (a lower bound above: enough for rules and
    certificates).
    """
    _evaluate_bounded(q0, q1, q2, prm, spheres, capsules, boxes, full, np.inf, out)


@njit(cache=True)
def _evaluate_bounded(
    q0, q1, q2, prm, spheres, capsules, boxes, full, clear_upper, out
):  # pragma: no cover
    """:func:`_evaluate`; in ``full`` mode the clearance is exact only where it is below
    ``clear_upper`` (a value >= ``clear_upper`` otherwise), for running minima."""
    L0, L1, L2 = prm[_P_L0], prm[_P_L1], prm[_P_L2]
    for k in range(_N_MEASURES):
        out[k] = -np.inf
    out[_M_REASON] = 0.0
    reason = 0
    if not (
        q0 >= prm[_P_LO]
        and q1 >= prm[_P_LO + 1]
        and q2 >= prm[_P_LO + 2]
        and q0 <= prm[_P_HI]
        and q1 <= prm[_P_HI + 1]
        and q2 <= prm[_P_HI + 2]
    ):
        reason = _R_LIMITS
        if not full:
            out[_M_REASON] = reason
            return
    half = 0.5 * L0
    cu = -half + L1 * math.cos(q1)
    cw = L1 * math.sin(q1)
    du = half + L1 * math.cos(q2)
    dw = L1 * math.sin(q2)
    eu, ew = du - cu, dw - cw
    d2 = eu * eu + ew * ew
    d = math.sqrt(d2)
    if not (d > 0.0 and d <= 2.0 * L2 * (1.0 + 1e-12)):
        out[_M_REASON] = reason if reason else _R_ASSEMBLY
        return
    # kappa band on |CD|
    dmargin = min(d - 2.0 * L2 * prm[_P_DLO], 2.0 * L2 * prm[_P_DHI] - d)
    out[_M_DMARGIN] = dmargin
    ratio = min(d / (2.0 * L2), 1.0)
    tan_half = ratio / math.sqrt(max(1.0 - ratio * ratio, 0.0)) if ratio < 1.0 else np.inf
    out[_M_KAPPA] = max(tan_half, 1.0 / tan_half) if tan_half > 0.0 else np.inf
    if reason == 0 and dmargin < 0.0:
        reason = _R_KAPPA
        if not full:
            out[_M_REASON] = reason
            return
    # P in the plane, passive angles
    h2 = L2 * L2 - 0.25 * d2
    s = prm[_P_BRANCH] * math.sqrt(h2 / d2) if h2 > 0.0 else 0.0
    pu = 0.5 * (cu + du) - s * ew
    pw = 0.5 * (cw + dw) + s * eu
    t4 = math.atan2(pw - cw, pu - cu)
    t5 = math.atan2(pw - dw, pu - du)
    m_axis = prm[_P_SIGNS] * pw / (L1 + L2)
    m_a = prm[_P_SIGNS + 1] * math.sin(t4 - q1)
    m_b = prm[_P_SIGNS + 2] * math.sin(t5 - q2)
    serial = min(m_axis, min(m_a, m_b))
    out[_M_SERIAL_RAW] = serial
    if prm[_P_SERIAL_ON] == 0.0:
        out[_M_SERIAL] = np.inf  # rules 4 and 5 off: nothing to certify
    else:
        out[_M_SERIAL] = serial - prm[_P_SERIAL]
        if reason == 0 and serial <= 0.0:
            reason = _R_MODE
        elif reason == 0 and serial < prm[_P_SERIAL]:
            reason = _R_SERIAL
    if reason and not full:
        out[_M_REASON] = reason
        return
    # links in 3-D: rotate in-plane (u, w) about +y by theta1
    c1, s1 = math.cos(q0), math.sin(q0)
    rad = prm[_P_RAD]
    upper = clear_upper + rad if full else prm[_P_CLEAR] + rad + 1.0
    best = upper
    ends_u = (-half, half, cu, du)
    ends_w = (0.0, 0.0, cw, dw)
    for link in range(4):
        au, aw = ends_u[link], ends_w[link]
        if link < 2:
            bu, bw = (cu, cw) if link == 0 else (du, dw)
        else:
            bu, bw = pu, pw
        dist = segment_min_distance(
            aw * c1, au, -aw * s1, bw * c1, bu, -bw * s1, spheres, capsules, boxes, best
        )
        if dist < best:
            best = dist
    clear = best - rad
    out[_M_CLEAR_RAW] = clear
    out[_M_CLEAR] = clear - prm[_P_CLEAR]
    if reason == 0 and out[_M_CLEAR] < 0.0:
        reason = _R_CLEAR
    out[_M_REASON] = reason


@njit(cache=True)
def _evaluate_many(q, prm, spheres, capsules, boxes, full, out):  # pragma: no cover
    for i in range(q.shape[0]):
        _evaluate(q[i, 0], q[i, 1], q[i, 2], prm, spheres, capsules, boxes, full, out[i])


@njit(cache=True)
def _rates_s(dq0, dq1, dq2, prm, s_min):  # pragma: no cover - compiled
    """Lipschitz bounds over the parameter t in [0, 1] of a straight motion q0 + t dq, for the
    d-margin, serial margin and clearance margin, valid wherever
    |sin(theta4 - theta5)| >= s_min > 0.

    The loop closure C + L2 e(theta4) = D + L2 e(theta5) differentiated and projected on
    e(theta5) gives |dtheta4| <= |dD - dC| / (L2 |sin(theta4 - theta5)|)
    <= L1 (|dtheta2| + |dtheta3|) / (L2 s_min), and the same for theta5."""
    L1, L2 = prm[_P_L1], prm[_P_L2]
    reach = L1 + L2
    a0, a1, a2 = abs(dq0), abs(dq1), abs(dq2)
    rate_cd = L1 * (a1 + a2)
    r45 = rate_cd / (L2 * s_min)
    rate_serial = max(max(r45 + a1, r45 + a2), (L1 * a1 + L2 * r45) / reach)
    # a point of a link moves by (distance to the axis AB) |dtheta1| + its in-plane motion
    v_c = L1 * a1
    v_d = L1 * a2
    v_p = min(v_c, v_d) + L2 * r45
    rate_clear = max(L1 * a0 + max(v_c, v_d), reach * a0 + max(max(v_c, v_d), v_p))
    return rate_cd, rate_serial, rate_clear


@njit(cache=True)
def _rates(dq0, dq1, dq2, prm):  # pragma: no cover - compiled
    """:func:`_rates_s` valid wherever kappa(A) <= K = kappa_max: there
    |sin(theta4 - theta5)| = (1 + |cos|) / kappa >= 1 / K."""
    return _rates_s(dq0, dq1, dq2, prm, 1.0 / prm[_P_KAPPA])


@njit(cache=True, inline="always")
def _sin_apex_min(prm, lb_cd):  # pragma: no cover - compiled
    """Least |sin(theta4 - theta5)| over postures whose |CD| lies in the kappa band shrunk by
    ``lb_cd`` >= 0 at both ends: |CD| = 2 L2 sin(gamma / 2) with gamma the apex angle, and
    sin(gamma) is concave in gamma on [0, pi], so its minimum is at an end of the range."""
    two_l2 = 2.0 * prm[_P_L2]
    lo = min(prm[_P_DLO] + lb_cd / two_l2, 1.0)
    hi = max(prm[_P_DHI] - lb_cd / two_l2, lo)
    # sin(gamma) = 2 sin(gamma/2) cos(gamma/2) = 2 r sqrt(1 - r^2)
    s_lo = 2.0 * lo * math.sqrt(max(1.0 - lo * lo, 0.0))
    s_hi = 2.0 * hi * math.sqrt(max(1.0 - hi * hi, 0.0))
    return min(s_lo, s_hi)


@njit(cache=True)
def _check_motion(
    qa, qb, prm, spheres, capsules, boxes, coarse_step, min_step, skip_ends
):  # pragma: no cover
    """Certify the straight motion qa -> qb. Returns (reason, t): reason 0 when every posture
    of the motion is valid, else the rule found broken (or not certifiable) near parameter t.
    Algorithm and proof: :meth:`ValidityChecker.check_motion`."""
    dq0, dq1, dq2 = qb[0] - qa[0], qb[1] - qa[1], qb[2] - qa[2]
    length = max(abs(dq0), max(abs(dq1), abs(dq2)))
    n = max(1, math.ceil(length / coarse_step))
    ts = np.empty(n + 1)
    ms = np.empty((n + 1, _N_MEASURES))
    done = np.zeros(n + 1, dtype=np.bool_)
    if skip_ends:
        _evaluate(qa[0], qa[1], qa[2], prm, spheres, capsules, boxes, True, ms[0])
        _evaluate(qb[0], qb[1], qb[2], prm, spheres, capsules, boxes, True, ms[n])
        ms[0, _M_REASON] = 0.0
        ms[n, _M_REASON] = 0.0
        done[0] = True
        done[n] = True
    # coarse samples, in bisection order so an obstacle in the middle is met early
    stride = 1
    while stride < n:
        stride *= 2
    while stride >= 1:
        for k in range(0, n + 1, stride):
            if done[k]:
                continue
            done[k] = True
            t = k / n
            ts[k] = t
            _evaluate(
                qa[0] + t * dq0,
                qa[1] + t * dq1,
                qa[2] + t * dq2,
                prm,
                spheres,
                capsules,
                boxes,
                False,
                ms[k],
            )
            if ms[k, _M_REASON] != 0.0:
                return int(ms[k, _M_REASON]), t
        stride //= 2
    for k in range(n + 1):
        ts[k] = k / n
    rate_cd = _rates(dq0, dq1, dq2, prm)[0]
    tiny = min_step / max(length, 1e-300)
    # depth-first certification with an explicit stack of intervals
    cap = n + 128
    st_t = np.empty((cap, 2))
    st_m = np.empty((cap, 2, 3))
    top = 0
    for k in range(n):
        st_t[top, 0], st_t[top, 1] = ts[k], ts[k + 1]
        for j in range(3):
            st_m[top, 0, j] = ms[k, 1 + j]
            st_m[top, 1, j] = ms[k + 1, 1 + j]
        top += 1
    mid = np.empty(_N_MEASURES)
    while top > 0:
        top -= 1
        ta, tb = st_t[top, 0], st_t[top, 1]
        w = tb - ta
        lb_cd = 0.5 * (st_m[top, 0, 0] + st_m[top, 1, 0] - rate_cd * w)
        if lb_cd >= 0.0:
            # |CD| stays lb_cd inside its band on the piece: a local bound on the apex sine
            _, rate_serial, rate_clear = _rates_s(dq0, dq1, dq2, prm, _sin_apex_min(prm, lb_cd))
        else:
            rate_serial = rate_clear = np.inf
        lb_se = 0.5 * (st_m[top, 0, 1] + st_m[top, 1, 1] - rate_serial * w)
        lb_cl = 0.5 * (st_m[top, 0, 2] + st_m[top, 1, 2] - rate_clear * w)
        if lb_cd >= 0.0 and lb_se >= 0.0 and lb_cl >= 0.0:
            continue
        tm = 0.5 * (ta + tb)
        if w <= tiny or top + 2 > cap:
            if lb_cd < 0.0:
                return _R_KAPPA, tm
            if lb_se < 0.0:
                return _R_SERIAL, tm
            return _R_CLEAR, tm
        _evaluate(
            qa[0] + tm * dq0,
            qa[1] + tm * dq1,
            qa[2] + tm * dq2,
            prm,
            spheres,
            capsules,
            boxes,
            False,
            mid,
        )
        if mid[_M_REASON] != 0.0:
            return int(mid[_M_REASON]), tm
        ma = st_m[top, 0].copy()
        mb = st_m[top, 1].copy()
        st_t[top, 0], st_t[top, 1] = ta, tm
        st_t[top + 1, 0], st_t[top + 1, 1] = tm, tb
        for j in range(3):
            st_m[top, 0, j] = ma[j]
            st_m[top, 1, j] = mid[1 + j]
            st_m[top + 1, 0, j] = mid[1 + j]
            st_m[top + 1, 1, j] = mb[j]
        top += 2
    return 0, 1.0


@njit(cache=True)
def _check_path(
    q, prm, spheres, capsules, boxes, coarse_step, min_step, reasons, ts
):  # pragma: no cover
    """Certify every motion of a waypoint path (N, 3); stops at the first broken motion."""
    for i in range(q.shape[0] - 1):
        r, t = _check_motion(
            q[i], q[i + 1], prm, spheres, capsules, boxes, coarse_step, min_step, False
        )
        reasons[i] = r
        ts[i] = t
        if r != 0:
            return i
    return -1


@njit(cache=True)
def _path_extremes(q, step, prm, spheres, capsules, boxes, out):  # pragma: no cover
    """(min clearance, max kappa_A, min signed serial) over the waypoints of q (N, 3) and
    samples every ``step`` rad (max-norm) on the motions between them, into out (3,); NaN
    when no sample closes the loop."""
    m = np.empty(_N_MEASURES)
    lo_clear, hi_kappa, lo_serial = np.inf, -np.inf, np.inf
    found = False
    for i in range(q.shape[0]):
        n = 1
        if i > 0:
            length = 0.0
            for j in range(3):
                length = max(length, abs(q[i, j] - q[i - 1, j]))
            n = max(1, math.ceil(length / step))
        for k in range(1, n + 1):
            if i == 0:
                a0, a1, a2 = q[0, 0], q[0, 1], q[0, 2]
            else:
                t = k / n
                a0 = q[i - 1, 0] + t * (q[i, 0] - q[i - 1, 0])
                a1 = q[i - 1, 1] + t * (q[i, 1] - q[i - 1, 1])
                a2 = q[i - 1, 2] + t * (q[i, 2] - q[i - 1, 2])
            # only obstacles that may lower the running minimum are measured exactly
            _evaluate_bounded(a0, a1, a2, prm, spheres, capsules, boxes, True, lo_clear, m)
            if m[_M_KAPPA] > -np.inf:
                found = True
                lo_clear = min(lo_clear, m[_M_CLEAR_RAW])
                hi_kappa = max(hi_kappa, m[_M_KAPPA])
                lo_serial = min(lo_serial, m[_M_SERIAL_RAW])
    if not found:
        out[0] = out[1] = out[2] = np.nan
    else:
        out[0], out[1], out[2] = lo_clear, hi_kappa, lo_serial


# ----------------------------------------------------------------------------- reports
@dataclass(frozen=True, slots=True)
class StateReport:
    """Validity and measures of N postures (arrays of shape (N,)).

    Attributes
    ----------
    valid : bool
    reason : str (object array), the first broken rule (see :data:`REASONS`), 'valid' if none.
    kappa_A : kappa(A) (inf at C = D or CD stretched, NaN where the loop does not close).
    serial_margin : the smallest serial measure, signed by the segment's working mode
        (negative: another working mode), NaN where the loop does not close.
    clearance : least distance link capsule - obstacle, m (inf without obstacles; negative
        when a link enters an obstacle), NaN where the loop does not close.
    """

    valid: np.ndarray
    reason: np.ndarray
    kappa_A: np.ndarray
    serial_margin: np.ndarray
    clearance: np.ndarray


@dataclass(frozen=True, slots=True)
class MotionReport:
    """Outcome of one certified straight motion: ``valid``; else ``reason`` (a rule of
    :data:`REASONS`) and ``t`` in [0, 1], where along the motion it was found."""

    valid: bool
    reason: str
    t: float


@dataclass(frozen=True, slots=True)
class PathReport:
    """Outcome of a certified waypoint path and measures sampled along it.

    ``valid``; ``bad_motion`` (index i of the first invalid motion i -> i+1, 0 for an invalid
    single posture, or -1), ``reason`` and ``t``; ``min_clearance``, ``max_kappa_A``,
    ``min_serial_margin``: extremes over the waypoints and samples every ``sample_step`` rad
    (max-norm) along the path (the certificate guarantees the margins hold in between);
    ``length``: sum of Euclidean joint distances, rad.
    """

    valid: bool
    bad_motion: int
    reason: str
    t: float
    min_clearance: float
    max_kappa_A: float
    min_serial_margin: float
    length: float


def densify(waypoints: np.ndarray, step: float) -> np.ndarray:
    """Waypoints (N, 3) with samples added so that no max-norm step exceeds ``step`` rad."""
    w = np.asarray(waypoints, dtype=float)
    parts = [w[:1]]
    for a, b in pairwise(w):
        n = max(1, math.ceil(float(np.max(np.abs(b - a))) / step))
        parts.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.vstack(parts)


@dataclass(frozen=True, slots=True, eq=False)
class ValidityChecker:
    """Validity of postures and motions of one design in one working and assembly mode.

    Parameters
    ----------
    design : Design
    margins : Margins
    obstacles : sequence of Sphere, Box, Capsule (wire dictionaries are accepted too)
    assembly_mode : '+' | '-'
    working_mode : one of :data:`planner.kinematics.WORKING_MODES`, e.g. '+-+'
    coarse_step : float, rad
        First sampling step of :meth:`check_motion` (max-norm); speed only, never soundness.
    serial_rules : bool, default True
        False drops rules 4 and 5 (working mode and serial margin; the measures are still
        reported). For motions that end on a serial singularity (mode-change transits), whose
        mode signs the caller checks itself; every other rule stays certified.

    Examples
    --------
    >>> from planner.design import Design
    >>> chk = ValidityChecker(Design.default(), Margins(), [], "+", "+-+")
    >>> chk.check_states([[0.0, 2.0, 1.0]]).reason.tolist()
    ['valid']
    """

    design: Design
    margins: Margins = field(default_factory=Margins)
    obstacles: Sequence[Obstacle] = ()
    assembly_mode: str = "+"
    working_mode: str = "+++"
    coarse_step: float = DEFAULT_COARSE_STEP
    serial_rules: bool = True
    _warm: bool = field(default=True, repr=False)
    _packed: PackedObstacles = field(init=False, repr=False)
    _prm: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.assembly_mode not in ASSEMBLY_MODES:
            raise InputError(f"assembly_mode must be '+' or '-', got {self.assembly_mode!r}")
        if self.working_mode not in WORKING_MODES:
            raise InputError(
                f"working_mode must be one of {', '.join(WORKING_MODES)}, got {self.working_mode!r}"
            )
        if not (math.isfinite(self.coarse_step) and self.coarse_step > 0):
            raise InputError(f"coarse_step must be > 0, got {self.coarse_step}")
        object.__setattr__(self, "obstacles", tuple(self.obstacles))
        object.__setattr__(self, "_packed", pack_obstacles(self.obstacles))
        d, m = self.design, self.margins
        lo, hi = m.cd_range
        prm = np.empty(_N_PARAMS)
        prm[_P_L0], prm[_P_L1], prm[_P_L2], prm[_P_RAD] = d.L0, d.L1, d.L2, d.link_radius
        prm[_P_LO : _P_LO + 3] = d.joint_min
        prm[_P_HI : _P_HI + 3] = d.joint_max
        prm[_P_BRANCH] = mode_signs(self.assembly_mode)[0]
        prm[_P_SIGNS : _P_SIGNS + 3] = mode_signs(self.working_mode)
        prm[_P_KAPPA], prm[_P_SERIAL], prm[_P_CLEAR] = m.kappa_max, m.serial_min, m.clearance
        prm[_P_DLO], prm[_P_DHI] = lo, hi
        prm[_P_SERIAL_ON] = 1.0 if self.serial_rules else 0.0
        prm.flags.writeable = False
        object.__setattr__(self, "_prm", prm)
        if self._warm:
            warm_up()

    def with_mode(self, working_mode: str, *, serial_rules: bool | None = None) -> ValidityChecker:
        """The same checker for another working mode (and optionally serial rules on/off)."""
        return ValidityChecker(
            self.design,
            self.margins,
            self.obstacles,
            self.assembly_mode,
            working_mode,
            self.coarse_step,
            self.serial_rules if serial_rules is None else serial_rules,
        )

    # ------------------------------------------------------------------ states
    def _measures(self, q: np.ndarray, full: bool) -> np.ndarray:
        q = _states(q)
        out = np.empty((q.shape[0], _N_MEASURES))
        _evaluate_many(q, self._prm, *self._packed, full, out)
        return out

    def is_valid(self, q: np.ndarray) -> np.ndarray:
        """Shape (N,) bool: which postures q (N, 3) are valid (fast path, stops at the first
        broken rule of each posture)."""
        return self._measures(q, False)[:, _M_REASON] == 0.0

    def is_valid_one(self, q0: float, q1: float, q2: float) -> bool:
        """Validity of one posture given as three floats (the cheapest call, for OMPL)."""
        out = np.empty(_N_MEASURES)
        _evaluate(q0, q1, q2, self._prm, *self._packed, False, out)
        return bool(out[_M_REASON] == 0.0)

    def check_states(self, q: np.ndarray) -> StateReport:
        """Validity, first broken rule and every measure of postures q, shape (N, 3), rad."""
        m = self._measures(q, True)
        reason = np.asarray(REASONS, dtype=object)[m[:, _M_REASON].astype(int)]
        closed = m[:, _M_KAPPA] > -np.inf
        nan = np.full(len(m), np.nan)
        return StateReport(
            valid=m[:, _M_REASON] == 0.0,
            reason=reason,
            kappa_A=np.where(closed, m[:, _M_KAPPA], nan),
            serial_margin=np.where(closed, m[:, _M_SERIAL_RAW], nan),
            clearance=np.where(closed, m[:, _M_CLEAR_RAW], nan),
        )

    def explain(self, q: np.ndarray) -> str:
        """A sentence naming the first rule posture q (3,) breaks and the measured value
        (``'valid'`` when none)."""
        q = _states(q)[0]
        r = self.check_states(q[None])
        reason = str(r.reason[0])
        m, d = self.margins, self.design
        if reason == "valid":
            return "valid"
        if reason == "joint_limits":
            lo, hi = np.asarray(d.joint_min), np.asarray(d.joint_max)
            i = int(np.argmax(np.maximum(lo - q, q - hi)))
            return (
                f"joint_limits: q[{i}] = {q[i]:.10g} rad lies outside [{lo[i]:.10g}, {hi[i]:.10g}]"
            )
        if reason == "assembly":
            return assembly_reason(d, q)
        if reason == "kappa_max":
            return (
                f"kappa_max: kappa_A = {r.kappa_A[0]:.10g} > margins.kappa_max = {m.kappa_max:.10g}"
            )
        if reason == "working_mode":
            return (
                f"working_mode: the posture is not in working mode {self.working_mode} "
                f"(signed serial measure {r.serial_margin[0]:.10g})"
            )
        if reason == "serial_min":
            return (
                f"serial_min: serial measure {r.serial_margin[0]:.10g} < "
                f"margins.serial_min = {m.serial_min:.10g}"
            )
        return (
            f"clearance: link clearance {r.clearance[0]:.10g} m < "
            f"margins.clearance = {m.clearance:.10g} m"
        )

    # ------------------------------------------------------------------ motions
    def check_motion(
        self, q_a: np.ndarray, q_b: np.ndarray, *, ends_known_valid: bool = False
    ) -> MotionReport:
        """Certify the straight joint-space motion ``q_a -> q_b`` (every posture on it valid).

        Algorithm: sample the motion every ``coarse_step`` (max-norm, rad) and reject it at
        the first invalid sample; then certify each piece [t_a, t_b] between samples with
        Lipschitz bounds, splitting it at its midpoint (which is checked) until certified,
        and rejecting the motion when a piece shorter than :data:`MIN_CERTIFIED_STEP` cannot be.

        Proof that no violation is skipped, whatever the step. Let g be one of three margins
        along the motion, each >= 0 exactly where its rule holds: the |CD| band margin
        (kappa rule), the signed serial margin (mode and serial rules), the clearance margin.
        If g is L-Lipschitz in t on [t_a, t_b], then for every t there
        ``g(t) >= (g(t_a) + g(t_b) - L (t_b - t_a)) / 2`` (the two cones from the ends meet
        there). A piece is accepted only when that bound is >= 0 for all three margins, so
        every posture of it keeps every margin. The constants (see ``_rates``), for the
        motion ``q_a + t dq``:

        * |CD|: C and D move by L1 |dtheta2| and L1 |dtheta3|: ``L = L1 (|dq2| + |dq3|)``,
          valid everywhere. Certifying it first (lower bound ``b >= 0`` on the piece) keeps
          |CD| at least ``b`` inside its band, hence |sin(theta4 - theta5)| >= s on the piece,
          s the least apex sine over that shrunk band (>= 1 / K), and the passive rates are
          at most ``r45 = L1 (|dq2| + |dq3|) / (L2 s)`` (``_rates_s``, ``_sin_apex_min``);
        * serial: ``r45 + |dq2|``, ``r45 + |dq3|`` (sin of a difference of angles) and
          ``(L1 |dq2| + L2 r45) / (L1 + L2)`` (w), the largest of the three for their minimum;
        * clearance: a link point at distance r <= L1 + L2 from the axis AB moves by at most
          ``r |dq1|`` plus its in-plane motion (L1 |dq2| for C, and for P that of C or D plus
          ``L2 r45``); a distance to a fixed obstacle is 1-Lipschitz in the link's points.

        Joint limits hold on the whole motion when they hold at its ends (a box is convex);
        the loop closes and the assembly mode holds while |CD| stays in its kappa band
        (0 < |CD| < 2 L2); the working mode cannot flip while the signed serial margin stays
        positive. So an accepted motion has no violation of any depth; the only loss is that
        motions grazing a margin more closely than the Lipschitz bounds resolve at
        :data:`MIN_CERTIFIED_STEP` are rejected, which is the safe side. Postures exactly on
        a margin (margin 0) have no certified motion.

        Parameters
        ----------
        q_a, q_b : array, shape (3,), rad
        ends_known_valid : bool
            Skip the rule checks of the two end postures (their measures are still computed).
            Only for callers that checked them already, e.g. a planner's tree nodes.
        """
        qa = np.ascontiguousarray(_states(q_a)[0])
        qb = np.ascontiguousarray(_states(q_b)[0])
        r, t = _check_motion(
            qa, qb, self._prm, *self._packed, self.coarse_step, MIN_CERTIFIED_STEP, ends_known_valid
        )
        return MotionReport(r == 0, REASONS[r], float(t))

    def motion_valid(self, q_a: np.ndarray, q_b: np.ndarray) -> bool:
        """:meth:`check_motion` ends included, as a bool, for float arrays of shape (3,)
        (copied: numba compiles read-only arrays separately)."""
        q_a = np.array(q_a, dtype=float)
        q_b = np.array(q_b, dtype=float)
        return (
            0
            == _check_motion(
                q_a, q_b, self._prm, *self._packed, self.coarse_step, MIN_CERTIFIED_STEP, False
            )[0]
        )

    def check_path(
        self, waypoints: np.ndarray, *, sample_step: float = DIAGNOSTIC_STEP, certify: bool = True
    ) -> PathReport:
        """Certify every straight motion of a waypoint path (N, 3), rad, and measure it.

        Validity comes from :meth:`check_motion` on each consecutive pair (waypoints
        included); ``certify=False`` skips it (only for motions certified already) and
        reports the path valid. The extremes are taken over the waypoints and samples every
        ``sample_step`` rad (max-norm); they are diagnostics, not the certificate.
        """
        q = np.ascontiguousarray(_states(waypoints))
        bad, reason, t = -1, 0, 1.0
        if certify and len(q) == 1:
            reason = int(self._measures(q, False)[0, _M_REASON])
            bad = 0 if reason else -1
        elif certify:
            reasons = np.zeros(len(q) - 1, dtype=np.int64)
            ts = np.zeros(len(q) - 1)
            bad = int(
                _check_path(
                    q, self._prm, *self._packed, self.coarse_step, MIN_CERTIFIED_STEP, reasons, ts
                )
            )
            if bad >= 0:
                reason, t = int(reasons[bad]), float(ts[bad])
        ext = np.empty(3)
        _path_extremes(q, float(sample_step), self._prm, *self._packed, ext)
        return PathReport(
            valid=bad < 0,
            bad_motion=bad,
            reason=REASONS[reason],
            t=t,
            min_clearance=float(ext[0]),
            max_kappa_A=float(ext[1]),
            min_serial_margin=float(ext[2]),
            length=float(np.sum(np.linalg.norm(np.diff(q, axis=0), axis=1))),
        )


_WARM = False


def warm_up() -> None:
    """Load (or compile) every numba kernel once, so that the first plan's budget is spent on
    planning. Called by the first :class:`ValidityChecker`; about 0.3 s from numba's cache."""
    global _WARM
    if _WARM:
        return
    _WARM = True
    chk = ValidityChecker(Design(0.5, 0.2, 0.6), Margins(), (), "+", "+-+", _warm=False)
    q = np.array([[0.0, 2.0, 1.0], [0.1, 2.1, 1.1]])
    chk.check_states(q)
    chk.is_valid(q)
    chk.is_valid_one(0.0, 2.0, 1.0)
    chk.check_motion(q[0], q[1])
    chk.motion_valid(q[0], q[1])
    chk.check_path(q)


def assembly_reason(design: Design, q: np.ndarray) -> str:
    """Why posture q (3,) does not assemble, with the measured |CD| (the loop closes only for
    0 < |CD| <= 2 L2)."""
    q = np.asarray(q, dtype=float)
    c = np.array([-design.L0 / 2 + design.L1 * np.cos(q[1]), design.L1 * np.sin(q[1])])
    d = np.array([design.L0 / 2 + design.L1 * np.cos(q[2]), design.L1 * np.sin(q[2])])
    cd = float(np.hypot(*(d - c)))
    if cd == 0.0:
        return "assembly: C = D (|CD| = 0 m), P is undetermined"
    return f"assembly: the loop does not close, |CD| = {cd:.10g} m > 2 L2 = {2 * design.L2:.10g} m"


def _states(q: object) -> np.ndarray:
    try:
        arr = np.asarray(q, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"q must be numbers, got {q!r}") from exc
    arr = np.atleast_2d(arr)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"q must have shape (3,) or (N, 3), got {np.shape(q)}")
    if not np.all(np.isfinite(arr)):
        raise InputError("q must be finite (no NaN or infinity)")
    return np.ascontiguousarray(arr)
