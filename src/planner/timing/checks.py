"""Dense re-check of a timed trajectory: limits, joint limits, assembly and validity.

Why dense, and how dense. The planner certified the straight segments of the polyline; the
timed trajectory leaves them near blended corners (toppra) or between through-states (ruckig),
and its limits are certified by the solvers only at their own grid points. So the curve is
re-checked at *check times* chosen so that consecutive checked postures are at most
``resolution`` apart in joint space (Euclidean, rad): every posture of the trajectory is then
within ``resolution / 2`` of a checked one. A validity rule whose margin changes by at most
``G`` per rad of joint motion (clearance: at most the reach ``L1 + L2`` m/rad; serial measures
and kappa(A) are smooth away from the singular sets they guard) cannot be violated by more than
``G * resolution / 2`` between checks. Passing the same ``resolution`` the planner's motion
validator uses gives the timed trajectory the same guarantee as the planned path. Limits are
checked at those times plus five points inside every toppra grid interval and both sides of
every acceleration jump, and at the output samples.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import njit

from planner import _kernels
from planner.constants import ASSEMBLY_TOL
from planner.design import Design
from planner.exceptions import InputError
from planner.kinematics import forward_batch
from planner.timing.limits import JointLimits
from planner.timing.path import distance_to_polyline, piece_of, point_on_piece
from planner.timing.toppra_method import PathProfile, read_at_path, read_at_time
from planner.timing.torque import TorqueModel, torque_time_scale
from planner.timing.trajectory import Curve, ToppraCurve, p_velocity

if TYPE_CHECKING:
    from planner.timing.job import TimingJob

__all__ = [
    "LIMIT_RTOL",
    "TORQUE_CHECK_RATE_HZ",
    "CheckReport",
    "StateChecker",
    "dense_check",
    "fit_ratios",
    "fit_time_scale",
    "torque_check_times",
]

logger = logging.getLogger(__name__)

#: Relative tolerance on every velocity, acceleration, jerk and Cartesian-speed limit: a sample
#: passes when |value| <= limit * (1 + LIMIT_RTOL) (solver round-off, not a slack).
LIMIT_RTOL = 1e-6
#: Relative tolerance on the deviation allowance.
DEVIATION_RTOL = 1e-9
#: Absolute tolerance on the design's joint limits, rad.
JOINT_LIMIT_TOL = 1e-9

#: With torque limits, the re-check also samples the motion at this rate, Hz: the check times
#: are spaced in joint space, but near rest a jerk-limited move changes its acceleration, and
#: so its torques, while the joints barely move (a 1.2 % excess was missed between them).
TORQUE_CHECK_RATE_HZ = 1000.0
#: Q (M, 3) -> valid (M,) bool, True = valid.
StateChecker = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True, eq=False)
class CheckReport:
    """Outcome of :func:`dense_check`.

    Attributes
    ----------
    t, q : check times (M,), s, and postures (M, 3), rad.
    bad_state : shape (M,), bool -- fails validity, joint limits or assembly.
    limit_ratio : dict rule -> largest |value| / limit over the samples (velocity,
        acceleration, jerk, cartesian_speed, torque).
    max_deviation_q, max_deviation_p : rad, m (see :class:`~planner.timing.Trajectory`).
    state_rule : shape (M,), str -- the failing rule of each bad state ("assembly",
        "joint_limits", "validity", "deviation"), "" for a good one.
    """

    t: np.ndarray
    q: np.ndarray
    bad_state: np.ndarray
    state_rule: np.ndarray
    limit_ratio: dict[str, float]
    max_deviation_q: float
    max_deviation_p: float

    @property
    def limits_ok(self) -> bool:
        return all(r <= 1.0 + LIMIT_RTOL for r in self.limit_ratio.values())

    @property
    def ok(self) -> bool:
        return self.limits_ok and not bool(np.any(self.bad_state))

    @property
    def worst_limit(self) -> tuple[str, float]:
        rule = max(self.limit_ratio, key=lambda k: self.limit_ratio[k])
        return rule, self.limit_ratio[rule]


def fit_time_scale(
    curve: ToppraCurve, limits: JointLimits, job: TimingJob, margin: float
) -> tuple[PathProfile, np.ndarray]:
    """The toppra profile slowed uniformly in time just enough that ``limits`` (the job's, or
    scaled) hold at every check position, ``margin`` (relative) inside them, not only at
    toppra's grid points; and those check positions (the slowed profile has the same grid,
    so the dense re-check's positions are these: built once). Step 3 of
    :func:`planner.timing.time_path`; here beside the re-check, whose positions and compiled
    pass it shares.

    Between grid points on a blend, q' and q'' turn, so a limit can be exceeded by a little
    (typically < 1 %, a few % on small blends). Slowing by c multiplies joint velocities and
    the Cartesian speed by c and accelerations by c^2 at the same path positions, so
    ``c = min(1, 1 / r_v, 1 / sqrt(r_a), 1 / r_cart)`` for the measured ratios r fixes them
    all exactly at those positions; torques scale by c^2 in their dynamic part only, and
    :func:`~planner.timing.torque.torque_time_scale` gives their c. Without torque limits the
    ratios come from one compiled pass (:func:`fit_ratios`: the same values as these steps).
    """
    prof = curve.profile
    tau_max = limits.torque_array
    torques = job.torque is not None and tau_max is not None
    # unsorted (a largest value needs no order; the re-check sorts their times), but in
    # order with torque limits, whose error names the first sample over a limit
    s = curve.check_path_positions(job.resolution, ordered=torques)
    target = 1.0 - margin
    ratios: tuple[Any, Any, Any]  # numpy's floats: a zero ratio divides to inf, as before
    if not torques and curve.path.n_pieces > 0:
        ratios = fit_ratios(curve, s, job.design, job.assembly_mode, limits)
    else:
        _, sd, sdd = prof.at_path(s)
        q, d1, d2 = curve.path.evaluate_all(s)
        r_v = np.max(np.abs(d1 * sd[:, None]) / limits.velocity_array)
        qdd = d1 * sdd[:, None] + d2 * (sd**2)[:, None]
        r_a = np.max(np.abs(qdd) / limits.acceleration_array)
        peak = np.max(job.gain_at(q, d1) * sd) if job.v_cart is not None else np.nan
        ratios = (r_v, r_a, peak)
    r_v, r_a, peak = ratios
    c = min(1.0, target / r_v, np.sqrt(target / r_a))
    if job.v_cart is not None:  # the largest |dP/ds| sd at the postures evaluated above
        c = min(c, target * job.v_cart / max(float(peak), 1e-300))
    if torques:
        assert job.torque is not None and tau_max is not None
        dyn, grav = job.torque.split(q, d1 * sd[:, None], qdd)
        c = min(c, torque_time_scale(dyn, grav, tau_max, target))
    if c >= 1.0:
        return prof, s
    logger.debug("toppra profile slowed by %.6f to meet the limits between grid points", c)
    return prof.time_scaled(c), s


def torque_check_times(duration: float) -> np.ndarray:
    """Times at :data:`TORQUE_CHECK_RATE_HZ` over [0, duration], s."""
    n = max(2, int(np.ceil(duration * TORQUE_CHECK_RATE_HZ)) + 1)
    return np.linspace(0.0, duration, n)


def dense_check(
    curve: Curve,
    *,
    design: Design,
    assembly_mode: str,
    waypoints: np.ndarray,
    limits: JointLimits,
    resolution: float,
    extra_times: np.ndarray,
    check_states: StateChecker | None,
    max_cartesian_speed: float | None,
    deviation_limit: np.ndarray | None = None,
    torque_model: TorqueModel | None = None,
    torque_in_time: bool = True,
    check_times: np.ndarray | None = None,
    validity_times: np.ndarray | None = None,
) -> CheckReport:
    """Evaluate ``curve`` at its check times (and ``extra_times``) and test every rule.

    Parameters
    ----------
    curve : Curve
    waypoints : shape (N, 3), rad -- the planned polyline (for the deviation).
    resolution : rad -- largest joint-space step between checked postures.
    extra_times : shape (E,), s -- e.g. the output sample times.
    check_states : Q (M, 3) -> bool (M,), optional
        The planner's validity rules (True = valid); joint limits and assembly are always
        checked here too.
    max_cartesian_speed : m/s, optional
    deviation_limit : shape (N,), rad, optional
        Largest allowed distance from the plan near each vertex (``max_deviation``); a
        posture farther from the segments it stands for fails with rule ``"deviation"``.
    torque_model : TorqueModel, optional
        With ``limits.torque``: the actuator torques checked too (rule ``"torque"``).
    torque_in_time : also check them on a :data:`TORQUE_CHECK_RATE_HZ` grid in time (needed
        for jerk-limited moves; a toppra curve's path acceleration is constant between its
        grid points, each of which is checked with subsamples, so near rest, where time
        passes but s does not, its torques do not change).
    check_times : shape (C,), s, optional
        ``curve.check_times(resolution)`` when the caller has them already.
    validity_times : shape (V,), s, optional
        Check times (each one of ``check_times``, to the bit) at most ``resolution`` apart
        in joint space, e.g. :meth:`ToppraCurve.validity_times`: ``check_states`` is then
        asked at these and at ``extra_times`` only (the others are there for the limits;
        the rules of a posture depend on the posture alone). None: at every check time.
    """
    if check_times is None:
        check_times = curve.check_times(resolution)
    times = [check_times, extra_times]
    if torque_model is not None and limits.torque is not None and torque_in_time:
        times.append(torque_check_times(curve.duration))
    t = np.unique(np.concatenate(times))
    st = _states(curve, t, design, assembly_mode, limits, torque_model, waypoints, deviation_limit)
    q, ratio = st.q, st.ratio
    if max_cartesian_speed is not None:
        ratio["cartesian_speed"] = st.speed / max_cartesian_speed
    # each bad posture's first failing rule, in this order (masks; the names at the end)
    failed: list[tuple[str, np.ndarray]] = [
        ("assembly", ~st.assembled),
        ("joint_limits", st.outside),
    ]
    if check_states is not None:
        failed.append(("validity", ~_valid_states(check_states, q, t, validity_times, extra_times)))
    if st.too_far is not None:
        failed.append(("deviation", st.too_far))
    dev_q, dev_p = st.dev_q, st.dev_p
    bad, rule = _first_failed(failed, t.shape[0])
    return CheckReport(
        t=t,
        q=q,
        bad_state=bad,
        state_rule=rule,
        limit_ratio=ratio,
        max_deviation_q=dev_q,
        max_deviation_p=dev_p,
    )


def _valid_states(
    check_states: StateChecker,
    q: np.ndarray,
    t: np.ndarray,
    validity_times: np.ndarray | None,
    extra_times: np.ndarray,
) -> np.ndarray:
    """:func:`dense_check`'s validity of the postures q (M, 3) at its times t (M,), sorted and
    unique: ``check_states`` at every one, or with ``validity_times`` only at those and at
    ``extra_times`` (both among t, to the bit; else at every one), the others valid."""
    at = None
    if validity_times is not None:
        at = np.zeros(t.shape[0], dtype=bool)
        for times in (validity_times, extra_times):
            i = np.minimum(np.searchsorted(t, times), t.shape[0] - 1)
            if not np.array_equal(t[i], times):  # not among t: every posture, never fewer
                at = None
                break
            at[i] = True
    asked = q if at is None else q[at]
    valid = np.asarray(check_states(asked))
    if valid.shape != (asked.shape[0],) or valid.dtype != np.bool_:
        raise InputError(
            f"check_states must return a bool array of shape ({asked.shape[0]},), "
            f"got {valid.dtype} {valid.shape}"
        )
    if at is None:
        return valid
    every = np.ones(t.shape[0], dtype=bool)
    every[at] = valid
    return every


def _first_failed(failed: list[tuple[str, np.ndarray]], m: int) -> tuple[np.ndarray, np.ndarray]:
    """(bad (M,) bool, state_rule (M,) str) of the rules' failure masks in the order given:
    a posture is named by the first rule it fails, "" when it fails none."""
    bad = np.zeros(m, dtype=bool)
    rule = np.full(m, "", dtype=object)
    for name, mask in failed:
        new = mask & ~bad
        if new.any():
            rule[new] = name
            bad |= new
    return bad, rule


@dataclass(frozen=True, eq=False)
class _Postures:
    """What :func:`dense_check` measures at its times before the validity rules: postures
    q (M, 3), P (M, 3), assembled (M,), the limit ratios (velocity, acceleration, jerk,
    torque; largest |value| / limit), the largest speed of P over the assembled postures
    (m/s), the postures beyond a joint limit (M,), those farther from the plan than their
    allowance (M,; None without ``deviation_limit`` or with no posture off the plan), and
    the largest distance from the plan in joint space (rad) and at P (m)."""

    q: np.ndarray
    assembled: np.ndarray
    ratio: dict[str, float]
    speed: float
    outside: np.ndarray
    too_far: np.ndarray | None
    dev_q: float
    dev_p: float


def _states(
    curve: Curve,
    t: np.ndarray,
    design: Design,
    assembly_mode: str,
    limits: JointLimits,
    torque_model: TorqueModel | None,
    waypoints: np.ndarray,
    deviation_limit: np.ndarray | None,
) -> _Postures:
    """:func:`dense_check`'s measures at times ``t`` (:class:`_Postures`). A toppra curve
    without torque limits in one compiled pass (:func:`_toppra_states`)."""
    torques = torque_model is not None and limits.torque is not None
    if isinstance(curve, ToppraCurve) and curve.path.n_pieces > 1 and not torques:
        return _toppra_states(curve, t, design, assembly_mode, limits, waypoints, deviation_limit)
    q, qd, qdd, jerk = curve.evaluate(t)
    segments = curve.plan_segments(t)
    ratio = {
        "velocity": float(np.max(np.abs(qd) / limits.velocity_array)),
        "acceleration": float(np.max(np.abs(qdd) / limits.acceleration_array)),
    }
    if jerk is not None and limits.jerk is not None:
        finite = np.isfinite(jerk)
        ratio["jerk"] = float(np.max(np.where(finite, np.abs(jerk), 0.0) / limits.jerk_array))
    if torque_model is not None and torques:
        tau = torque_model.torques(q, qd, qdd)
        # a singular posture (NaN torque) fails the assembly or validity rules, not this one
        ratio["torque"] = float(np.max(np.nan_to_num(np.abs(tau), nan=0.0) / limits.torque_array))
    p, v_p, assembled = p_velocity(design, q, qd, assembly_mode)
    speed = float(np.max(np.where(assembled, np.linalg.norm(v_p, axis=1), 0.0)))
    lo, hi = np.asarray(design.joint_min), np.asarray(design.joint_max)
    beyond = (q < lo - JOINT_LIMIT_TOL) | (q > hi + JOINT_LIMIT_TOL)
    outside = np.zeros(len(q), dtype=bool)
    if beyond.any():  # reduced per posture only then (most checks find none)
        outside = np.any(beyond, axis=1)
    off = segments[:, 0] >= 0
    too_far, dev_q, dev_p = None, 0.0, 0.0
    if np.any(off):
        dist, nearest = distance_to_polyline(waypoints, q[off], segments[off])
        if deviation_limit is not None:
            # A posture standing for segments lo..hi is near the corners lo+1..hi: it may be
            # as far from the plan as the smallest of their allowances.
            lo, hi = segments[off, 0] + 1, segments[off, 1]
            allowed = np.full(lo.shape[0], np.inf)
            for j in range(int(np.max(hi - lo, initial=0)) + 1):
                allowed = np.minimum(allowed, deviation_limit[np.minimum(lo + j, hi)])
            too_far = np.zeros(t.shape[0], dtype=bool)
            too_far[np.flatnonzero(off)] = dist > allowed * (1 + DEVIATION_RTOL) + 1e-12
        p_near = forward_batch(design, nearest, assembly_mode)
        both = assembled[off] & p_near.ok
        dev_q = float(np.max(dist))
        if np.any(both):
            at = np.flatnonzero(off)[both]
            dev_p = float(np.max(np.linalg.norm(p[at] - p_near.p[both], axis=1)))
    return _Postures(q, assembled, ratio, speed, outside, too_far, dev_q, dev_p)


def _toppra_states(
    curve: ToppraCurve,
    t: np.ndarray,
    design: Design,
    assembly_mode: str,
    limits: JointLimits,
    waypoints: np.ndarray,
    deviation_limit: np.ndarray | None,
) -> _Postures:
    """:func:`_states` of a toppra curve in one compiled pass (:func:`_toppra_kernel`): the
    profile read at each time, the posture and rates on the path, P and its velocity, the
    joint limits, on a blend the distance to its two segments, the allowance and P of the
    nearest planned posture, and the largest ratios, speed and distances, without an array
    per step; the same values as the steps (``tests/timing/test_timing_checks.py``)."""
    has_dev = deviation_limit is not None
    dev = np.asarray(deviation_limit if has_dev else np.zeros(0), dtype=float)
    out = _toppra_pass(
        curve, t, design, assembly_mode, limits, fit=False, waypoints=waypoints, deviation=dev
    )
    q, assembled, outside, too_far, largest = out
    ratio = {"velocity": float(largest[0]), "acceleration": float(largest[1])}
    any_off = bool(largest[5] > 0.0)  # a posture on a blend (the plan's segments near it)
    return _Postures(
        q,
        assembled,
        ratio,
        float(largest[2]),
        outside,
        too_far if has_dev and any_off else None,
        float(largest[3]),
        float(largest[4]),
    )


def fit_ratios(
    curve: ToppraCurve, s: np.ndarray, design: Design, assembly_mode: str, limits: JointLimits
) -> tuple[np.floating, np.floating, np.floating]:
    """At path positions ``s`` of a toppra curve (with pieces), in one compiled pass: the
    largest |qd_j| / velocity_j and |qdd_j| / acceleration_j, and the largest |dP/ds| sd, m/s
    (|dP/ds| inf where a posture does not assemble or CD is stretched; NaN when one such has
    sd = 0, as numpy's largest of inf * 0): what the time-scale fit measures, the same values
    as its steps (``tests/timing/test_timing_checks.py``)."""
    largest = _toppra_pass(curve, s, design, assembly_mode, limits, fit=True)[4]
    return largest[0], largest[1], largest[2]


def _toppra_pass(
    curve: ToppraCurve,
    x: np.ndarray,
    design: Design,
    assembly_mode: str,
    limits: JointLimits,
    *,
    fit: bool,
    waypoints: np.ndarray | None = None,
    deviation: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_toppra_kernel` at times (``fit`` False) or path positions ``x``: (q,
    assembled, outside, too_far, largest)."""
    prof, path = curve.profile, curve.path
    m = x.shape[0]
    q = np.empty((m, 3))
    assembled, outside, too_far = (np.zeros(m, dtype=np.bool_) for _ in range(3))
    largest = np.zeros(6)
    ro = _kernels.read_only
    w = path.waypoints if waypoints is None else waypoints
    _toppra_kernel(
        ro(x),
        fit,
        ro(prof.s),
        ro(prof.sd),
        ro(prof.time),
        ro(prof.sdd),
        ro(path.s0),
        ro(path.kind, np.int8),
        ro(path.origin),
        ro(path.direction),
        ro(path.normal),
        ro(path.radius),
        ro(path.corner, np.int64),
        design.L0,
        design.L1,
        design.L2,
        1.0 if assembly_mode == "+" else -1.0,
        ASSEMBLY_TOL,
        ro(limits.velocity_array),
        ro(limits.acceleration_array),
        ro(np.asarray(design.joint_min, dtype=float) - JOINT_LIMIT_TOL),
        ro(np.asarray(design.joint_max, dtype=float) + JOINT_LIMIT_TOL),
        ro(w),
        ro(np.zeros(0) if deviation is None else deviation),
        1 + DEVIATION_RTOL,
        q,
        assembled,
        outside,
        too_far,
        largest,
    )
    return q, assembled, outside, too_far, largest


@njit(cache=True, nogil=True, error_model="numpy")
def _toppra_kernel(
    x,
    fit,
    g_s,
    g_sd,
    g_time,
    g_sdd,
    s0,
    kind,
    origin,
    direction,
    normal,
    radius,
    corner,
    L0,
    L1,
    L2,
    branch,
    tol,
    vel,
    acc,
    jl_lo,
    jl_hi,
    w,
    dev,
    dev_scale,
    q,
    assembled,
    outside,
    too_far,
    largest,
):  # pragma: no cover - compiled
    """Per time x (``fit`` False): (s, sd, sdd) as :meth:`PathProfile.at_time` reads them
    (``read_at_time``), the piece and q, q', q'' on it (``piece_of``, ``point_on_piece``),
    qd = q' sd and qdd = q' sdd + q'' sd^2, P and dP/dt (:func:`planner._kernels.velocity_of`),
    whether q is beyond ``jl_lo`` / ``jl_hi``, and on the blend of corner k the distance to
    the plan's segments k-1 and k of ``w`` (``distance_to_polyline``'s arithmetic), whether
    it is over ``dev[k] dev_scale + 1e-12`` (with ``dev``), and P of the nearest point;
    into ``largest`` the greatest |qd_j| / vel_j, |qdd_j| / acc_j, |dP/dt| over assembled
    postures, distance, |P - P_near| (both assembled) and the count of blend postures. Per
    path position x (``fit``): (sd, sdd) as :meth:`PathProfile.at_path` reads them, the
    posture at x, the same ratios, and into ``largest[2]`` the greatest |dP/ds| sd (|dP/ds|
    from ``velocity_of`` at qd = q', inf where it is not 2; NaN when one product is NaN).
    Each formula in numpy's order: the same values bit for bit."""
    n_pieces = kind.shape[0]
    q1, q2 = np.empty(3), np.empty(3)
    nan_peak = False
    at, on = 0, 0  # the grid and piece counts of the position before (hints)
    for m in range(x.shape[0]):
        if fit:
            s = x[m]
            _, sd, a, at = read_at_path(s, g_s, g_sd, g_time, g_sdd, at)
        else:
            s, sd, a, at = read_at_time(x[m], g_s, g_sd, g_time, g_sdd, at)
        k, on = piece_of(s0, n_pieces, s, on)
        (q[m, 0], q[m, 1], q[m, 2], q1[0], q1[1], q1[2], q2[0], q2[1], q2[2]) = point_on_piece(
            k, s - s0[k], kind, origin, direction, normal, radius
        )
        for j in range(3):
            largest[0] = max(largest[0], abs(q1[j] * sd) / vel[j])
            largest[1] = max(largest[1], abs(q1[j] * a + q2[j] * sd**2) / acc[j])
        rate = 1.0 if fit else sd  # |dP/ds| in the fit, |dP/dt| in the check
        state, p0, p1, p2, v0, v1, v2 = _kernels.velocity_of(
            L0,
            L1,
            L2,
            q[m, 0],
            q[m, 1],
            q[m, 2],
            q1[0] * rate,
            q1[1] * rate,
            q1[2] * rate,
            branch,
            tol,
        )
        assembled[m] = state == 2
        speed = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2) if state == 2 else np.inf
        if fit:
            peak = speed * sd
            if peak != peak:
                nan_peak = True
            elif peak > largest[2]:
                largest[2] = peak
            continue
        if state == 2:
            largest[2] = max(largest[2], speed)
        for j in range(3):
            if q[m, j] < jl_lo[j] or q[m, j] > jl_hi[j]:
                outside[m] = True
        c = corner[k]
        if c < 0:  # on a line of the plan: no deviation
            continue
        largest[5] += 1.0
        best, near0, near1, near2 = _nearest_on_corner(q[m, 0], q[m, 1], q[m, 2], c, w)
        dist = math.sqrt(best)
        largest[3] = max(largest[3], dist)
        if dev.shape[0] > 0:
            too_far[m] = dist > dev[c] * dev_scale + 1e-12
        closes, _, _, _, _, pu, pw, _ = _kernels.close_loop(L0, L1, L2, near1, near2, branch, tol)
        if state == 2 and closes:
            e0 = p0 - pw * math.cos(near0)
            e1 = p1 - pu
            e2 = p2 - -pw * math.sin(near0)
            largest[4] = max(largest[4], math.sqrt(e0 * e0 + e1 * e1 + e2 * e2))
    if nan_peak:
        largest[2] = np.nan


@njit(cache=True, nogil=True)
def _nearest_on_corner(x0, x1, x2, c, w):  # pragma: no cover - compiled
    """The least squared distance of the posture (x0, x1, x2) to the plan's segments c - 1
    and c of ``w`` (N, 3) and the foot of it, as ``distance_to_polyline`` measures a posture
    against the segments it stands for (indices clipped to the segments, a single waypoint
    a segment from it to itself; the first of equally near segments kept)."""
    last_w = w.shape[0] - 1
    n_seg = max(last_w, 1)
    lo = min(max(c - 1, 0), n_seg - 1)
    hi = min(max(c, lo), n_seg - 1)
    best, near0, near1, near2 = np.inf, np.nan, np.nan, np.nan
    for seg in range(lo, hi + 1):
        b = min(seg + 1, last_w)
        denom = 0.0
        dot = 0.0
        for j in range(3):
            ab = w[b, j] - w[seg, j]
            denom += ab * ab
            dot += ((x0 if j == 0 else x1 if j == 1 else x2) - w[seg, j]) * ab
        f = dot / max(denom, 1e-300) if denom > 0 else 0.0
        f = min(max(f, 0.0), 1.0)
        foot0 = w[seg, 0] + f * (w[b, 0] - w[seg, 0])
        foot1 = w[seg, 1] + f * (w[b, 1] - w[seg, 1])
        foot2 = w[seg, 2] + f * (w[b, 2] - w[seg, 2])
        d2 = 0.0
        d2 += (x0 - foot0) ** 2
        d2 += (x1 - foot1) ** 2
        d2 += (x2 - foot2) ** 2
        if d2 < best:
            best, near0, near1, near2 = d2, foot0, foot1, foot2
    return best, near0, near1, near2
