"""The public entry of timing: :func:`time_path`, with its bounded repair loop.

Steps, each a function that :func:`time_path` calls in turn:

1. validate the inputs (typed errors naming the field): :func:`planner.timing.job.validate_inputs`;
2. blend the polyline's corners (:class:`~planner.timing.path.BlendedPath`) within
   ``max_deviation``, keeping the ``stop_at`` vertices as rest points:
   :func:`_build_blended_path`;
3. time it (:func:`_time_by_method`): toppra's time-optimal profile, slowed uniformly just
   enough that the limits hold between its grid points too; for ``ruckig``, a chain of
   jerk-limited moves through states taken from a toppra profile (slowed uniformly if the
   Cartesian speed bound needs it);
4. re-check the timed trajectory densely (:func:`~planner.timing.checks.dense_check`) at the
   check times and the output times (:func:`_output_times`): :func:`_dense_check`;
5. repair and go back to 3, at most ``MAX_REPAIRS`` times (:func:`_repair`):

   * a posture that fails validity, joint limits or assembly near a blend, or strays farther
     from the plan than ``max_deviation`` (ruckig): that corner's
     blend shrinks (``max_deviation / 4``, then ``/ 16``, then the corner becomes a stop,
     where the trajectory follows the planned segments exactly);
   * a limit exceeded somewhere the fit did not look (an output sample): the same profile
     (toppra) or chain (ruckig, Cartesian speed) is slowed uniformly by the measured excess;
     any other ruckig limit excess: the limits are scaled down and everything re-solved;

   a failure on the planned segments themselves cannot be repaired by timing: it raises
   :class:`~planner.exceptions.TrajectoryCheckError` at once, as does a failure left after the
   last repair. A trajectory is never returned without passing the check;
6. sample the checked curve, ends exact: :func:`_result`;
7. with torque limits, also the velocity-only timing slowed down uniformly until the torques
   hold (:func:`_slowed_velocity_only`), and the quicker of the two is the answer
   (:func:`_quicker_under_torques`): a torque-limited timing is never slower than that floor.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

from planner.design import Design
from planner.dynamics import DEFAULT_GRAVITY, Inertia
from planner.exceptions import (
    InputError,
    TimingError,
    TimingInfeasibleError,
    TrajectoryCheckError,
)
from planner.timing.checks import (
    LIMIT_RTOL,
    CheckReport,
    StateChecker,
    dense_check,
    fit_time_scale,
    torque_check_times,
)
from planner.timing.jerk_filter import JerkFilteredCurve, jerk_limited
from planner.timing.job import MAX_OUTPUT_SAMPLES, TimingJob, validate_inputs
from planner.timing.limits import JointLimits
from planner.timing.options import DEFAULT_MAX_DEVIATION, DEFAULT_SAMPLE_RATE_HZ
from planner.timing.path import BlendedPath
from planner.timing.ruckig_method import (
    SEED_REFINE,
    MoveCache,
    RuckigCurve,
    build_ruckig_curve,
)
from planner.timing.toppra_method import (
    PathProfile,
    SectionCache,
    check_deadline,
    min_blend_radius,
    solve_toppra,
)
from planner.timing.torque import torque_time_scale
from planner.timing.trajectory import (
    Curve,
    RestCurve,
    TimeScaledCurve,
    ToppraCurve,
    Trajectory,
    p_velocity,
    sample_times,
)
from planner.timing.via_retime import quicker_retimed
from planner.timing.vias import SplicedCurve, drop_failed_vias, splice_vias

__all__ = [
    "DEFAULT_CHECK_RESOLUTION",
    "MAX_OUTPUT_SAMPLES",
    "MAX_REPAIRS",
    "time_path",
]

logger = logging.getLogger(__name__)

#: Largest joint-space step between two postures of the dense re-check, rad.
DEFAULT_CHECK_RESOLUTION = 0.01
#: Repair rounds before giving up (3 blend shrinks per corner, and limit rescaling).
MAX_REPAIRS = 6
#: A corner's blend shrinks by this factor per repair; below ``max_deviation / 16`` it stops.
_SHRINK = 4.0
_SHRINK_STEPS = 2
#: With torque limits, a toppra profile that its fit slows by more than 2 % (the torques
#: overshoot between grid points where M(q) changes fast, on tight blends: up to 26 % was
#: measured) is solved again on a grid twice as fine, at most this many times; the fastest
#: fitted profile is kept.
_TORQUE_REFINES = 2
_TORQUE_REFINE_BELOW = 1.02
#: toppra's own method solves on a grid this much finer than ``LINE_STEP`` / ``ARC_STEP`` of
#: :mod:`planner.timing.toppra_method` (lines), and its blends ``TOPPRA_ARC_REFINE`` finer
#: still: the profile's constraints hold at grid points and its switches are quantised by
#: the grid, so a coarse grid is slow, and most of the loss is on the blends, where the
#: bounds dip and turn. With neither, the velocity-only profile was 0.6-5 % above the
#: optimum of a 128x finer grid (issue 36, 30 random three-corner paths; median 1.2 %); with
#: both (4 and 4: blends 16x) at most 0.24 % (median 0.06 %) for 2.3x the solve time
#: (``tests/timing/test_timing_optimality.py`` holds it within 0.5 %). ruckig's through-states
#: keep their own coarse grid (:data:`~planner.timing.ruckig_method.SEED_REFINE`).
TOPPRA_REFINE = 4
TOPPRA_ARC_REFINE = 4
#: The time scaling of a toppra profile aims this far (relative) inside the limits, so the
#: output samples, which fall between the fitted positions, pass too (the excess found there
#: was at most 2e-4 on the benchmark paths).
_FIT_MARGIN = 1e-3


def _exceeded(report: CheckReport) -> list[str]:
    """The limit rules a report finds exceeded."""
    return [rule for rule, r in report.limit_ratio.items() if r > 1.0 + LIMIT_RTOL]


def _fit_cartesian_speed(
    curve: Curve, design: Design, assembly_mode: str, resolution: float, v_cart: float
) -> Curve:
    """A ruckig chain slowed uniformly in time just enough that |dP/dt| <= v_cart at the
    check times (the through-states come from a toppra profile that meets the bound, but the
    moves between them may not). Slowing by c scales the speed of P by c and keeps every joint
    limit (velocity c, acceleration c^2, jerk c^3)."""
    t = curve.check_times(resolution)
    q, qd, _, _ = curve.evaluate(t)
    _, v, ok = p_velocity(design, q, qd, assembly_mode)
    peak = float(np.max(np.where(ok, np.linalg.norm(v, axis=1), 0.0)))
    target = v_cart * (1.0 - _FIT_MARGIN)
    if peak <= target:
        return curve
    return TimeScaledCurve(curve, target / peak)


def _fit_torque(curve: Curve, job: TimingJob) -> Curve:
    """A curve slowed uniformly in time just enough that the torque limits hold at the check
    times: a ruckig chain (the through-states come from a torque-limited toppra profile, but
    the jerk-limited moves between them may overshoot), or the velocity-only curve of
    :func:`_slowed_velocity_only`: the dynamic part of the torques scales
    by c^2 (:func:`~planner.timing.torque.torque_time_scale`), every joint limit still holds."""
    tau_max = job.limits.torque_array
    if job.torque is None or tau_max is None:
        return curve
    t = np.union1d(curve.check_times(job.resolution), torque_check_times(curve.duration))
    q, qd, qdd, _ = curve.evaluate(t)
    dyn, grav = job.torque.split(q, qd, qdd)
    c = torque_time_scale(dyn, grav, tau_max, 1.0 - _FIT_MARGIN)
    return curve if c >= 1.0 else TimeScaledCurve(curve, c)


def _torque_slow_down(curve: Curve, job: TimingJob, report: CheckReport) -> float:
    """The uniform slow-down that brings the torques of the failed check back within the
    limits (1 without torque limits)."""
    tau_max = job.limits.torque_array
    if job.torque is None or tau_max is None:
        return 1.0
    q, qd, qdd, _ = curve.evaluate(report.t)
    dyn, grav = job.torque.split(q, qd, qdd)
    return torque_time_scale(dyn, grav, tau_max, 1.0 - _FIT_MARGIN)


def _blame(curve: Curve, path: BlendedPath, report: CheckReport) -> set[int] | None:
    """Waypoint indices (of ``path.waypoints``) of the blends holding the bad postures, or
    None when a bad posture lies on a part that follows the planned segments exactly."""
    t_bad = report.t[report.bad_state]
    while isinstance(curve, (TimeScaledCurve, SplicedCurve)):  # (via chains: dropped first)
        scaled = isinstance(curve, TimeScaledCurve)
        t_bad = t_bad * curve.c if scaled else curve.base_time(t_bad)[0]  # type: ignore[union-attr]
        curve = curve.base
    if isinstance(curve, ToppraCurve):
        s, _, _ = curve.profile.at_time(t_bad)
        corners = path.arc_corner_at(s)
        if np.any(corners < 0):
            return None
        return {int(c) for c in corners}
    if isinstance(curve, (RuckigCurve, JerkFilteredCurve)):
        found: set[int] = set()
        for at in curve.corners_at(t_bad):
            if not at:
                return None
            found.update(at)
        return found
    return None


def _failure(report: CheckReport, where: str) -> TrajectoryCheckError:
    i = int(np.argmax(report.bad_state))
    rule = str(report.state_rule[i])
    q = tuple(float(x) for x in report.q[i])
    return TrajectoryCheckError(
        f"the timed trajectory fails the {rule} check at t = {report.t[i]:.4f} s, "
        f"q = {[round(x, 6) for x in q]} ({where})",
        rule=rule,
        time=float(report.t[i]),
        q=q,  # type: ignore[arg-type]
    )


def time_path(
    design: Design,
    waypoints: np.ndarray,
    limits: JointLimits,
    *,
    method: Literal["toppra", "ruckig"] = "toppra",
    assembly_mode: str = "+",
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
    max_cartesian_speed: float | None = None,
    max_deviation: float | np.ndarray = DEFAULT_MAX_DEVIATION,
    stop_at: Iterable[int] = (),
    check_states: StateChecker | None = None,
    check_resolution: float = DEFAULT_CHECK_RESOLUTION,
    deadline: float | None = None,
    max_samples: int | None = None,
    inertia: Inertia | None = None,
    gravity: tuple[float, float, float] = DEFAULT_GRAVITY,
    via_at: Iterable[int] = (),
    via_radius: float | np.ndarray | None = None,
    grid_refine: float | None = None,
) -> Trajectory:
    """Turn a planned joint path into a checked, timed trajectory from rest to rest.

    Parameters
    ----------
    design : Design
        Geometry (for P and its speed) and joint limits (checked along the trajectory).
    waypoints : array, shape (N, 3), rad
        The planned polyline: consecutive waypoints joined by straight joint-space segments,
        values literal (never wrapped). Inside the design's joint limits.
    limits : JointLimits
        Per-joint velocity and acceleration limits; jerk too for ``method="ruckig"``.
    method : "toppra" | "ruckig"
        ``toppra``: time-optimal under velocity and acceleration limits (and the Cartesian
        speed bound); acceleration is piecewise constant, jerk undefined. ``ruckig``:
        jerk-limited; q, qd and qdd continuous.
    assembly_mode : "+" | "-"
        Assembly mode of the path (for P).
    sample_rate_hz : float, Hz
        Output sample rate (the end time is always a sample).
    max_cartesian_speed : float, m/s, optional
        Bound on |dP/dt|. toppra: a constraint of the time-optimal problem; ruckig: the
        through-states come from that profile, and the chain is slowed uniformly if a move
        between them still exceeds the bound.
    max_deviation : float or array (N,), rad
        Largest joint-space distance from each interior vertex to its corner blend; 0 keeps
        the vertex (the trajectory stops there). Every re-checked posture is within this
        distance of the planned segments it stands for (toppra: by construction; ruckig:
        enforced by the re-check, a corner whose move strays farther has its blend shrunk).
    stop_at : indices of waypoints where the trajectory comes to rest (e.g. transits).
    check_states : callable Q (M, 3) -> bool (M,), optional
        Validity rules of the planner (True = valid), applied densely to the timed
        trajectory; joint limits and assembly are always checked.
    check_resolution : float, rad
        Largest joint-space step between two re-checked postures (see
        :mod:`planner.timing.checks` for the argument); use the planner's resolution.
    deadline : float, optional
        ``time.monotonic()`` value after which the work stops with
        :class:`~planner.exceptions.TimingDeadlineError`.
    max_samples : int, optional
        Most output samples allowed (default and cap :data:`MAX_OUTPUT_SAMPLES`): a
        duration x ``sample_rate_hz`` beyond it raises
        :class:`~planner.exceptions.InputError` (``field="sample_rate_hz"``) once the
        profile is known, before any sample is computed.
    inertia : Inertia, optional
        The robot's inertial model: with it, or with ``limits.torque`` (then default
        :meth:`~planner.dynamics.Inertia.default`), the trajectory carries its torques
        ``tau``; with ``limits.torque`` the timing is time-optimal under them as well
        (toppra's second-order constraint; ruckig: checked and slowed) and the dense
        re-check includes them.
    gravity : shape (3,), m/s^2, base frame (with torques)
    via_at : waypoints passed as free via states within their ``max_deviation``: a section
        whose interior waypoints all are may be a chain of moves through them
        (:mod:`planner.timing.vias`; kept when faster and when it passes the re-check).
    via_radius : float or array (N,), rad, optional
        Each via's ball, where its posture may lie (default: its ``max_deviation``); its
        moves may still leave the planned segments by up to ``max_deviation``. 0 passes the
        vertex exactly, at a free velocity: a section holding such a via always takes its
        chain (the blended path's arc rounds the corner, it does not pass the vertex),
        unless the re-check drops it; the caller checks the pass if it must be exact.
    grid_refine : float, optional -- toppra's grid refinement (:func:`_time_by_method`).

    Returns
    -------
    Trajectory
        Starts at ``waypoints[0]`` and ends at ``waypoints[-1]`` exactly, at rest.

    Raises
    ------
    InputError, LimitsError
        A bad argument (the message names it).
    TimingInfeasibleError
        The solver found no profile.
    TrajectoryCheckError
        The dense re-check fails and the repairs could not fix it.
    TimingDeadlineError
        ``deadline`` passed.
    """
    t_start = time.perf_counter()
    job = validate_inputs(
        design,
        waypoints,
        limits,
        method,
        assembly_mode,
        sample_rate_hz,
        max_cartesian_speed,
        max_deviation,
        stop_at,
        check_resolution,
        check_states,
        deadline,
        max_samples,
        inertia,
        gravity,
        via_at,
        via_radius,
        grid_refine,
    )
    return _quicker_under_torques(job, t_start)


def _quicker_under_torques(job: TimingJob, t_start: float) -> Trajectory:
    """Steps 2 to 7: without torque limits, the timing of :func:`_timed`; with them (step 7),
    the torque-limited timing, or the velocity-only one slowed down uniformly until the
    torques hold, whichever is quicker; the torque-limited timing's error when neither
    exists."""
    if job.limits.torque is None:
        return _timed(job, t_start)[0]
    limited: Trajectory | None = None
    error: TimingError | None = None
    try:
        limited = _timed(job, t_start)[0]
    except (TimingInfeasibleError, TrajectoryCheckError) as exc:
        error = exc
    slowed = _slowed_velocity_only(job, t_start)
    if limited is None and slowed is None:
        assert error is not None
        raise error
    best = min((x for x in (limited, slowed) if x is not None), key=lambda x: x.duration)
    return replace(best, computation_time_s=time.perf_counter() - t_start)


def _timed(job: TimingJob, t_start: float) -> tuple[Trajectory, _State]:
    """Steps 2 to 6: the trajectory of ``job`` that passes the dense re-check, and the state
    the repairs left (its path, blends shrunk where they had to)."""
    state = _build_blended_path(job)
    while True:
        check_deadline(job.deadline, "while timing the path")
        curve = _time_by_method(job, state)
        t_out = _output_times(job, curve)
        check_deadline(job.deadline, "before the dense re-check")
        report = _dense_check(job, state, curve, t_out)
        if report.ok:
            break
        _repair(job, state, curve, report)
    return _result(job, state, curve, report, t_out, t_start), state


#: Uniform slow-downs tried by :func:`_slowed_velocity_only` (each from the re-check's
#: measured torques: the first one aims inside the limits, so one is the usual count).
_SLOWED_TRIES = 3


def _slowed_velocity_only(job: TimingJob, t_start: float) -> Trajectory | None:
    """Step 7, with torque limits: the job timed without them (velocity, acceleration,
    jerk, Cartesian speed; same path, blends and checks), then slowed uniformly in time by
    the largest factor c that brings every torque within its limit (the dynamic part scales
    by c^2, :func:`~planner.timing.torque.torque_time_scale`; every other limit still holds)
    and re-checked densely with the torques. The torque-limited timing is meant to beat it,
    but where the second-order constraint's grid or a ruckig chain's fit costs more, this one
    is the floor: no answer is slower than a uniform slow-down of the velocity-only
    trajectory (issue 36). None when it cannot be built (gravity above a limit, a failed
    check)."""
    free = replace(job, limits=replace(job.limits, torque=None))
    try:
        base, state = _timed(free, t_start)
    except (TimingInfeasibleError, TrajectoryCheckError):
        return None
    try:  # the closed-form slow-down at the check times (the fit of a ruckig chain)
        curve = _fit_torque(base.curve, job)
        for _ in range(_SLOWED_TRIES):
            check_deadline(job.deadline, "while slowing the velocity-only timing")
            t_out = _output_times(job, curve)
            report = _dense_check(job, state, curve, t_out)
            if report.ok:
                return _result(job, state, curve, report, t_out, t_start)
            if set(_exceeded(report)) != {"torque"}:
                return None
            # slowed again from the torques where the check found them too high
            curve = TimeScaledCurve(curve, _torque_slow_down(curve, job, report))
    except TimingInfeasibleError:
        return None
    return None


@dataclass(eq=False)
class _State:
    """What the repair loop changes between rounds.

    path : the blended path being timed (its blends shrink on repair).
    dev : blend allowance per merged waypoint, rad; ``dev0`` the requested one (the re-check's
        deviation limit) and ``floor`` the smallest before a corner becomes a stop.
    scale, refine : joint-limit scaling and toppra grid refinement (ruckig limit repairs).
    slow_down : a pending uniform time scaling of ``profile`` (toppra limit repairs).
    profile : the toppra profile of ``path``, None when it must be solved again.
    rescaled : a ruckig chain slowed down by a repair, used as is in the next round.
    sections, moves : the toppra section profiles and Ruckig moves solved so far, so that a
        repair round solves again only what its repair changed (the work of all rounds stays
        linear in the number of waypoints; ``benchmarks/timing.py --scaling``).
    via, via_chains, via_off : the via waypoints (merged), the via chains built (by section)
        and the sections whose chain a repair dropped (:mod:`planner.timing.vias`).
    positions : (path, grid, s) -- the check path positions ``s`` the time-scale fit measured
        on ``path`` for a profile on ``grid`` (the dense re-check of a toppra curve on the same
        path and grid, slowed or not, checks the same ones: built once).
    """

    path: BlendedPath
    dev: np.ndarray
    dev0: np.ndarray
    floor: np.ndarray
    min_radius: float
    scale: float = 1.0
    refine: int = 1
    repairs: int = 0
    slow_down: float = 1.0
    profile: PathProfile | None = None
    rescaled: Curve | None = None
    sections: SectionCache = field(default_factory=dict)
    moves: MoveCache = field(default_factory=MoveCache)
    via: np.ndarray | None = None
    via_radius: np.ndarray | None = None
    via_chains: dict = field(default_factory=dict)
    via_off: set = field(default_factory=set)
    positions: tuple[BlendedPath, np.ndarray, np.ndarray] | None = None


def _build_blended_path(job: TimingJob) -> _State:
    """Step 2: the polyline's corners blended within ``max_deviation``, the ``stop_at``
    vertices kept as rest points; the allowances per merged waypoint."""
    min_radius = min_blend_radius(job.limits)
    path = BlendedPath.from_waypoints(job.waypoints, job.max_deviation, job.stop, min_radius)
    first = np.unique(path.index_map, return_index=True)[1]
    dev = np.minimum.reduceat(job.max_deviation, first)
    via = None if job.via is None else np.bincount(path.index_map, job.via, len(dev)) > 0
    via_radius = None if job.via_radius is None else np.minimum.reduceat(job.via_radius, first)
    return _State(
        path=path,
        dev=dev,
        dev0=dev.copy(),  # the allowance per (merged) waypoint, rad
        floor=dev / _SHRINK**_SHRINK_STEPS,
        min_radius=min_radius,
        via=via,
        via_radius=via_radius,
    )


def _time_by_method(job: TimingJob, state: _State) -> Curve:
    """Step 3: the timed curve of the current path. toppra: its time-optimal profile, slowed
    uniformly just enough that the limits hold between its grid points too (or by a pending
    repair's factor), on a grid refined ``TOPPRA_REFINE`` times on lines and
    ``TOPPRA_ARC_REFINE`` more on blends, or ``job.grid_refine`` times on both when given
    (the re-check and the time-scale fit hold the limits either way). ruckig: a chain of jerk-limited moves through states taken from a
    toppra profile (solved on a coarser grid, see :data:`SEED_REFINE`), slowed uniformly if
    the Cartesian speed bound needs it; a chain slowed by a repair is used as is."""
    if state.rescaled is not None:
        curve, state.rescaled = state.rescaled, None
        return curve
    path = state.path
    if path.length <= 0.0:
        return RestCurve(path.waypoints[0])
    lim = job.limits if state.scale == 1.0 else job.limits.scaled(state.scale)
    gain = job.speed_gain(path)
    if state.profile is None:
        own = job.method == "toppra"
        base, arc_refine = (TOPPRA_REFINE, TOPPRA_ARC_REFINE) if own else (SEED_REFINE, 1.0)
        if own and job.grid_refine is not None:
            base, arc_refine = job.grid_refine, 1.0
        refine = state.refine * base
        best: PathProfile | None = None
        for _ in range(1 + (_TORQUE_REFINES if lim.torque is not None else 0)):
            profile = solve_toppra(
                path,
                lim,
                speed_gain=gain,
                max_cartesian_speed=job.v_cart,
                refine=refine,
                arc_refine=arc_refine,
                deadline=job.deadline,
                torque_model=job.torque,
                cache=state.sections,
            )
            if job.method != "toppra":
                break
            fitted, positions = fit_time_scale(ToppraCurve(path, profile), lim, job, _FIT_MARGIN)
            if best is None or fitted.duration < best.duration:
                best = fitted
                state.positions = (path, fitted.s, positions)
            if fitted.duration <= profile.duration * _TORQUE_REFINE_BELOW:
                break
            refine *= 2  # the torques overshoot between grid points: a finer grid
        state.profile = best if best is not None else profile
    elif state.slow_down < 1.0:
        state.profile = state.profile.time_scaled(state.slow_down)
    if job.method == "toppra":  # with an asked jerk: each section moving-averaged
        smoothed = jerk_limited(ToppraCurve(path, state.profile), job.limits)
        return _with_vias(job, state, smoothed, lim)
    curve = build_ruckig_curve(path, state.profile, lim, deadline=job.deadline, cache=state.moves)
    return _with_vias(job, state, _fitted_chain(curve, job), lim)


def _fitted_chain(curve: Curve, job: TimingJob) -> Curve:
    """A chain of moves slowed uniformly for the Cartesian speed bound and torque limits."""
    if job.v_cart is not None:
        curve = _fit_cartesian_speed(
            curve, job.design, job.assembly_mode, job.resolution, job.v_cart
        )
    return _fit_torque(curve, job)


def _with_vias(job: TimingJob, state: _State, curve: Curve, lim: JointLimits) -> Curve:
    """``curve`` with its via sections spliced in where faster (:func:`splice_vias`)."""
    if state.via is None or state.profile is None:
        return curve
    return splice_vias(
        curve,
        state.path,
        state.profile,
        state.via,
        state.dev0 if state.via_radius is None else state.via_radius,
        lim,
        corridor=state.dev0,
        jerk=lim.jerk is not None,  # ruckig, or toppra with an asked jerk
        fit=lambda c: quicker_retimed(  # with torque limits: re-timed along its path too
            c,
            _fitted_chain(c, job),
            lim,
            job.torque,
            job.resolution,
            lambda r: _fitted_chain(r, job),
        ),
        chains=state.via_chains,
        dropped=state.via_off,
        key=state.scale,
        deadline=job.deadline,
    )


def _output_times(job: TimingJob, curve: Curve) -> np.ndarray:
    """The output rate's sample times plus every instant the motion rests (stop_at,
    transits); :class:`~planner.exceptions.InputError` when there would be more than the
    sample cap, before any sample is computed."""
    count = math.floor(curve.duration * job.rate) + 1
    if count > job.max_samples:
        raise InputError(
            f"sample_rate_hz = {job.rate:g} Hz would produce {count} samples over the "
            f"trajectory's {curve.duration:.4g} s, more than the limit of "
            f"{job.max_samples}: lower the rate",
            field="sample_rate_hz",
        )
    return np.union1d(sample_times(curve.duration, job.rate), curve.rest_times())


def _dense_check(job: TimingJob, state: _State, curve: Curve, t_out: np.ndarray) -> CheckReport:
    """Step 4: the timed curve re-checked densely (:func:`~planner.timing.checks.dense_check`)
    against the requested limits (not the scaled ones), joint limits, assembly, validity and
    the requested deviation allowance."""
    check_times = validity_times = None
    if isinstance(curve, ToppraCurve):
        # the validity rules at postures job.resolution apart (and the output samples),
        # the limits at every check time (ToppraCurve.validity_times)
        validity_times = curve.validity_times(job.resolution)
        if state.positions is not None:
            path, grid, positions = state.positions
            if curve.path is path and curve.profile.s is grid:  # the fit's positions
                check_times = curve.check_times(job.resolution, positions)
    return dense_check(
        curve,
        design=job.design,
        assembly_mode=job.assembly_mode,
        waypoints=state.path.waypoints,
        limits=job.limits,
        resolution=job.resolution,
        extra_times=t_out,
        check_states=job.check_states,
        max_cartesian_speed=job.v_cart,
        deviation_limit=state.dev0,
        torque_model=job.torque,
        torque_in_time=job.method == "ruckig",
        check_times=check_times,
        validity_times=validity_times,
    )


def _repair(job: TimingJob, state: _State, curve: Curve, report: CheckReport) -> None:
    """Step 5: one repair of a failed check (module docstring), or
    :class:`~planner.exceptions.TrajectoryCheckError` when none can help: the repairs are
    used up, or a bad posture lies on the planned segments themselves."""
    if state.repairs >= MAX_REPAIRS:
        if not report.limits_ok:
            rule, ratio = report.worst_limit
            raise TrajectoryCheckError(
                f"the {rule} limit is exceeded by a factor {ratio:.6f} after "
                f"{state.repairs} repairs",
                rule=rule,
            )
        raise _failure(report, f"after {state.repairs} repairs")
    state.repairs += 1
    repairs = state.repairs
    state.slow_down = 1.0
    dropped = drop_failed_vias(curve, report)
    state.via_off.update(dropped)
    if dropped:
        logger.info("timing repair %d: via chains dropped at %s", repairs, dropped)
        return
    if np.any(report.bad_state):
        path = state.path
        blamed = _blame(curve, path, report)
        if blamed is None:
            raise _failure(report, "on the planned segments: the path itself is invalid")
        dev, floor = state.dev, state.floor
        for k in blamed:
            dev[k] = 0.0 if dev[k] / _SHRINK < floor[k] * (1 - 1e-12) else dev[k] / _SHRINK
        stop_now = np.zeros(path.waypoints.shape[0], bool)
        stop_now[[k for k in blamed if dev[k] == 0.0]] = True
        state.path = BlendedPath.from_waypoints(
            path.waypoints, dev, stop_now | path.kept_stops(), state.min_radius
        )
        state.profile = None
        logger.info("timing repair %d: blends shrunk at waypoints %s", repairs, sorted(blamed))
    elif job.method == "ruckig" and set(_exceeded(report)) <= {"cartesian_speed", "torque"}:
        # Slow the same chain down uniformly (every joint limit still holds).
        c = _torque_slow_down(curve, job, report)
        if "cartesian_speed" in report.limit_ratio:
            c = min(c, (1.0 / report.limit_ratio["cartesian_speed"]) * (1.0 - _FIT_MARGIN))
        state.rescaled = TimeScaledCurve(curve, c)
        logger.info("timing repair %d: ruckig chain slowed by %.6f", repairs, c)
    elif job.method == "toppra":
        # Slow the same profile down uniformly: velocities and the Cartesian speed scale by
        # c, accelerations by c^2, at the same path positions.
        c = min(
            (1.0 / np.sqrt(r) if rule == "acceleration" else 1.0 / r)
            for rule, r in report.limit_ratio.items()
            if rule != "torque"
        )
        c = min(c * (1.0 - _FIT_MARGIN), _torque_slow_down(curve, job, report))
        state.slow_down = min(c, 1.0 - _FIT_MARGIN)
        logger.info("timing repair %d: profile slowed by %.6f", repairs, state.slow_down)
    else:
        rule, ratio = report.worst_limit
        state.scale *= min(1.0 / ratio, 1.0 - 1e-4) * (1.0 - 1e-3)
        state.refine *= 2
        state.profile = None
        logger.info(
            "timing repair %d: %s limit x%.6f, limits scaled to %.6f",
            repairs,
            rule,
            ratio,
            state.scale,
        )


def _result(
    job: TimingJob,
    state: _State,
    curve: Curve,
    report: CheckReport,
    t_out: np.ndarray,
    t_start: float,
) -> Trajectory:
    """Step 6: the checked curve sampled at the output times, ends exact (the first and last
    planned waypoints, at rest), with its measured quality."""
    q, qd, qdd, jerk = curve.evaluate(t_out)
    path = state.path
    q[0], q[-1] = path.waypoints[0], path.waypoints[-1]
    # at every rest instant (the ends, each stop_at, each transit) the samples carry the rest
    # state, qd = qdd = 0: toppra's acceleration jumps there (from braking to starting, as at
    # the ends from 0), so the instant itself has no one value; ruckig's is 0 already
    rest = np.isin(t_out, curve.rest_times())
    rest[0] = rest[-1] = True
    qd[rest] = 0.0
    qdd[rest] = 0.0
    if jerk is not None and not np.all(np.isfinite(jerk)):
        jerk = None
    p, v_p, _ = p_velocity(job.design, q, qd, job.assembly_mode)
    tau = None if job.torque is None else job.torque.torques(q, qd, qdd)
    return Trajectory(
        method=job.method,
        duration=curve.duration,
        t=t_out,
        q=q,
        qd=qd,
        qdd=qdd,
        jerk=jerk,
        p=p,
        p_speed=np.linalg.norm(v_p, axis=1),
        max_deviation_q=report.max_deviation_q,
        max_deviation_p=report.max_deviation_p,
        repairs=state.repairs,
        checked_samples=int(report.t.shape[0]),
        computation_time_s=time.perf_counter() - t_start,
        curve=curve,
        tau=tau,
        max_torque_ratio=report.limit_ratio.get("torque"),
    )
