"""Straight tool paths: P follows a Cartesian polyline inside one working and assembly mode.

Entry points: :func:`plan_cartesian` (the joint path, optionally timed) and
:func:`inspect_cartesian` (a pre-check that says where the polyline leaves the workspace of
the start's working mode or meets a serial or parallel singular surface, before any planning).

How a straight path is built (``docs/cartesian.md`` has the full argument):

1. The polyline starts at P of the start posture and runs through ``waypoints`` in order. It is
   probed every :data:`PROBE_STEP` m by the inverse kinematics of the start's working mode
   (one branch: the mode's sign triple fixes it), joint values unwrapped continuously from
   the start's literal values, and every probe is checked against every rule of a plan
   (:class:`planner.validity.ValidityChecker`). The first probe that breaks a rule, or where
   the branch does not exist (P out of reach) or changes assembly mode, ends the path; the
   last valid point before it is found by bisection along the polyline.
2. Up to there, the joint path is a polyline through inverse-kinematics postures. Between two
   consecutive ones the robot moves on the straight joint segment, whose P leaves the
   Cartesian line; :func:`chord_deviation_bound` bounds that deviation from above (a second
   derivative bound, proved in its docstring), and a piece is split into equal Cartesian
   parts (as many as the bound's quadratic decay asks, :data:`MAX_PARTS` at most) until the
   bound is at most ``chord_share * path_tolerance``.
3. Every joint piece is certified by :meth:`ValidityChecker.check_path` (all rules hold on the
   whole straight joint motion, not only at samples); a piece that cannot be certified is
   split too, and where splitting reaches :data:`MIN_PIECE` m the path stops at the piece's
   start, with the rule the certificate named.
4. Timing (optional) is :func:`planner.timing.time_path` with the blend allowance of every
   joint vertex chosen so that a blended posture keeps P within the rest of the tolerance
   (:func:`blend_allowance`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Literal

import numpy as np

from planner.design import Design
from planner.exceptions import InputError, TimingError
from planner.geometry import Obstacle
from planner.kinematics import WORKING_MODES, conditioning, forward_batch, inverse_batch
from planner.planning.planner import posture_mode
from planner.planning.problem import JointPosture
from planner.planning.result import Diagnostics, PlanPath, PlanStatus, Segment
from planner.validity import Margins, ValidityChecker

__all__ = [
    "CHORD_SHARE",
    "MIN_PIECE",
    "PROBE_STEP",
    "CartesianDiagnostics",
    "CartesianResult",
    "PathEvent",
    "StopPoint",
    "blend_allowance",
    "chord_deviation_bound",
    "distance_to_polyline_3d",
    "inspect_cartesian",
    "plan_cartesian",
    "second_derivative_bound",
]

#: Spacing of the rule probes along the polyline, m (the first broken rule is located within
#: this, then bisected to :data:`BISECT_TOL`).
PROBE_STEP = 2e-3
#: Initial spacing of the joint waypoints, m (the chord bound refines where needed).
INITIAL_STEP = 0.05
#: Shortest Cartesian piece the refinement splits down to, m.
MIN_PIECE = 1e-7
#: Bisection tolerance on the stopping point along the polyline, m.
BISECT_TOL = 1e-8
#: Points classified at once per round of :func:`_narrow` (one batched inverse kinematics
#: each): a bracket shrinks by NARROW_POINTS + 1 per round, 3 rounds from PROBE_STEP to
#: BISECT_TOL where bisection takes 18 single-point steps.
NARROW_POINTS = 64
#: A final piece ending on the bisected boundary and at most this long (m) has its end pulled
#: back (from :data:`BACKOFF_START` m, by factors of 4) rather than split, to certify it.
BACKOFF_PIECE = 1e-3
BACKOFF_START = 1e-7
#: Share of ``path_tolerance`` given to the chords between joint waypoints; the rest is the
#: timing's corner blends.
CHORD_SHARE = 0.5
#: Most refinement rounds (each splits the pieces that fail).
MAX_ROUNDS = 60
#: Most parts one refinement round cuts a piece into.
MAX_PARTS = 16
#: Where a piece whose motion cannot be certified is split (shares of its length).
GRADED_SPLIT = (0.5, 0.75, 0.875)


# ------------------------------------------------------------------------------ results
@dataclass(frozen=True, slots=True)
class StopPoint:
    """Where and why a Cartesian path stops short.

    Attributes
    ----------
    rule : str
        ``joint_limits``, ``assembly``, ``kappa_max``, ``working_mode``, ``serial_min``,
        ``clearance`` (the validity rules), ``workspace`` (the working mode's branch does not
        reach the point), or ``path_tolerance`` (the line cannot be followed within the
        tolerance by a certified joint path there).
    value : float
        The measured value that breaks the rule (kappa(A), serial measure, clearance in m,
        joint value in rad, distance in m), NaN when none applies.
    p : shape (3,), m
        The last valid point of P on the polyline (where the path ends).
    fraction : float
        Share of the polyline's length achieved, in [0, 1).
    detail : str
        The sentence of the message (rule, value, point).
    """

    rule: str
    value: float
    p: np.ndarray
    fraction: float
    detail: str


@dataclass(frozen=True, slots=True)
class PathEvent:
    """A surface the polyline meets, found by :func:`inspect_cartesian`.

    Attributes
    ----------
    kind : str
        ``leg_A_stretched``, ``leg_A_folded``, ``leg_B_stretched``, ``leg_B_folded``,
        ``P_on_axis`` (a serial singular surface: the working mode's workspace ends there);
        ``serial_min`` (the surface where a serial measure equals ``margins.serial_min``,
        named in ``detail``); ``kappa_max`` (kappa(A) = ``margins.kappa_max``);
        ``parallel`` (kappa(A) infinite: C, D, P aligned); ``joint_limits``.
    segment : int
        Index of the polyline segment (0: start-P -> waypoints[0]).
    fraction : float
        Position along the whole polyline, share of its length, in [0, 1].
    p : shape (3,), m
    entering : bool
        True when the polyline goes from the valid side to the invalid side there.
    detail : str
    """

    kind: str
    segment: int
    fraction: float
    p: np.ndarray
    entering: bool
    detail: str


@dataclass(frozen=True, slots=True)
class CartesianDiagnostics:
    """Measures of a Cartesian path (the fields of a plan's diagnostics plus deviations).

    Attributes
    ----------
    planning_time_s, timing_time_s : float, s
    path_length : float, rad -- joint-space length of the path.
    cartesian_length : float, m -- length of the polyline achieved.
    max_kappa_A, min_serial_margin, min_clearance : extremes (as :class:`Diagnostics`).
    chord_bound : float, m -- largest certified chord deviation of the joint pieces.
    max_path_deviation : float, m -- largest measured distance of P from the polyline: over
        the timed trajectory's dense check times when timed, else over the joint pieces
        sampled finely.
    blend_deviation_bound : float, m -- certified bound on the extra deviation of the blends.
    waypoints : int -- joint waypoints of the path.
    """

    planning_time_s: float
    timing_time_s: float = 0.0
    path_length: float = float("nan")
    cartesian_length: float = 0.0
    max_kappa_A: float = float("nan")
    min_serial_margin: float = float("nan")
    min_clearance: float = float("nan")
    chord_bound: float = 0.0
    max_path_deviation: float = float("nan")
    blend_deviation_bound: float = 0.0
    waypoints: int = 0


@dataclass(frozen=True, eq=False)
class CartesianResult:
    """Result of :func:`plan_cartesian`.

    Attributes
    ----------
    status : PlanStatus
        ``solved`` exactly when ``fraction == 1``; ``no_path`` when the path stops short;
        ``invalid_start`` when the start breaks a rule (fraction 0, no path).
    message : str
        For ``no_path``: the rule, the measured value, the point and the fraction.
    fraction : float
        Share of the polyline's length achieved, in [0, 1].
    path : PlanPath or None
        The joint path up to the last valid point (one segment in the start's modes).
    polyline : shape (K + 1, 3), m -- start-P followed by the waypoints.
    s : shape (N,), m -- arc length along the polyline of each joint waypoint.
    p : shape (N, 3), m -- P of each joint waypoint (on the polyline).
    stop : StopPoint or None
    trajectory : planner.timing.Trajectory or None
    timing_error : str -- why timing failed (empty when it did not).
    events : tuple of PathEvent -- the pre-check of the polyline (:func:`inspect_cartesian`).
    working_mode, assembly_mode : str
    diagnostics : CartesianDiagnostics
    """

    status: PlanStatus
    message: str
    fraction: float
    path: PlanPath | None
    polyline: np.ndarray
    s: np.ndarray
    p: np.ndarray
    stop: StopPoint | None
    trajectory: object | None
    timing_error: str
    events: tuple[PathEvent, ...]
    working_mode: str
    assembly_mode: str
    diagnostics: CartesianDiagnostics = field(
        default_factory=lambda: CartesianDiagnostics(float("nan"))
    )

    @property
    def solved(self) -> bool:
        return self.status is PlanStatus.SOLVED

    def plan_diagnostics(self) -> Diagnostics:
        """The plan-style :class:`~planner.planning.result.Diagnostics` of this path."""
        d = self.diagnostics
        return Diagnostics(
            planning_time_s=d.planning_time_s,
            path_length=d.path_length,
            min_clearance=d.min_clearance,
            max_kappa_A=d.max_kappa_A,
            min_serial_margin=d.min_serial_margin,
            planner="cartesian",
            attempts=1,
        )


# ------------------------------------------------------------------------------ geometry
def _as_points(waypoints: object) -> np.ndarray:
    try:
        w = np.asarray(waypoints, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"waypoints must be numbers, got {waypoints!r}") from exc
    if w.ndim == 1 and w.shape == (3,):
        w = w[None]
    if w.ndim != 2 or w.shape[1] != 3 or w.shape[0] < 1:
        raise InputError(f"waypoints must have shape (K, 3) with K >= 1, got {w.shape}")
    if not np.all(np.isfinite(w)):
        raise InputError("waypoints must be finite (no NaN or infinity)")
    return w


class _Polyline:
    """A Cartesian polyline parameterised by arc length s (m)."""

    def __init__(self, vertices: np.ndarray) -> None:
        seg = np.diff(vertices, axis=0)
        lengths = np.linalg.norm(seg, axis=1)
        keep = np.concatenate([[True], lengths > 1e-12])  # drop repeated points
        self.vertices = vertices[keep]
        seg = np.diff(self.vertices, axis=0)
        self.lengths = np.linalg.norm(seg, axis=1)
        self.cum = np.concatenate([[0.0], np.cumsum(self.lengths)])
        self.length = float(self.cum[-1])
        self.dirs = seg / np.maximum(self.lengths, 1e-300)[:, None]
        # index of each kept vertex among the given ones (for segment numbers in messages)
        self.given_index = np.flatnonzero(keep)

    def segment_of(self, s: np.ndarray) -> np.ndarray:
        i = np.searchsorted(self.cum, s, side="right") - 1
        return np.clip(i, 0, max(len(self.lengths) - 1, 0))

    def at(self, s: np.ndarray) -> np.ndarray:
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.length)
        if self.length == 0.0:
            return np.broadcast_to(self.vertices[0], (*s.shape, 3)).copy()
        i = self.segment_of(s)
        return self.vertices[i] + (s - self.cum[i])[..., None] * self.dirs[i]


def distance_to_polyline_3d(vertices: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance of each point (M, 3) to the polyline through ``vertices`` (K, 3), m.

    Exact: the least point-segment distance over the segments (a single vertex: the distance
    to it).
    """
    v = np.asarray(vertices, dtype=float)
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    if v.shape[0] == 1:
        return np.linalg.norm(pts - v[0], axis=1)
    best = np.full(pts.shape[0], np.inf)
    for a, b in pairwise(v):
        ab = b - a
        den = float(ab @ ab)
        t = np.clip((pts - a) @ ab / den, 0.0, 1.0) if den > 0 else np.zeros(pts.shape[0])
        best = np.minimum(best, np.linalg.norm(a + t[:, None] * ab - pts, axis=1))
    return best


# ------------------------------------------------------------------------------ bounds
def _cd(design: Design, q: np.ndarray) -> np.ndarray:
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
    s = _apex_sine_lower(design, _cd(design, q_a), _cd(design, q_b), rate_cd)
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
    q_a, q_b = np.atleast_2d(q_a), np.atleast_2d(q_b)
    n = q_a.shape[0]
    t = np.arange(m + 1) / m
    dq = q_b - q_a
    qs = (q_a[:, None, :] + t[None, :, None] * dq[:, None, :]).reshape(-1, 3)
    fb = forward_batch(design, qs, assembly_mode)
    p = fb.p.reshape(n, m + 1, 3)
    ok = np.all(fb.ok.reshape(n, m + 1), axis=1)
    chord = p[:, :1] + t[None, :, None] * (p[:, -1:] - p[:, :1])
    f = np.max(np.linalg.norm(p - chord, axis=2), axis=1)
    ends = np.maximum(
        np.linalg.norm(p[:, 0] - line_a, axis=1), np.linalg.norm(p[:, -1] - line_b, axis=1)
    )
    m2 = second_derivative_bound(design, q_a, q_b, w_a, w_b)
    with np.errstate(invalid="ignore"):
        bound = f + m2 / (8.0 * m * m) + ends
    return np.where(ok & np.isfinite(bound), bound, np.inf)


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
    cd = _cd(design, q)
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


# ------------------------------------------------------------------------------ IK walk
def _ik(design: Design, pts: np.ndarray, slot: int, asm_sign: int):
    """IK of points (M, 3) in one working-mode slot: q wrapped (M, 3), ok (M,), w (M,),
    flipped (M,) (the branch exists but in the other assembly mode)."""
    ib = inverse_batch(design, pts)
    q = ib.q[:, slot]
    ok = ib.ok[:, slot] & ~ib.degenerate
    asm = ib.assembly_mode_signs[:, slot]
    flipped = ok & (asm != asm_sign)
    return q, ok & ~flipped, ib.w[:, slot], flipped


def _unwrap_to(q: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """q shifted by multiples of 2 pi per joint to be nearest ``ref``."""
    return q + 2 * np.pi * np.round((ref - q) / (2 * np.pi))


def _unwrap_chain(q: np.ndarray, q0: np.ndarray) -> np.ndarray:
    """:func:`_unwrap_chain` vectorised: cumulative sum of wrapped differences."""
    d = np.diff(np.vstack([q0[None], q]), axis=0)
    d = d - 2 * np.pi * np.round(d / (2 * np.pi))
    return q0 + np.cumsum(d, axis=0)


def _fmt_value(value: float, bound: float) -> str:
    """``value`` with just enough digits to differ from ``bound`` (at least 4)."""
    for digits in range(4, 17):
        a, b = f"{value:.{digits}g}", f"{bound:.{digits}g}"
        if a != b:
            return a
    return repr(value)


def _fmt_point(p: np.ndarray) -> str:
    return "(" + ", ".join(f"{x:.4g}" for x in p) + ")"


def _narrow(
    a: float,
    b: float,
    classify,
    tol: float,
    q_b: np.ndarray | None = None,
    reason_b: str = "",
) -> tuple[float, float, np.ndarray | None, str]:
    """Shrink a bracket [a, b] (m along the polyline) of a change of a rule to ``b - a <= tol``.

    ``classify(s)`` takes arc lengths (M,) inside the bracket and returns ``(same, q,
    reason)``: ``same`` (M,) bool, True where s is on a's side of the change; ``q`` (M, 3) the
    posture there (NaN where none); ``reason`` (M,) the rule broken there. Each round
    classifies :data:`NARROW_POINTS` evenly spaced interior points at once and keeps the
    interval from the last point on a's side before the first point on b's side to that
    point, so the change found is the first one the points see (as with bisection, two
    changes closer than a round's spacing can hide each other). Returns ``(a, b, q_b,
    reason_b)``: the final bracket and the posture and rule at its end (the given ones when
    b never moved)."""
    while b - a > tol:
        s = a + (b - a) * np.arange(1, NARROW_POINTS + 1) / (NARROW_POINTS + 1)
        same, q, reason = classify(s)
        if np.all(same):
            a = float(s[-1])
            continue
        j = int(np.argmax(~same))
        if j > 0:
            a = float(s[j - 1])
        b = float(s[j])
        q_b = q[j] if np.all(np.isfinite(q[j])) else None
        reason_b = str(reason[j])
    return a, b, q_b, reason_b


class _Walker:
    """State shared by the steps of :func:`plan_cartesian`."""

    def __init__(self, design, checker, poly, q0, slot, asm_sign):
        self.design = design
        self.checker = checker
        self.poly = poly
        self.q0 = q0
        self.slot = slot
        self.asm_sign = asm_sign

    def posture_at(self, s: np.ndarray, ref: np.ndarray):
        """(q unwrapped towards ref (M, 3), ok (M,), w (M,), flipped (M,)) at arc lengths s."""
        pts = self.poly.at(s)
        q, ok, w, flipped = _ik(self.design, pts, self.slot, self.asm_sign)
        q = np.where(ok[:, None], _unwrap_to(q, ref), np.nan)
        return q, ok, w, flipped

    def probe_valid(self, s: np.ndarray, ref: np.ndarray):
        """Validity of the IK postures at arc lengths s (M,), unwrapped towards ``ref``:
        (valid (M,), q (M, 3), reason (M,)); the reason is "workspace" or "assembly" where the
        working mode's branch does not reach the point (or changes assembly mode)."""
        q, ok, _, flipped = self.posture_at(np.asarray(s, dtype=float), ref)
        valid = np.zeros(q.shape[0], dtype=bool)
        reason = np.where(flipped, "assembly", "workspace").astype(object)
        if np.any(ok):
            rep = self.checker.check_states(q[ok])
            valid[ok] = rep.valid
            reason[ok] = rep.reason
        return valid, q, reason


def _describe(
    design: Design,
    checker: ValidityChecker,
    rule: str,
    q_bad: np.ndarray | None,
    p_bad: np.ndarray,
) -> tuple[float, str]:
    """(measured value, sentence) of the rule broken at posture q_bad (P = p_bad)."""
    m = checker.margins
    if rule == "workspace":
        a = np.array([0.0, -design.L0 / 2, 0.0])
        b = -a
        ra, rb = float(np.linalg.norm(p_bad - a)), float(np.linalg.norm(p_bad - b))
        hi, lo = design.L1 + design.L2, abs(design.L2 - design.L1)
        for name, r in (("AP", ra), ("BP", rb)):
            if r > hi:
                return r, (f"workspace: |{name}| = {_fmt_value(r, hi)} m > L1 + L2 = {hi:.6g} m, "
                           "P is out of reach")  # fmt: skip
            if r < lo:
                return r, (f"workspace: |{name}| = {_fmt_value(r, lo)} m < |L2 - L1| = "
                           f"{lo:.6g} m, P is out of reach")  # fmt: skip
        return float("nan"), (
            f"workspace: working mode {checker.working_mode} does not reach P there"
        )
    if q_bad is None or not np.all(np.isfinite(q_bad)):
        return float("nan"), f"{rule}: the path cannot continue"
    if rule == "assembly":
        return float("nan"), (
            f"assembly: the inverse kinematics of working mode {checker.working_mode} changes "
            f"assembly mode (from {checker.assembly_mode}): the line crosses a parallel "
            "singularity (C, D, P aligned)"
        )
    rep = checker.check_states(q_bad[None])
    if rule == "joint_limits":
        lo, hi = np.asarray(design.joint_min), np.asarray(design.joint_max)
        i = int(np.argmax(np.maximum(lo - q_bad, q_bad - hi)))
        bound = lo[i] if q_bad[i] < lo[i] else hi[i]
        rel = "<" if q_bad[i] < lo[i] else ">"
        return float(q_bad[i]), (
            f"joint_limits: theta{i + 1} = {_fmt_value(q_bad[i], bound)} rad {rel} "
            f"joint_{'min' if rel == '<' else 'max'}[{i}] = {bound:.6g} rad"
        )
    if rule == "kappa_max":
        k = float(rep.kappa_A[0])
        return k, f"kappa(A) = {_fmt_value(k, m.kappa_max)} > margins.kappa_max = {m.kappa_max:g}"
    if rule in ("serial_min", "working_mode"):
        fb = forward_batch(design, q_bad, checker.assembly_mode)
        c = conditioning(design, fb.q, fb.passive, fb.w)
        names = {
            "P_on_axis": "|w| / (L1 + L2) (P near the axis AB)",
            "leg_A": "|sin(theta4 - theta2)| (leg A near stretched or folded)",
            "leg_B": "|sin(theta5 - theta3)| (leg B near stretched or folded)",
        }
        kind = str(c.nearest_serial_kind[0])
        val = float(c.min_serial[0])
        return val, (
            f"serial_min: {names[kind]} = {_fmt_value(val, m.serial_min)} < "
            f"margins.serial_min = {m.serial_min:g}"
        )
    if rule == "clearance":
        c = float(rep.clearance[0])
        return c, (
            f"clearance: link clearance {_fmt_value(c, m.clearance)} m < "
            f"margins.clearance = {m.clearance:g} m"
        )
    return float("nan"), checker.explain(q_bad)


# ------------------------------------------------------------------------------ pre-check
def _sphere_crossings(p0, d, length, centre, radius):
    """Parameters s in (0, length] where |p0 + s d - centre| = radius (d unit)."""
    f = p0 - centre
    b = float(f @ d)
    c = float(f @ f) - radius * radius
    disc = b * b - c
    if disc < 0:
        return []
    r = math.sqrt(disc)
    return [s for s in (-b - r, -b + r) if 0.0 < s <= length]


def _cylinder_crossings(p0, d, length, radius):
    """Parameters where the distance to the y axis (x^2 + z^2) equals radius (radius >= 0);
    for radius 0 the parameter of the closest approach when it touches the axis."""
    px, pz, dx, dz = p0[0], p0[2], d[0], d[2]
    a = dx * dx + dz * dz
    b = px * dx + pz * dz
    c = px * px + pz * pz - radius * radius
    if a < 1e-300:
        return []
    if radius == 0.0:
        s = -b / a
        closest = math.hypot(px + s * dx, pz + s * dz)
        return [s] if 0.0 < s <= length and closest <= 1e-12 else []
    disc = b * b - a * c
    if disc < 0:
        return []
    r = math.sqrt(disc)
    return [s for s in ((-b - r) / a, (-b + r) / a) if 0.0 < s <= length]


def inspect_cartesian(
    design: Design,
    start: JointPosture,
    waypoints: np.ndarray,
    *,
    margins: Margins | None = None,
    probe_step: float = PROBE_STEP,
) -> tuple[PathEvent, ...]:
    """Where the polyline start-P -> waypoints meets the singular surfaces of the start's
    working mode, before planning (a pre-check; obstacles are not considered).

    The serial singular surfaces and the serial margins are closed forms: leg A is stretched
    or folded where |AP| = L1 + L2 or |L2 - L1|, and |sin(theta4 - theta2)| = serial_min where
    |AP|^2 = L1^2 + L2^2 +- 2 L1 L2 sqrt(1 - serial_min^2) (law of cosines in A-C-P); the same
    about B; P is on the axis where x = z = 0, and |w| / (L1 + L2) = serial_min on the cylinder
    of radius serial_min (L1 + L2) about it. Their crossings with each straight segment are
    roots of quadratics. kappa(A) depends on the working mode's inverse kinematics, so the
    kappa_max and parallel surfaces are found by probing every ``probe_step`` m and bisecting;
    so are the joint limits (literal, unwrapped from the start).

    Returns
    -------
    tuple of PathEvent, ordered along the polyline.
    """
    margins = margins if margins is not None else Margins()
    fb = forward_batch(design, start.q, start.assembly_mode)
    if not fb.ok[0]:
        return ()
    p_start = fb.p[0]
    poly = _Polyline(np.vstack([p_start[None], _as_points(waypoints)]))
    if poly.length == 0.0:
        return ()
    L1, L2 = design.L1, design.L2
    sm = margins.serial_min
    root = math.sqrt(1.0 - sm * sm)
    centres = {"A": np.array([0.0, -design.L0 / 2, 0.0]), "B": np.array([0.0, design.L0 / 2, 0.0])}
    events: list[PathEvent] = []

    def add(kind, s_global, entering, detail, seg):
        p = poly.at(np.array([s_global]))[0]
        events.append(
            PathEvent(kind, int(poly.given_index[seg + 1] - 1), s_global / poly.length, p,
                      entering, detail)
        )  # fmt: skip

    for k in range(len(poly.lengths)):
        p0, d, length = poly.vertices[k], poly.dirs[k], float(poly.lengths[k])
        s0 = float(poly.cum[k])
        for leg, c in centres.items():
            surfaces = (
                (f"leg_{leg}_stretched", L1 + L2, +1),
                (f"leg_{leg}_folded", abs(L2 - L1), -1),
            )
            for kind, radius, outward in surfaces:
                for s in _sphere_crossings(p0, d, length, c, radius):
                    grad = float((p0 + s * d - c) @ d)  # > 0: moving away from the centre
                    entering = grad * outward > 0
                    verb = "leaves" if entering else "enters"
                    add(kind, s0 + s, entering,
                        f"{kind}: |{leg}P| = {radius:.6g} m, the line {verb} the workspace",
                        k)  # fmt: skip
            for sign, which in ((+1, "stretched"), (-1, "folded")):
                radius = math.sqrt(max(L1 * L1 + L2 * L2 + sign * 2 * L1 * L2 * root, 0.0))
                for s in _sphere_crossings(p0, d, length, c, radius):
                    grad = float((p0 + s * d - c) @ d)
                    entering = grad * sign > 0
                    add("serial_min", s0 + s, entering,
                        f"serial_min: |sin(theta{4 if leg == 'A' else 5} - "
                        f"theta{2 if leg == 'A' else 3})| = {sm:g} (leg {leg} near {which}, "
                        f"|{leg}P| = {radius:.6g} m)", k)  # fmt: skip
        for s in _cylinder_crossings(p0, d, length, 0.0):
            add("P_on_axis", s0 + s, True, "P_on_axis: P meets the axis AB (w = 0)", k)
        for s in _cylinder_crossings(p0, d, length, sm * design.reach):
            q = p0 + s * d
            entering = float(q[0] * d[0] + q[2] * d[2]) < 0
            add("serial_min", s0 + s, entering,
                f"serial_min: |w| / (L1 + L2) = {sm:g} (P {sm * design.reach:.4g} m from "
                "the axis AB)", k)  # fmt: skip

    # probed: kappa(A) and the joint limits along the working mode's branch
    mode = posture_mode(design, start)
    if mode is not None:
        slot = WORKING_MODES.index(mode)
        asm_sign = 1 if start.assembly_mode == "+" else -1
        n = max(2, math.ceil(poly.length / probe_step) + 1)
        s = np.linspace(0.0, poly.length, n)
        q, ok, _, _ = _ik(design, poly.at(s), slot, asm_sign)
        q[0] = start.q
        lo, hi = margins.cd_range

        def measures(qq, okk):
            cd = np.where(okk, _cd(design, np.nan_to_num(qq)) / (2 * L2), np.nan)
            kappa_ok = (cd >= lo) & (cd <= hi)
            return cd, kappa_ok

        cd, kappa_ok = measures(q, ok)
        run = np.cumprod(ok).astype(bool)  # the branch exists from the start up to here
        qc = _unwrap_chain(np.nan_to_num(q[1:]), start.q) if n > 1 else q
        qc = np.vstack([start.q[None], qc])
        jl_ok = np.all((qc >= np.asarray(design.joint_min) - 1e-12)
                       & (qc <= np.asarray(design.joint_max) + 1e-12), axis=1)  # fmt: skip
        for kind, good in (("kappa_max", kappa_ok), ("joint_limits", jl_ok)):
            for i in np.flatnonzero((good[1:] != good[:-1]) & run[1:] & run[:-1]):
                ga = bool(good[i])

                def classify(s_, kind=kind, ga=ga, ref=qc[i]):
                    qm, okm, _, _ = _ik(design, poly.at(s_), slot, asm_sign)
                    if kind == "kappa_max":
                        gm = measures(qm, okm)[1]
                    else:
                        qm = _unwrap_to(qm, ref)
                        gm = np.all((qm >= design.joint_min) & (qm <= design.joint_max), axis=1)
                    return gm == ga, qm, np.full(len(s_), "")

                a, b, _, _ = _narrow(float(s[i]), float(s[i + 1]), classify, BISECT_TOL)
                seg = int(poly.segment_of(np.array([a]))[0])
                if kind == "kappa_max":
                    detail = f"kappa_max: kappa(A) = {margins.kappa_max:g}"
                else:
                    detail = "joint_limits: a joint reaches its literal limit"
                add(kind, 0.5 * (a + b), bool(ga), detail, seg)
        # parallel singularities: |CD| / (2 L2) reaching 0 or 1 between probes is inside the
        # kappa band's complement; report where kappa(A) is largest there
        bad = run & ~kappa_ok
        if np.any(bad):
            dist = np.minimum(cd, 1.0 - cd)
            for i in np.flatnonzero(bad):
                if 0 < i < n - 1 and dist[i] <= dist[i - 1] and dist[i] <= dist[i + 1]:
                    if dist[i] < 1e-3:
                        kind_p = "C=D" if cd[i] < 0.5 else "CD_stretched"
                        seg = int(poly.segment_of(np.array([s[i]]))[0])
                        add("parallel", float(s[i]), True,
                            f"parallel: C, D and P nearly aligned ({kind_p}), kappa(A) "
                            "very large", seg)  # fmt: skip
    events.sort(key=lambda e: e.fraction)
    return tuple(events)


# ------------------------------------------------------------------------------ planning
def plan_cartesian(
    design: Design,
    start: JointPosture,
    waypoints: np.ndarray,
    *,
    obstacles: Sequence[Obstacle] = (),
    margins: Margins | None = None,
    path_tolerance: float = 1e-3,
    timing: Literal["toppra", "ruckig", "none"] = "toppra",
    limits: object | None = None,
    cartesian_speed: float | None = None,
    sample_rate_hz: float = 100.0,
    check_resolution: float | None = None,
    chord_share: float = CHORD_SHARE,
    time_partial: bool = True,
    inspect: bool = True,
) -> CartesianResult:
    """Move P on the straight segments start-P -> waypoints[0] -> ... in the start's working
    and assembly mode, stopping at the last valid point where a rule would break.

    Parameters
    ----------
    design : Design
    start : JointPosture
        Its working mode (the sign triple of its posture) and assembly mode are kept.
    waypoints : array, shape (K, 3) or (3,), m
    obstacles : sequence of obstacles (wire dictionaries accepted, as the checker does).
    margins : Margins, optional (defaults).
    path_tolerance : float, m, > 0
        Largest distance of P from the polyline, along the joint path (certified by
        :func:`chord_deviation_bound`) and along the timed trajectory (certified by the blend
        allowance of :func:`blend_allowance`, re-measured densely).
    timing : "toppra" | "ruckig" | "none"
    limits : planner.timing.JointLimits, optional (defaults).
    cartesian_speed : float, m/s, optional
        Bound on the speed of P (``max_cartesian_speed`` of :func:`planner.timing.time_path`):
        the tool moves at this constant speed wherever the joint limits allow.
    sample_rate_hz : float, Hz -- output rate of the trajectory.
    check_resolution : float, rad, optional -- the timing's dense re-check step (default
        the timing's default).
    chord_share : float in (0, 1) -- share of the tolerance for the chords.
    time_partial : bool -- also time a path that stops short (default True).
    inspect : bool -- run :func:`inspect_cartesian` and attach its events.

    Returns
    -------
    CartesianResult
        ``fraction`` = share of the polyline's length achieved; status ``solved`` exactly
        when it is 1.

    Raises
    ------
    InputError
        A malformed argument (the message names it).
    """
    from planner.timing import DEFAULT_CHECK_RESOLUTION, JointLimits, time_path

    t0 = time.perf_counter()
    margins = margins if margins is not None else Margins()
    if not isinstance(start, JointPosture):
        raise InputError(f"start must be a JointPosture, got {type(start).__name__}")
    try:
        tol = float(path_tolerance)
    except (TypeError, ValueError) as exc:
        raise InputError(f"path_tolerance must be a number, got {path_tolerance!r}") from exc
    if not (math.isfinite(tol) and tol > 0):
        raise InputError(f"path_tolerance must be a positive finite number (m), got {tol!r}")
    if not 0.0 < chord_share < 1.0:
        raise InputError(f"chord_share must lie in (0, 1), got {chord_share!r}")
    if timing not in ("toppra", "ruckig", "none"):
        raise InputError(f"timing must be 'toppra', 'ruckig' or 'none', got {timing!r}")
    limits = limits if limits is not None else JointLimits.default()
    pts = _as_points(waypoints)
    asm = start.assembly_mode
    q0 = np.array(start.q, dtype=float)
    fb = forward_batch(design, q0, asm)

    def early(status: PlanStatus, message: str, mode: str = "") -> CartesianResult:
        poly = np.vstack([fb.p[0][None] if fb.ok[0] else np.full((1, 3), np.nan), pts])
        return CartesianResult(
            status, message, 0.0, None, poly, np.zeros(0), np.zeros((0, 3)), None, None, "",
            (), mode, asm, CartesianDiagnostics(time.perf_counter() - t0),
        )  # fmt: skip

    mode = posture_mode(design, start)
    if mode is None:
        checker0 = ValidityChecker(design, margins, obstacles, asm, "+++")
        why = checker0.explain(q0)
        if why in ("valid",) or why.startswith(("working_mode", "serial_min", "kappa")):
            why = "working_mode: the start lies on a serial singularity (its mode is undefined)"
        return early(PlanStatus.INVALID_START, f"invalid start: {why}")
    checker = ValidityChecker(design, margins, obstacles, asm, mode)
    if not checker.is_valid(q0[None])[0]:
        return early(PlanStatus.INVALID_START, f"invalid start: {checker.explain(q0)}", mode)
    p0 = fb.p[0]
    poly = _Polyline(np.vstack([p0[None], pts]))
    slot = WORKING_MODES.index(mode)
    asm_sign = 1 if asm == "+" else -1
    walker = _Walker(design, checker, poly, q0, slot, asm_sign)
    events = inspect_cartesian(design, start, pts, margins=margins) if inspect else ()

    # 1. probes: the first broken rule along the polyline, bisected
    end_s = poly.length
    stop_rule, q_stop_bad, p_stop_bad = "", None, None
    if poly.length > 0:
        n = max(2, math.ceil(poly.length / PROBE_STEP) + 1)
        s_probe = np.unique(np.concatenate([np.linspace(0.0, poly.length, n), poly.cum]))
        qw, ok, _, flipped = _ik(design, poly.at(s_probe), slot, asm_sign)
        qw[0] = q0
        first_missing = int(np.argmax(~ok)) if not np.all(ok) else len(s_probe)
        qp = np.full_like(qw, np.nan)
        if first_missing > 1:
            qp[1:first_missing] = _unwrap_chain(qw[1:first_missing], q0)
        qp[0] = q0
        valid = np.zeros(len(s_probe), dtype=bool)
        if first_missing > 0:
            valid[:first_missing] = checker.is_valid(qp[:first_missing])
        valid[0] = True
        if not np.all(valid):
            j = int(np.argmax(~valid))
            a, b = float(s_probe[j - 1]), float(s_probe[j])
            q_ref = qp[j - 1]
            good_q = q_ref
            bad_reason = "workspace" if j >= first_missing else ""
            bad_q = None
            if j < first_missing:
                bad_q = qp[j]
                bad_reason = str(checker.check_states(qp[j][None]).reason[0])
            elif flipped[j]:
                bad_reason = "assembly"
            a, b, bad_q, bad_reason = _narrow(
                a, b, lambda s_: walker.probe_valid(s_, good_q), BISECT_TOL, bad_q, bad_reason
            )
            end_s = a
            stop_rule, q_stop_bad = bad_reason, bad_q
            p_stop_bad = poly.at(np.array([b]))[0]

    # 2-3. joint waypoints up to end_s: chords within the tolerance, motions certified
    tol_chord = chord_share * tol
    n0 = max(1, math.ceil(end_s / INITIAL_STEP))
    s = np.unique(np.concatenate([np.linspace(0.0, end_s, n0 + 1),
                                  poly.cum[poly.cum < end_s]]))  # fmt: skip
    if end_s == 0.0:
        s = np.zeros(1)
    q, ok, w, _ = walker.posture_at(s, q0)
    q[0], ok[0], w[0] = q0, True, fb.w[0]
    if len(s) > 1:
        q[1:] = _unwrap_chain(np.nan_to_num(q[1:]), q0)
    if not np.all(ok):  # a waypoint between probes missed the branch: cut there
        cut = int(np.argmax(~ok))
        s, q, w = s[:cut], q[:cut], w[:cut]
        end_s = float(s[-1])
        stop_rule = stop_rule or "workspace"
    certified = 0  # pieces [0, certified) are certified (chord and motion)
    backoff = 0.0
    bound = np.zeros(max(len(s) - 1, 0))
    cut_reason = ""
    for _ in range(MAX_ROUNDS * 4):
        if certified >= len(s) - 1:
            break
        # chord bounds of the uncertified pieces
        tail = slice(certified, len(s) - 1)
        b_tail = chord_deviation_bound(
            design, q[tail], q[certified + 1 :], w[tail], w[certified + 1 :],
            poly.at(s[tail]), poly.at(s[certified + 1 :]), asm,
        )  # fmt: skip
        bound = np.concatenate([bound[:certified], b_tail])
        too_far = b_tail > tol_chord
        short = np.diff(s[certified:]) <= MIN_PIECE
        split = too_far & ~short
        if np.any(too_far & short):
            first_stuck = certified + int(np.argmax(too_far & short))
            if not np.any(split[: first_stuck - certified]):
                # cannot follow the line within the tolerance here: stop before the piece
                s, q, w = s[: first_stuck + 1], q[: first_stuck + 1], w[: first_stuck + 1]
                bound = bound[:first_stuck]
                end_s, cut_reason = float(s[-1]), "path_tolerance"
                q_stop_bad = None
                p_stop_bad = poly.at(np.array([end_s]))[0]
                continue
        if np.any(split):
            # each piece over the tolerance is cut into n equal parts at once, n from the
            # bound's quadratic decay with the piece's length (f and the second-derivative
            # term both scale with its square): one round where halving would take several;
            # a part still over the tolerance is split again in the next round
            pieces = certified + np.flatnonzero(split)
            n_parts = np.clip(np.ceil(np.sqrt(b_tail[split] / tol_chord)), 2, MAX_PARTS).astype(int)
            idx = np.repeat(pieces, n_parts - 1)
            frac = np.concatenate([np.arange(1, n) / n for n in n_parts])
            s_mid = s[idx] + frac * (s[idx + 1] - s[idx])
            qm, okm, wm, _ = walker.posture_at(s_mid, q[idx])
            valid_m = okm.copy()
            if np.any(okm):
                valid_m[okm] = checker.is_valid(qm[okm])
            if not np.all(valid_m):
                # a midpoint between two valid probes breaks a rule: cut before it
                first = int(np.argmax(~valid_m))
                k = int(idx[first])
                s, q, w = s[: k + 1], q[: k + 1], w[: k + 1]
                end_s = float(s[-1])
                cut_reason = "midpoint"
                q_stop_bad = qm[first] if okm[first] else None
                p_stop_bad = poly.at(np.array([s_mid[first]]))[0]
                stop_rule = (str(checker.check_states(qm[first][None]).reason[0])
                             if okm[first] else "workspace")  # fmt: skip
                keep = idx < k
                idx, s_mid, qm, wm = idx[keep], s_mid[keep], qm[keep], wm[keep]
            s = np.insert(s, idx + 1, s_mid)
            q = np.insert(q, idx + 1, qm, axis=0)
            w = np.insert(w, idx + 1, wm)
            bound = bound[:certified]
            continue
        # every chord is within the tolerance: certify the motions
        rep = checker.check_path(q[certified:], certify=True)
        if rep.valid:
            certified = len(s) - 1
            break
        k = certified + rep.bad_motion
        certified = k
        piece = s[k + 1] - s[k]
        if k + 1 == len(s) - 1 and end_s < poly.length and piece <= BACKOFF_PIECE:
            # the final piece ends on a margin (the bisected boundary), where no motion can be
            # certified (margin 0): pull the end back, by growing steps. The steps are tried
            # in order as one at a time would (the first end whose motion certifies is kept;
            # an end that breaks a rule, or a step beyond half the piece, ends the pull-back),
            # but their postures come from one batched inverse kinematics.
            first_step = BACKOFF_START if backoff == 0.0 else 4.0 * backoff
            steps = first_step * 4.0 ** np.arange(16)
            pulled = np.cumsum(steps)
            fits = steps < 0.5 * (piece - np.concatenate([[0.0], pulled[:-1]]))
            n_try = int(np.argmin(fits)) if not np.all(fits) else len(fits)
            accepted = False
            if n_try > 0:
                s_try = float(s[-1]) - pulled[:n_try]
                qm, okm, wm, _ = walker.posture_at(s_try, q[k])
                valid_m = okm.copy()
                if np.any(okm):
                    valid_m[okm] = checker.is_valid(qm[okm])
                for j in range(n_try):
                    backoff = float(steps[j])
                    if not valid_m[j]:
                        break
                    s[-1], q[-1], w[-1] = s_try[j], qm[j], wm[j]
                    end_s = float(s_try[j])
                    rep = checker.check_path(q[certified:], certify=True)
                    if rep.valid:
                        accepted = True
                        break
                else:
                    backoff = float(4.0 * steps[n_try - 1])  # the next step is too large
                piece = s[k + 1] - s[k]
            else:
                backoff = first_step
            if accepted:
                bound = bound[:certified]
                continue
        if piece > MIN_PIECE:
            # split at the midpoint; the final piece of a path that stops on a rule's boundary
            # also at 3/4 and 7/8: the margin shrinks towards that end, so its second half
            # fails in turn (three halving rounds in one)
            stops_short = k + 1 == len(s) - 1 and end_s < poly.length
            frac = GRADED_SPLIT if stops_short else GRADED_SPLIT[:1]
            s_mid = s[k] + np.asarray(frac) * (s[k + 1] - s[k])
            qm, okm, wm, _ = walker.posture_at(s_mid, q[k])
            valid_m = okm.copy()
            if np.any(okm):
                valid_m[okm] = checker.is_valid(qm[okm])
            n_ok = int(np.argmin(valid_m)) if not np.all(valid_m) else len(frac)
            if n_ok > 0:
                s = np.insert(s, k + 1, s_mid[:n_ok])
                q = np.insert(q, k + 1, qm[:n_ok], axis=0)
                w = np.insert(w, k + 1, wm[:n_ok])
                bound = bound[:certified]
                continue
        # the motion out of waypoint k cannot be certified: stop at k
        t_bad = rep.t
        q_stop_bad = q[k] + t_bad * (q[k + 1] - q[k])
        p_stop_bad = forward_batch(design, q_stop_bad, asm).p[0]
        stop_rule = rep.reason
        s, q, w = s[: k + 1], q[: k + 1], w[: k + 1]
        bound = bound[:k]
        end_s = float(s[-1])
        cut_reason = "motion"
    else:  # pragma: no cover - the refinement always ends (pieces halve down to MIN_PIECE)
        raise InputError("the Cartesian refinement did not converge")
    bound = bound[: len(s) - 1]

    fraction = 1.0 if poly.length == 0.0 else min(end_s / poly.length, 1.0)
    if end_s >= poly.length:
        fraction = 1.0
    stop = None
    status = PlanStatus.SOLVED if fraction == 1.0 else PlanStatus.NO_PATH
    message = f"solved: P follows the polyline in working mode {mode} ({len(s)} waypoints)"
    if status is PlanStatus.NO_PATH:
        rule = stop_rule or "path_tolerance"
        if cut_reason == "path_tolerance":
            rule = "path_tolerance"
        p_end = poly.at(np.array([end_s]))[0]
        if rule == "path_tolerance":
            value = float(bound.max()) if len(bound) else float("nan")
            sentence = (
                f"path_tolerance: no certified joint path keeps P within {tol:g} m of the line "
                "here (the chord bound grows without limit: a singularity is near)"
            )
        else:
            value, sentence = _describe(
                design, checker, rule, q_stop_bad,
                p_stop_bad if p_stop_bad is not None else p_end,
            )  # fmt: skip
        where = f" at P = {_fmt_point(p_end)}, {100 * fraction:.1f} % along the path"
        ahead = [e for e in events if e.fraction >= fraction - 1e-9 and e.entering]
        hint = f"; ahead: {ahead[0].detail} at {100 * ahead[0].fraction:.1f} %" if ahead else ""
        message = sentence + where + hint
        stop = StopPoint(rule, value, p_end, fraction, sentence + where)

    # measures of the joint path
    path = PlanPath(q.copy(), (Segment(mode, asm, 0, len(q) - 1),), ())
    p_way = poly.at(s)
    p_way[0] = p0
    report = checker.check_path(q, certify=False)
    planning_time = time.perf_counter() - t0

    trajectory, timing_error, timing_time = None, "", 0.0
    dev_measured = float("nan")
    blend_bound = 0.0
    if timing != "none" and len(q) >= 2 and (status is PlanStatus.SOLVED or time_partial):
        t1 = time.perf_counter()
        budget = np.full(len(q), tol)
        budget[1:-1] -= np.maximum(bound[:-1], bound[1:])
        dev, gain = blend_allowance(design, q, budget)
        blend_bound = float(np.max(gain[dev > 0] * dev[dev > 0], initial=0.0))

        def timed(method: str):
            return time_path(
                design, q, limits, method=method, assembly_mode=asm,
                sample_rate_hz=sample_rate_hz, max_cartesian_speed=cartesian_speed,
                max_deviation=dev, check_states=checker.is_valid,
                check_resolution=check_resolution or DEFAULT_CHECK_RESOLUTION,
            )  # fmt: skip

        try:
            trajectory = timed(timing)
        except TimingError as exc:
            timing_error = str(exc)
            if timing == "ruckig":
                # ruckig's moves between through-states may stray farther than the small
                # blend allowance that the tolerance leaves; toppra's blends cannot
                try:
                    trajectory = timed("toppra")
                    timing_error = f"ruckig failed ({exc}); timed with toppra instead"
                except TimingError as exc2:
                    timing_error = f"ruckig: {exc}; toppra: {exc2}"
        timing_time = time.perf_counter() - t1
        if trajectory is not None:
            tc = trajectory.curve.check_times(min(check_resolution or 1e-3, 1e-3))
            qt = trajectory.curve.evaluate(tc)[0]
            pt = forward_batch(design, qt, asm).p
            dev_measured = float(np.max(distance_to_polyline_3d(poly.vertices, pt)))
    if trajectory is None and len(q) >= 2:
        dense = np.concatenate([q[i] + np.linspace(0, 1, 9)[:, None] * (q[i + 1] - q[i])
                                for i in range(len(q) - 1)])  # fmt: skip
        dev_measured = float(np.max(distance_to_polyline_3d(
            poly.vertices, forward_batch(design, dense, asm).p)))  # fmt: skip
    elif len(q) < 2:
        dev_measured = 0.0
    diagnostics = CartesianDiagnostics(
        planning_time_s=planning_time,
        timing_time_s=timing_time,
        path_length=report.length,
        cartesian_length=end_s,
        max_kappa_A=report.max_kappa_A,
        min_serial_margin=report.min_serial_margin,
        min_clearance=report.min_clearance,
        chord_bound=float(bound.max()) if len(bound) else 0.0,
        max_path_deviation=dev_measured,
        blend_deviation_bound=blend_bound,
        waypoints=len(q),
    )
    if timing_error:
        message += f" (timing: {timing_error})"
    return CartesianResult(
        status, message, fraction, path, poly.vertices, s, p_way, stop, trajectory,
        timing_error, events, mode, asm, diagnostics,
    )  # fmt: skip
