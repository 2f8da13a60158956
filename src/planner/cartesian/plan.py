"""Straight tool paths: P follows a Cartesian polyline inside one working and assembly mode.

The straight kind of :mod:`planner.motion`: :class:`StraightMotion` supplies the planning step
(steps 1-3 below) and the answer (:class:`~planner.cartesian.result.CartesianResult`); the
pipeline (:func:`planner.motion.run`) does the rest as for every kind: the gravity check at the
start, the timing with its dense re-check, the one deadline policy (past the deadline, status
``timeout``). :func:`plan_cartesian` is its keyword call; :func:`inspect_cartesian` a pre-check
that says where the polyline leaves the workspace of the start's working mode or meets a
serial or parallel singular surface, before any planning.

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
4. Timing (optional) is the pipeline's (:func:`planner.motion.time_planned`) with the blend
   allowance of every joint vertex chosen so that a blended posture keeps P within the rest
   of the tolerance (:func:`blend_allowance`). Ruckig's moves between through-states may
   stray farther than that small allowance; TOPPRA's blends cannot, so a path Ruckig cannot
   time is timed with TOPPRA and the answer says so.

One module a part, this one the kind and the family's public face (it exports the names users
import from ``planner.cartesian.plan``): :mod:`planner.cartesian.certify` (steps 1-3),
:mod:`planner.cartesian.walk` (the polyline, the inverse kinematics of the mode's branch along
it, the bisection of step 1), :mod:`planner.cartesian.messages` (why a path stops),
:mod:`planner.cartesian.chords` (the bounds of steps 2 and 4),
:mod:`planner.cartesian.inspection` (the pre-check) and
:mod:`planner.cartesian.result` (the answer).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np

from planner.cartesian.certify import MAX_REFINEMENTS, MIN_PIECE, Refinement, probe_polyline
from planner.cartesian.chords import (
    blend_allowance,
    chord_deviation_bound,
    second_derivative_bound,
)
from planner.cartesian.inspection import inspect_cartesian, inspect_with_branch
from planner.cartesian.messages import describe_stop, format_point
from planner.cartesian.result import (
    CartesianDiagnostics,
    CartesianResult,
    PathEvent,
    StopPoint,
)
from planner.cartesian.walk import (
    PROBE_STEP,
    Polyline,
    Walker,
    as_points,
    distance_to_polyline_3d,
    max_deviation_along,
)
from planner.design import Design
from planner.dynamics import DEFAULT_GRAVITY, Inertia
from planner.exceptions import InputError
from planner.geometry import Obstacle
from planner.kinematics import WORKING_MODES, forward_batch
from planner.motion import MotionProblem, Planned, Timed, TimingRequest, run
from planner.planning.problem import JointPosture
from planner.planning.result import PlanPath, PlanStatus, Segment
from planner.planning.single_mode import posture_mode
from planner.timing.limits import JointLimits
from planner.timing.options import TimingOptions
from planner.timing.trajectory import Curve, TimeScaledCurve, ToppraCurve
from planner.validity import Margins, ValidityChecker
from planner.validity.reports import PathReport

__all__ = [
    "CHORD_SHARE",
    "MIN_PIECE",
    "PROBE_STEP",
    "CartesianDiagnostics",
    "CartesianResult",
    "PathEvent",
    "StopPoint",
    "StraightMotion",
    "blend_allowance",
    "chord_deviation_bound",
    "distance_to_polyline_3d",
    "inspect_cartesian",
    "plan_cartesian",
    "second_derivative_bound",
]

#: Share of ``path_tolerance`` given to the chords between joint waypoints; the rest is the
#: timing's corner blends.
CHORD_SHARE = 0.5
#: toppra's grid refinement for a straight path (:func:`planner.timing.time_path`'s
#: ``grid_refine``; plans use 4 on lines and 16 on blends). A straight path is many short
#: chords (20-30 joint pieces for 0.6 m at 1 mm), and the grid's floor of intervals per piece
#: made its size grow with the chord count (460-650 points for 0.6 m: half the call's time);
#: the profile is mostly flat at the Cartesian speed bound, so refinement 1 loses 0.2 % of
#: duration on ``benchmarks/cartesian.py``'s lines for 2x less time. The dense re-check and
#: the time-scale fit hold every limit as before.
TIMING_GRID_REFINE = 1.0


@dataclass(frozen=True, slots=True)
class _Refused:
    """The planning step's detail when the start is refused: the start's mode, if any."""

    mode: str
    t0: float


@dataclass(frozen=True, slots=True, eq=False)
class _Straight:
    """The planning step's detail: the certified joint path and why it ends where it does."""

    poly: Polyline
    s: np.ndarray
    q: np.ndarray
    bound: np.ndarray
    end_s: float
    fraction: float
    stop: StopPoint | None
    events: tuple[PathEvent, ...]
    mode: str
    path: PlanPath
    p_way: np.ndarray
    report: PathReport
    planning_time_s: float
    blend_bound: float


@dataclass(frozen=True, slots=True, eq=False)
class StraightMotion:
    """P on the straight segments start-P -> waypoints[0] -> ... in the start's working and
    assembly mode, stopping at the last valid point where a rule would break: a
    :class:`planner.motion.Motion` whose answer is a :class:`CartesianResult`.

    Parameters
    ----------
    waypoints : array, shape (K, 3) or (3,), m
    path_tolerance : float, m, > 0
        Largest distance of P from the polyline, along the joint path (certified by
        :func:`chord_deviation_bound`) and along the timed trajectory (certified by the blend
        allowance of :func:`blend_allowance`, re-measured densely).
    chord_share : float in (0, 1) -- share of the tolerance for the chords.
    time_partial : bool -- also time a path that stops short (default True).
    inspect : bool -- run :func:`inspect_cartesian` and attach its events.
    check_resolution : float, rad, optional -- the timing's dense re-check step (default
        the timing's default).
    """

    waypoints: np.ndarray
    path_tolerance: float = 1e-3
    chord_share: float = CHORD_SHARE
    time_partial: bool = True
    inspect: bool = True
    check_resolution: float | None = None

    def __post_init__(self) -> None:
        try:
            tol = float(self.path_tolerance)
        except (TypeError, ValueError) as exc:
            raise InputError(
                f"path_tolerance must be a number, got {self.path_tolerance!r}",
                field="path_tolerance",
            ) from exc
        if not (math.isfinite(tol) and tol > 0):
            raise InputError(
                f"path_tolerance must be a positive finite number (m), got {tol!r}",
                field="path_tolerance",
            )
        if not 0.0 < self.chord_share < 1.0:
            raise InputError(f"chord_share must lie in (0, 1), got {self.chord_share!r}")
        object.__setattr__(self, "path_tolerance", tol)
        object.__setattr__(self, "waypoints", as_points(self.waypoints))

    def plan(self, problem: MotionProblem) -> Planned[_Straight | _Refused]:
        """Steps 1-3 (the module docstring), and the timing of step 4 asked of the pipeline."""
        t0 = time.monotonic()
        design, start, budget = problem.design, problem.start, problem.budget
        asm = start.assembly_mode
        q0 = np.array(start.q, dtype=float)
        mode = posture_mode(design, start)
        if mode is None:
            checker0 = ValidityChecker(design, problem.margins, problem.obstacles, asm, "+++")
            why = checker0.explain(q0)
            if why in ("valid",) or why.startswith(("working_mode", "serial_min", "kappa")):
                why = "working_mode: the start lies on a serial singularity (its mode is undefined)"
            return Planned(PlanStatus.INVALID_START, f"invalid start: {why}", _Refused("", t0))
        checker = ValidityChecker(design, problem.margins, problem.obstacles, asm, mode)
        if not checker.is_valid(q0[None])[0]:
            message = f"invalid start: {checker.explain(q0)}"
            return Planned(PlanStatus.INVALID_START, message, _Refused(mode, t0))
        fb = forward_batch(design, q0, asm)
        pts = self.waypoints
        poly = Polyline(np.vstack([fb.p[0][None], pts]))
        slot, asm_sign = WORKING_MODES.index(mode), 1 if asm == "+" else -1
        walker = Walker(design, checker, poly, q0, slot, asm_sign)
        events: tuple[PathEvent, ...] = ()
        known = None  # the pre-check's inverse kinematics of its probes: the plan's own
        if self.inspect:
            events, known = inspect_with_branch(
                design,
                start,
                pts,
                margins=problem.margins,
                deadline=budget.deadline,
                built=(poly, mode),
            )
        probed = probe_polyline(design, checker, walker, poly, q0, slot, asm_sign, budget, known)
        tol = self.path_tolerance
        refined = Refinement(
            design, checker, walker, poly, q0, fb.w[0], probed, self.chord_share * tol
        ).run(budget)
        status, message, fraction, stop = _outcome(
            design, checker, poly, refined, events, tol, mode
        )
        q, s = refined.q, refined.s
        p_way = poly.at(s)
        p_way[0] = fb.p[0]
        detail = _Straight(
            poly,
            s,
            q,
            refined.bound,
            refined.end_s,
            fraction,
            stop,
            tuple(events),
            mode,
            PlanPath(q.copy(), (Segment(mode, asm, 0, len(q) - 1),), ()),
            p_way,
            refined.path_report(),
            time.monotonic() - t0,
            0.0,
        )
        timed = problem.timing.method != "none"
        if not timed or len(q) < 2 or not (status is PlanStatus.SOLVED or self.time_partial):
            return Planned(status, message, detail)
        allowance = np.full(len(q), tol)
        allowance[1:-1] -= np.maximum(refined.bound[:-1], refined.bound[1:])
        dev, gain = blend_allowance(design, q, allowance)
        blend_bound = float(np.max(gain[dev > 0] * dev[dev > 0], initial=0.0))
        detail = replace(detail, blend_bound=blend_bound)
        timing = TimingRequest(
            q,
            asm,
            checker.is_valid,
            dev,
            check_resolution=self.check_resolution,
            fallback=("toppra",),
            grid_refine=TIMING_GRID_REFINE,
        )
        return Planned(status, message, detail, timing)

    def answer(
        self, problem: MotionProblem, planned: Planned[_Straight | _Refused], timed: Timed
    ) -> CartesianResult:
        """The straight path, its trajectory (or why it was not timed) and its measures: the
        deviation of P from the polyline re-measured along the trajectory (or along the joint
        path when not timed)."""
        detail = planned.detail
        if not isinstance(detail, _Straight):
            return _refused(problem, self.waypoints, planned, detail)
        design, asm = problem.design, problem.start.assembly_mode
        trajectory, q = timed.trajectory, detail.q
        timing_error = timed.note or timed.reason
        status, message = planned.status, planned.message
        if timed.late:
            status = PlanStatus.TIMEOUT
            message = f"the path was found but timing ran out of time: {timed.error}"
        if trajectory is not None:
            resolution = min(self.check_resolution or 1e-3, 1e-3)
            dev_measured = _measured_deviation(
                design, trajectory.curve, resolution, asm, detail.poly.vertices
            )
        elif len(q) >= 2:
            dense = np.concatenate(
                [
                    q[i] + np.linspace(0, 1, 9)[:, None] * (q[i + 1] - q[i])
                    for i in range(len(q) - 1)
                ]
            )
            pt = forward_batch(design, dense, asm).p
            dev_measured = float(np.max(distance_to_polyline_3d(detail.poly.vertices, pt)))
        else:
            dev_measured = 0.0
        report, bound = detail.report, detail.bound
        diagnostics = CartesianDiagnostics(
            planning_time_s=detail.planning_time_s,
            timing_time_s=timed.time_s,
            path_length=report.length,
            cartesian_length=detail.end_s,
            max_kappa_A=report.max_kappa_A,
            min_serial_margin=report.min_serial_margin,
            min_clearance=report.min_clearance,
            chord_bound=float(bound.max()) if len(bound) else 0.0,
            max_path_deviation=dev_measured,
            blend_deviation_bound=detail.blend_bound,
            waypoints=len(q),
        )
        if timing_error and not timed.late:
            message += f" (timing: {timing_error})"
        return CartesianResult(
            status,
            message,
            detail.fraction,
            detail.path,
            detail.poly.vertices,
            detail.s,
            detail.p_way,
            detail.stop,
            trajectory,
            timing_error,
            detail.events,
            detail.mode,
            asm,
            diagnostics,
        )


def _measured_deviation(
    design: Design, curve: Curve, resolution: float, asm: str, vertices: np.ndarray
) -> float:
    """The largest distance of P from the polyline through ``vertices`` over the postures of
    ``curve`` at its check times for ``resolution``, m. A toppra curve (slowed uniformly or
    not) visits its path's postures at its check path positions whatever the timing, so they
    are measured there directly: the same postures as through the times, without the round
    trip s -> t -> s nor the rates, which the measure does not use, and in one compiled pass
    (:func:`~planner.cartesian.walk.max_deviation_along`: the same number as the postures'
    forward kinematics and distances, unsorted positions since a largest value needs no
    order; together 4x less than the three steps on a 0.6 m line)."""
    base = curve.base if isinstance(curve, TimeScaledCurve) else curve
    if isinstance(base, ToppraCurve):
        s = base.check_path_positions(resolution, ordered=False)
        return max_deviation_along(design, base.path, s, asm, vertices)
    q = curve.evaluate(curve.check_times(resolution))[0]
    return float(np.max(distance_to_polyline_3d(vertices, forward_batch(design, q, asm).p)))


def _refused(
    problem: MotionProblem, waypoints: np.ndarray, planned: Planned[Any], detail: _Refused | None
) -> CartesianResult:
    """The answer when nothing was planned: the start refused (by a rule, or by gravity at
    the start), or the deadline passed while planning."""
    start = problem.start
    fb = forward_batch(problem.design, np.asarray(start.q, dtype=float), start.assembly_mode)
    first = fb.p[0][None] if fb.ok[0] else np.full((1, 3), np.nan)
    elapsed = 0.0 if detail is None else time.monotonic() - detail.t0
    return CartesianResult(
        planned.status,
        planned.message,
        0.0,
        None,
        np.vstack([first, waypoints]),
        np.zeros(0),
        np.zeros((0, 3)),
        None,
        None,
        "",
        (),
        "" if detail is None else detail.mode,
        start.assembly_mode,
        CartesianDiagnostics(elapsed),
    )


def _outcome(
    design: Design,
    checker: ValidityChecker,
    poly: Polyline,
    refined: Refinement,
    events: Sequence[PathEvent],
    tol: float,
    mode: str,
) -> tuple[PlanStatus, str, float, StopPoint | None]:
    """(status, message, fraction, stop) of the certified path: ``solved`` when it reaches
    the end of the polyline, else ``no_path`` with the rule, its value, the point and the
    next event the pre-check saw ahead."""
    end_s = refined.end_s
    fraction = 1.0 if poly.length == 0.0 else min(end_s / poly.length, 1.0)
    if end_s >= poly.length:
        fraction = 1.0
    if fraction == 1.0:
        message = (
            f"solved: P follows the polyline in working mode {mode} ({len(refined.s)} waypoints)"
        )
        return PlanStatus.SOLVED, message, fraction, None
    rule = refined.stop_rule or "path_tolerance"
    if refined.cut_reason == "path_tolerance":
        rule = "path_tolerance"
    p_end = poly.at(np.array([end_s]))[0]
    bound = refined.bound
    if refined.cut_reason == "rounds":
        value, sentence = (
            float("nan"),
            (
                f"{rule}: the motion on from here was not certified within "
                f"{MAX_REFINEMENTS} refinement passes (the path up to here is)"
            ),
        )
    elif rule == "path_tolerance":
        value = float(bound.max()) if len(bound) else float("nan")
        sentence = (
            f"path_tolerance: no certified joint path keeps P within {tol:g} m of the line "
            "here (the chord bound grows without limit: a singularity is near)"
        )
    else:
        p_bad = refined.p_bad if refined.p_bad is not None else p_end
        value, sentence = describe_stop(design, checker, rule, refined.q_bad, p_bad)
    where = f" at P = {format_point(p_end)}, {100 * fraction:.1f} % along the path"
    ahead = [e for e in events if e.fraction >= fraction - 1e-9 and e.entering]
    hint = f"; ahead: {ahead[0].detail} at {100 * ahead[0].fraction:.1f} %" if ahead else ""
    stop = StopPoint(rule, value, p_end, fraction, sentence + where)
    return PlanStatus.NO_PATH, sentence + where + hint, fraction, stop


def plan_cartesian(
    design: Design,
    start: JointPosture,
    waypoints: np.ndarray,
    *,
    obstacles: Sequence[Obstacle] = (),
    margins: Margins | None = None,
    path_tolerance: float = 1e-3,
    timing: Literal["toppra", "ruckig", "none"] = "toppra",
    limits: JointLimits | None = None,
    cartesian_speed: float | None = None,
    sample_rate_hz: float = 100.0,
    check_resolution: float | None = None,
    chord_share: float = CHORD_SHARE,
    time_partial: bool = True,
    inspect: bool = True,
    inertia: Inertia | None = None,
    gravity: tuple[float, float, float] = DEFAULT_GRAVITY,
    deadline: float | None = None,
) -> CartesianResult:
    """The keyword call of :class:`StraightMotion` through the pipeline: move P on the
    straight segments start-P -> waypoints[0] -> ... in the start's working and assembly
    mode, stopping at the last valid point where a rule would break.

    Parameters
    ----------
    design : Design
    start : JointPosture
        Its working mode (the sign triple of its posture) and assembly mode are kept.
    waypoints, path_tolerance, chord_share, time_partial, inspect, check_resolution :
        As for :class:`StraightMotion`.
    obstacles : spheres, boxes, capsules (:mod:`planner.geometry`).
    margins : Margins, optional (defaults).
    timing : "toppra" | "ruckig" | "none"
    limits : planner.timing.JointLimits, optional (defaults).
    cartesian_speed : float, m/s, optional
        Bound on the speed of P (``max_cartesian_speed`` of :func:`planner.timing.time_path`):
        the tool moves at this constant speed wherever the joint limits allow.
    sample_rate_hz : float, Hz -- output rate of the trajectory.
    inertia, gravity : the robot's :class:`planner.dynamics.Inertia` and gravity (m/s^2) for
        the timing's torques (:func:`planner.timing.time_path`).
    deadline : float, optional
        A :func:`time.monotonic` value: checked between chunks of probes, in every round of
        the refinement and by the timing; past it, status ``timeout`` (the path kept when it
        was certified before the deadline passed).

    Returns
    -------
    CartesianResult
        ``fraction`` = share of the polyline's length achieved; status ``solved`` exactly
        when it is 1 (and the deadline did not pass).

    Raises
    ------
    InputError
        A malformed argument (the message names it).
    """
    if timing not in ("toppra", "ruckig", "none"):
        raise InputError(f"timing must be 'toppra', 'ruckig' or 'none', got {timing!r}")
    options = TimingOptions(
        method=timing, sample_rate_hz=sample_rate_hz, max_cartesian_speed=cartesian_speed
    )
    problem = MotionProblem.of(
        design,
        start,
        obstacles=obstacles,
        margins=margins,
        timing=options,
        limits=limits,
        inertia=inertia,
        gravity=gravity,
        deadline=deadline,
    )
    motion = StraightMotion(
        np.asarray(waypoints),
        path_tolerance,
        chord_share,
        time_partial,
        inspect,
        check_resolution,
    )
    return run(problem, motion)
