"""Sequences with moving targets: picking parts from a belt (:class:`~planner.sequence.
problem.MovingTarget`), the interception planned over the working modes.

A moving target splits the sequence. The targets between moving ones are planned and timed
as any sequence (:func:`planner.sequence.solve.plan_sequence`, from rest to rest: the target
before a moving one is a stop); each moving target is then, in the working mode chosen:

1. **staging**: when the robot rests in another working mode, a planned leg to the same
   point P in the target's mode (the mode change through the transits the plan and the
   region map allow; a mode the plan cannot reach is out);
2. **interception** (:mod:`planner.sequence.interception`): the meeting time chosen on the
   part's trackable window (:mod:`planner.sequence.belt`): a wait at rest, a time-optimal
   move into the part's state (P and its velocity equal the part's), the tracking span of
   ``dwell`` s (the product's inverse kinematics on the part's straight path), a time-optimal
   move to rest at the landing posture: the next target's point in the same mode (consumed
   when its own mode allows it; else the next run starts there with it), or, for a last
   target without a cycle, to rest wherever the brakes bring it. Every curve is re-checked
   densely (validity in the mode, joint limits, assembly, the limits, torques); a candidate
   that fails is replaced by the next best;
3. the mode: ``objective="time"`` tries every working mode that reaches the part's path and
   keeps the one that brings the tool to rest at the landing soonest (staging included);
   ``"fixed"`` keeps the target's mode (for "any": the mode the robot rests in when it
   reaches the part, else the first that does) and meets the part as early as possible.

Before any planning, the part's path is scanned in every working mode (:func:`scan_part`):
a part that is nowhere reachable, or only before the sequence starts, is ``unreachable``
naming the target and the window; a part that leaves before the robot can meet it is
``unreachable`` with the window and the time the robot was ready.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from planner.exceptions import InputError
from planner.kinematics import WORKING_MODES, forward_batch
from planner.motion import MotionProblem
from planner.planning import CartesianTarget, JointPosture, PlanPath, PlanResult, PlanStatus
from planner.planning.result import Diagnostics, Segment
from planner.planning.single_mode import goal_candidates, posture_mode
from planner.sequence.belt import HoldCurve, scan_part
from planner.sequence.interception import BuiltPick, Interception, intercept
from planner.sequence.motion import leg_name
from planner.sequence.problem import (
    Leg,
    MovingTarget,
    SequenceDiagnostics,
    SequenceResult,
    SequenceTarget,
)
from planner.sequence.trajectory import joined_trajectory
from planner.timing.state_moves import StateMover
from planner.timing.torque import TorqueModel
from planner.validity import ValidityChecker

__all__ = ["MAX_VERIFIED", "plan_moving_sequence"]

#: Candidate meetings verified by their real curves per mode before the mode is given up.
MAX_VERIFIED = 6

Goal = JointPosture | CartesianTarget | MovingTarget


@dataclass
class _Run:
    """The sequence as it is built: the curves one after the other, the legs, the modes, the
    time and posture where the robot rests now."""

    q: np.ndarray
    t: float
    pieces: list = field(default_factory=list)
    legs: list[Leg] = field(default_factory=list)
    modes: dict[int, str] = field(default_factory=dict)
    static: list[SequenceResult] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    evaluated: int = 0  # meeting times whose cost was computed
    verified: int = 0  # modes whose best meeting was built and re-checked


def _checked(goals: Sequence[Goal], targets: Sequence[SequenceTarget], problem: MotionProblem):
    """What a sequence with moving targets cannot hold: two moving targets in a row (the
    move between two tracking spans is not built), or no timing (a meeting is a time)."""
    if problem.timing.method == "none":
        raise InputError(
            "a sequence with a moving target must be timed: its meetings are times",
            field=("timing", "method"),
        )
    for i in range(1, len(goals)):
        if isinstance(goals[i], MovingTarget) and isinstance(goals[i - 1], MovingTarget):
            raise InputError(
                f"targets {i - 1} and {i} are both moving: a static target (the place) must "
                "lie between two moving targets",
                field=("targets", i, "goal"),
            )


def _windows_text(windows: dict[str, list[tuple[float, float]]]) -> str:
    parts = [f"{m} from {a:.3f} to {b:.3f} s" for m, ws in windows.items() for a, b in ws if b >= a]
    return "; ".join(parts)


def _scan_all(problem: MotionProblem, target: MovingTarget, modes: Sequence[str]):
    """The part's path in each of ``modes`` over its whole pass (for the message and the
    search)."""
    asm = problem.start.assembly_mode
    out = {}
    for m in modes:
        checker = ValidityChecker(problem.design, problem.margins, problem.obstacles, asm, m)
        out[m] = (
            checker,
            scan_part(
                problem.design,
                target,
                checker,
                problem.limits,
                np.asarray(problem.start.q),
                -math.inf,
            ),
        )
    return out


def _precheck(
    problem: MotionProblem, goals: Sequence[Goal]
) -> tuple[SequenceResult | None, dict[int, dict]]:
    """Before any planning: each moving target's path must be trackable somewhere after the
    sequence starts (time 0) in one of its working modes; else ``unreachable``. Returns the
    scans too (per moving target, per mode: its checker and :class:`PartPath`)."""
    all_scans = {}
    for i, g in enumerate(goals):
        if not isinstance(g, MovingTarget):
            continue
        modes = list(WORKING_MODES) if g.working_mode == "any" else [g.working_mode]
        scans = all_scans[i] = _scan_all(problem, g, modes)
        windows = {m: s.windows() for m, (_, s) in scans.items() if s.windows()}
        if not windows:
            message = (
                f"target {i}: the part's path never enters the reachable set (in working "
                f"mode{'s' if len(modes) > 1 else ''} {', '.join(modes)})"
            )
            return SequenceResult(PlanStatus.UNREACHABLE, message, ()), all_scans
        if all(b < 0.0 for ws in windows.values() for _, b in ws):
            message = (
                f"target {i}: the part is reachable only before the sequence starts "
                f"({_windows_text(windows)}; sequence time)"
            )
            return SequenceResult(PlanStatus.UNREACHABLE, message, ()), all_scans
    return None, all_scans


def _shifted(msg: str, offset: int, n: int) -> str:
    """A run's message with its target indices made the sequence's."""

    def name(m: re.Match) -> str:
        return leg_name(int(m.group(1)) + offset, n)

    return re.sub(r"\btarget (\d+)", name, msg)


def _static_run(
    problem: MotionProblem,
    run: _Run,
    items: list[tuple[int, SequenceTarget]],
    objective: str,
    n: int,
) -> SequenceResult | None:
    """The static targets ``items`` (index, target) from where the robot rests, as one
    sequence; appended to ``run``; the failed answer when it fails."""
    from planner.sequence.solve import plan_sequence

    asm = problem.start.assembly_mode
    sub = problem.with_(start=JointPosture(run.q, asm))
    result = plan_sequence(sub, [t for _, t in items], cycle=False, objective=objective)
    offset = items[0][0]
    legs = [
        replace(
            leg,
            target_index=leg.target_index + offset,
            start_time=leg.start_time + run.t,
            end_time=leg.end_time + run.t,
            transit_times=tuple(x + run.t for x in leg.transit_times),
        )
        for leg in result.legs
    ]
    if not result.solved:
        message = _shifted(result.message, offset, n)
        return replace(result, message=message, legs=(*run.legs, *legs))
    for j, m in enumerate(result.diagnostics.modes):
        if m:
            run.modes[offset + j] = m
    run.legs += legs
    run.pieces.append(result.trajectory.curve)
    run.static.append(result)
    run.t += result.cycle_time
    run.q = np.asarray(result.trajectory.q[-1], dtype=float)
    return None


@dataclass(frozen=True, eq=False)
class _Option:
    """One working mode's best verified interception of a moving target."""

    mode: str
    pick: BuiltPick
    ic: Interception
    staging: SequenceResult | None
    consumed: bool


def _landing(
    problem: MotionProblem, goal: Goal | None, checker: ValidityChecker, q_near: np.ndarray
) -> tuple[np.ndarray | None, bool, str]:
    """Where the departure comes to rest: (posture or None for a last target, whether it
    is the next target itself, why none)."""
    if goal is None:
        return None, False, ""
    mode, design = checker.working_mode, problem.design
    if isinstance(goal, JointPosture):
        if posture_mode(design, goal) == mode and goal.assembly_mode == checker.assembly_mode:
            return np.asarray(goal.q, dtype=float), True, ""
        fb = forward_batch(design, goal.q, goal.assembly_mode)
        point, consumed = fb.p[0], False
    else:
        assert isinstance(goal, CartesianTarget)
        point, consumed = goal.p, goal.working_mode in ("any", mode)
    cands, why = goal_candidates(design, CartesianTarget(point, mode), checker, q_near)
    if not len(cands):
        return None, False, why or "the next target is not reached in this mode"
    return cands[0], consumed, ""


def _staging(problem: MotionProblem, run: _Run, mode: str) -> tuple[SequenceResult | None, str]:
    """The planned leg to P where the robot rests, in ``mode`` (None when it rests in that
    mode already); the reason when it cannot be planned."""
    from planner.sequence.solve import plan_sequence

    asm = problem.start.assembly_mode
    here = JointPosture(run.q, asm)
    if posture_mode(problem.design, here) == mode:
        return None, ""
    point = forward_batch(problem.design, run.q, asm).p[0]
    sub = problem.with_(start=here)
    result = plan_sequence(
        sub, [SequenceTarget(CartesianTarget(point, mode))], cycle=False, objective="fixed"
    )
    if not result.solved:
        return result, f"no change to working mode {mode}: {result.message}"
    return result, ""


def _interception(
    problem: MotionProblem,
    q_s: np.ndarray,
    t_s: float,
    target: SequenceTarget,
    next_goal: Goal | None,
    scan: tuple,
    objective: str,
) -> tuple[Interception | None, bool, str]:
    """The search's context from rest at ``q_s`` at time ``t_s`` in the scan's mode, whether
    the departure lands on the next target itself, and why there is none."""
    checker, path = scan
    landing, consumed, why = _landing(problem, next_goal, checker, q_s)
    if why:
        return None, False, f"the next target in {checker.working_mode}: {why}"
    goal = target.goal
    assert isinstance(goal, MovingTarget)
    mover = StateMover(problem.limits, jerk=problem.timing.method == "ruckig")
    ic = Interception(
        problem.design,
        goal,
        target.dwell,
        checker,
        problem.limits,
        mover,
        path,
        q_s,
        t_s,
        landing,
        objective,
    )
    return ic, consumed, ""


def _staged_bound(
    problem: MotionProblem,
    run: _Run,
    target: SequenceTarget,
    next_goal: Goal | None,
    scan: tuple,
    objective: str,
) -> tuple[float, str]:
    """A bound on a mode that needs a staging leg, before planning it: the search from the
    staging posture (P where the robot rests, in the mode) as if the robot rested there at
    the per-joint least time of the move (:func:`~planner.sequence.mode_search.
    leg_lower_bound`: no staging leg is quicker), so the search only meets later for real."""
    from planner.sequence.mode_search import leg_lower_bound

    checker = scan[0]
    point = forward_batch(problem.design, run.q, problem.start.assembly_mode).p[0]
    cands, why = goal_candidates(
        problem.design, CartesianTarget(point, checker.working_mode), checker, run.q
    )
    if not len(cands):
        return math.inf, f"no staging posture in {checker.working_mode}: {why}"
    t_s = run.t + leg_lower_bound(run.q, cands[0], problem.limits, stop_a=True, stop_b=True)
    ic, _, why = _interception(problem, cands[0], t_s, target, next_goal, scan, objective)
    if ic is None:
        return math.inf, why
    meetings = intercept(ic)
    run.evaluated += ic.evaluations
    if not meetings:
        return math.inf, f"no meeting possible in {checker.working_mode} after {t_s:.3f} s"
    return meetings[0].cost, ""


def _option(
    problem: MotionProblem,
    run: _Run,
    target: SequenceTarget,
    next_goal: Goal | None,
    scan: tuple,
    objective: str,
    torque: TorqueModel | None,
    beat: float = math.inf,
) -> tuple[_Option | None, str]:
    """The best verified interception in one working mode (the scan's), or why none. A mode
    that needs a staging leg is planned only when its bound (the search from where the robot
    rests, the staging's time left out: it only delays) is below ``beat``."""
    mode = scan[0].working_mode
    here = posture_mode(problem.design, JointPosture(run.q, problem.start.assembly_mode))
    if here != mode and math.isfinite(beat):
        bound, why = _staged_bound(problem, run, target, next_goal, scan, objective)
        if why:
            return None, why
        if bound >= beat:
            return None, f"{mode} cannot beat {beat:.4g} s (its bound {bound:.4g} s)"
    staging, why = _staging(problem, run, mode)
    if why:
        return None, why
    q_s, t_s = run.q, run.t
    if staging is not None:
        q_s = np.asarray(staging.trajectory.q[-1], dtype=float)
        t_s += staging.cycle_time
    ic, consumed, why = _interception(problem, q_s, t_s, target, next_goal, scan, objective)
    if ic is None:
        return None, why
    meetings = intercept(ic)
    run.evaluated += ic.evaluations
    if not meetings:
        return None, f"no meeting possible in {mode} after {t_s:.3f} s"
    run.verified += 1
    v_cart = problem.timing.max_cartesian_speed
    last = ""
    for meeting in meetings[:MAX_VERIFIED]:
        pick = ic.build(meeting, torque=torque, v_cart=v_cart)
        if pick is not None and pick.ok:
            return _Option(mode, pick, ic, staging, consumed), ""
        if pick is not None and pick.report is not None:
            rules = sorted({str(r) for r in pick.report.state_rule if r})
            last = ", ".join(rules) or "the limits"
    return None, f"every meeting tried in {mode} fails its check ({last})"


def _pick_leg(index: int, opt: _Option, t_start: float) -> Leg:
    """The leg of a moving target: its path the approach and the tracking span's ends."""
    pick, asm = opt.pick, opt.ic.checker.assembly_mode
    tr = pick.tracking
    q_meet, q_leave = tr.state(0.0)[0], tr.state(tr.dwell)[0]
    path = PlanPath(np.array([opt.ic.q_s, q_meet, q_leave]), (Segment(opt.mode, asm, 0, 2),))
    t_meet = pick.meeting.t
    plan = PlanResult(PlanStatus.SOLVED, "", path, Diagnostics(0.0))
    point = tuple(float(x) for x in opt.ic.target.at(t_meet)[0])
    speed = float(np.linalg.norm(tr.state(0.0)[1]))
    return Leg(
        index,
        plan,
        opt.mode,
        t_start,
        t_meet,
        2,
        0.0,
        speed,
        (),
        t_meet,
        point,  # type: ignore[arg-type]
    )


def _moving(
    problem: MotionProblem,
    run: _Run,
    index: int,
    target: SequenceTarget,
    next_goal: Goal | None,
    objective: str,
    torque: TorqueModel | None,
    scans: dict,
) -> tuple[SequenceResult | None, bool]:
    """Step 1-3 for moving target ``index``, appended to ``run``; (the failed answer, or
    None; whether the next target was reached by the departure)."""
    goal = target.goal
    assert isinstance(goal, MovingTarget)
    here = posture_mode(problem.design, JointPosture(run.q, problem.start.assembly_mode))
    if goal.working_mode != "any":
        modes = [goal.working_mode]
    elif objective == "fixed" and here is not None:
        modes = [here, *(m for m in WORKING_MODES if m != here)]
    else:
        modes = list(WORKING_MODES)
    # the modes the robot rests in first: no staging leg, and a bound for the others
    modes.sort(key=lambda m: m != here)
    options: list[_Option] = []
    whys = []
    for m in modes:
        if not scans[m][1].windows():
            continue
        beat = min((o.pick.meeting.cost for o in options), default=math.inf)
        opt, why = _option(problem, run, target, next_goal, scans[m], objective, torque, beat)
        if opt is not None:
            options.append(opt)
            if objective == "fixed":
                break
        else:
            whys.append(why)
    if not options:
        windows = {m: s.windows() for m, (_, s) in scans.items() if s.windows()}
        message = (
            f"target {index}: the part is reachable {_windows_text(windows)} (sequence time), "
            f"but no meeting is possible from where the robot rests at {run.t:.3f} s: "
            + "; ".join(whys)
        )
        return SequenceResult(PlanStatus.UNREACHABLE, message, tuple(run.legs)), False
    options.sort(key=lambda o: o.pick.meeting.cost)
    best = options[0]
    t_leave_prev = run.t
    if best.staging is not None:
        run.pieces.append(best.staging.trajectory.curve)
        run.t += best.staging.cycle_time
    pick = best.pick
    run.pieces += [HoldCurve(run.q if best.staging is None else best.ic.q_s, pick.hold)]
    run.pieces += [pick.approach, pick.tracking, pick.departure]
    run.legs.append(_pick_leg(index, best, t_leave_prev))
    run.modes[index] = best.mode
    t_leave = pick.meeting.t + pick.tracking.dwell
    run.t = t_leave + pick.departure.duration
    q_end = pick.departure.evaluate(np.array([pick.departure.duration]))[0][0]
    run.q = np.asarray(q_end if best.ic.landing is None else best.ic.landing, dtype=float)
    note = f"target {index}: met the part at {pick.meeting.t:.4g} s in {best.mode}"
    if len(options) > 1:
        second = options[1]
        note += f" (runner-up {second.mode}: at rest at {second.pick.meeting.cost:.4g} s)"
    run.notes.append(note)
    if best.consumed:
        assert next_goal is not None and best.ic.landing is not None
        path = PlanPath(
            np.array([pick.tracking.state(pick.tracking.dwell)[0], best.ic.landing]),
            (Segment(best.mode, problem.start.assembly_mode, 0, 1),),
        )
        plan = PlanResult(PlanStatus.SOLVED, "", path, Diagnostics(0.0))
        run.legs.append(Leg(index + 1, plan, best.mode, t_leave, run.t, 1, 0.0, 0.0))
        if isinstance(next_goal, CartesianTarget):
            run.modes[index + 1] = best.mode
    return None, best.consumed


def plan_moving_sequence(
    problem: MotionProblem,
    targets: Sequence[SequenceTarget],
    goals: Sequence[Goal],
    cycle: bool,
    objective: str,
    t0: float,
) -> SequenceResult:
    """A sequence holding moving targets (module docstring); ``goals`` has one entry per
    leg (the start again at the end with ``cycle``)."""
    _checked(goals, targets, problem)
    early, scans = _precheck(problem, goals)
    if early is not None:
        return early
    n = len(targets)
    items = [(i, targets[i] if i < n else SequenceTarget(goals[i])) for i in range(len(goals))]
    run = _Run(np.asarray(problem.start.q, dtype=float), 0.0)
    torque = None
    if problem.inertia is not None or problem.limits.torque is not None:
        torque = TorqueModel(
            problem.design, problem.inertia, problem.gravity, problem.start.assembly_mode
        )
    i = 0
    while i < len(goals):
        k = next((j for j in range(i, len(goals)) if isinstance(goals[j], MovingTarget)), None)
        static = items[i : len(goals) if k is None else k]
        if static:
            failed = _static_run(problem, run, static, objective, n)
            if failed is not None:
                return failed
        if k is None:
            break
        next_goal = goals[k + 1] if k + 1 < len(goals) else None
        failed, consumed = _moving(
            problem, run, k, items[k][1], next_goal, objective, torque, scans[k]
        )
        if failed is not None:
            return failed
        i = k + 2 if consumed else k + 1
    trajectory = joined_trajectory(problem, run.pieces, run.static, torque, t0)
    modes = tuple(
        run.modes.get(i, "") if not isinstance(g, JointPosture) else "" for i, g in enumerate(goals)
    )
    legs = len(goals)
    message = "; ".join(
        [
            f"{legs} leg{'s' if legs != 1 else ''}" + (" (a cycle)" if cycle else ""),
            f"cycle time {trajectory.duration:.4g} s",
            *run.notes,
        ]
    )
    diagnostics = SequenceDiagnostics(
        planning_time_s=time.monotonic() - t0 - trajectory.computation_time_s,
        timing_time_s=trajectory.computation_time_s,
        modes=modes,
        estimates=run.verified,
        extra={"notes": tuple(run.notes), "meeting_evaluations": run.evaluated},
    )
    return SequenceResult(
        PlanStatus.SOLVED,
        message,
        tuple(run.legs),
        None,
        trajectory,
        diagnostics=diagnostics,
    )
