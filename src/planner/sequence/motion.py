"""The sequence kind of :mod:`planner.motion` (:class:`SequenceMotion`): steps 3-6 of a
sequence (:mod:`planner.sequence.solve`) for goals whose working modes are settled.

Its planning step plans every leg as a single plan is (the goal kind's planning step,
:meth:`planner.solver.GoalMotion.plan`, timing off: a leg is not timed alone) and joins the
legs (:mod:`planner.sequence.joining`); its answer reads each leg's times from the one
trajectory (:mod:`planner.sequence.leg_times`). The pipeline does the rest.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from planner.motion import MotionProblem, Planned, Timed, path_timing, run
from planner.planning import CartesianTarget, JointPosture, PlanPath, PlanResult, PlanStatus
from planner.sequence.blends import AskedBlend, blend_uses, fit_blends, shrink_message
from planner.sequence.joining import EXACT_CORRIDOR, join_legs, smooth_pass_through, turning_back
from planner.sequence.leg_times import SAMPLING_SLACK, leg_times, transit_times
from planner.sequence.problem import (
    BlendUse,
    Leg,
    SequenceDiagnostics,
    SequenceResult,
    SequenceTarget,
)
from planner.solver import GoalMotion
from planner.timing.options import TimingOptions

__all__ = ["EXACT_PASS_TOL", "SequenceMotion", "leg_name", "solved_message"]

#: How close (rad) a trajectory must come to an exact pass-through target's posture to have
#: passed it exactly: the via states are the posture itself, and locating the instant of
#: closest approach (:mod:`planner.sequence.leg_times`) reads it to about 1e-8.
EXACT_PASS_TOL = 1e-6


def leg_name(index: int, n_targets: int) -> str:
    """How a message names leg ``index``: "target 3", or the cycle's return to the start."""
    return "the return to the start" if index == n_targets else f"target {index}"


def _plan_legs(
    problem: MotionProblem,
    goals: Sequence[JointPosture | CartesianTarget],
    cache: dict[tuple[Any, ...], PlanResult],
) -> tuple[list[PlanResult], int | None]:
    """Step 3: each leg planned as a single plan is (the planning step of
    :class:`planner.solver.GoalMotion`) from the previous arrival posture; stops at the first
    leg that fails and returns its index (else None). ``cache``: plans already made, by
    (leg, start posture, goal)."""
    plans: list[PlanResult] = []
    untimed = TimingOptions(method="none")
    q = np.asarray(problem.start.q, dtype=float)
    asm = problem.start.assembly_mode
    for i, goal in enumerate(goals):
        key = (i, q.tobytes(), _goal_key(goal))
        result = cache.get(key)
        if result is None:
            leg = problem.with_(start=JointPosture(q, asm), timing=untimed)
            planned = GoalMotion(goal).plan(leg)  # the leg's planning step: not timed alone
            assert planned.detail is not None
            result = planned.detail
            cache[key] = result
        plans.append(result)
        if not result.solved or result.path is None:
            return plans, i
        q = np.asarray(result.path.waypoints[-1], dtype=float)
    return plans, None


def _goal_key(goal: JointPosture | CartesianTarget) -> tuple:
    if isinstance(goal, JointPosture):
        return ("q", goal.q.tobytes(), goal.assembly_mode)
    return ("p", goal.p.tobytes(), goal.working_mode)


def _arrival_mode(path: PlanPath | None) -> str:
    """The working mode a leg arrives in; "" without a path or segments."""
    return path.segments[-1].working_mode if path is not None and path.segments else ""


@dataclass(frozen=True, slots=True)
class _Joined:
    """The planning step's detail: the legs' plans and, once every leg is solved, the joined
    path and where each target lies on it (steps 3-4)."""

    plans: tuple[PlanResult, ...]
    planning_time_s: float
    modes: tuple[str, ...]
    failed: int | None = None
    path: PlanPath | None = None
    at: tuple[int, ...] = ()
    stops: tuple[bool, ...] = ()
    exact: tuple[bool, ...] = ()
    turning: tuple[int, ...] = ()
    blends: tuple[float, ...] = ()  # the joint-space blend used at each target (0: stop, exact)
    asked: tuple[AskedBlend | None, ...] = ()


@dataclass(frozen=True, slots=True, eq=False)
class SequenceMotion:
    """Steps 3-6 for goals whose working modes are settled (the targets' own, or an
    assignment of :mod:`planner.sequence.mode_search`), a :class:`planner.motion.Motion`
    whose answer is a :class:`~planner.sequence.SequenceResult`.

    ``goals`` and ``stops`` have one entry per leg (the return to the start included with
    ``cycle``); ``t0`` is when the sequence's work began (:func:`time.monotonic`);
    ``plan_cache`` holds the leg plans already made (shared between the assignments of a
    mode search); ``extra`` the mode search's diagnostics (``runner_up``, ``estimates``).
    With ``compare_stops``, a sequence passing targets exactly (blend 0) is timed again with
    those targets as stops, and the quicker is the answer (:func:`_quicker_with_stops`); and
    one passing targets within their blends is timed again passing them exactly
    (``blends_off``: every blend 0), the quicker the answer (:func:`_quicker_exactly`): a
    trajectory through the target is within any blend of it, so a larger blend is never
    slower."""

    targets: tuple[SequenceTarget, ...]
    goals: tuple[JointPosture | CartesianTarget, ...]
    stops: tuple[bool, ...]
    cycle: bool
    t0: float
    plan_cache: dict[tuple[Any, ...], PlanResult] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)
    compare_stops: bool = True
    blends_off: bool = False
    exact_vias: bool = False

    def plan(self, problem: MotionProblem) -> Planned[_Joined]:
        """Steps 3-4: the legs planned and joined, the blends shrunk to fit their legs
        (:mod:`planner.sequence.blends`), the corner allowances and the stops of the one
        timing."""
        n = len(self.targets)
        plans, failed = _plan_legs(problem, self.goals, self.plan_cache)
        planning_time = time.monotonic() - self.t0
        modes = tuple(
            _arrival_mode(p.path) if p.path is not None and isinstance(g, CartesianTarget) else ""
            for p, g in zip(plans, self.goals, strict=False)
        )
        if failed is not None:
            bad = plans[failed]
            message = f"{leg_name(failed, n)}: {bad.message}"
            return Planned(bad.status, message, _Joined(tuple(plans), planning_time, modes, failed))
        joined, at = join_legs(np.asarray(problem.start.q, dtype=float), plans)
        wanted = [not s for s in self.stops]  # the pass-through targets asked for
        turning = turning_back(np.asarray(joined.waypoints), at, wanted)
        stops = list(self.stops)
        for i in turning:
            stops[i] = True
        w = np.asarray(joined.waypoints)
        asm = problem.start.assembly_mode
        asked = [
            AskedBlend.of(problem.design, i, self.targets[i], w[at[i]], asm, off=self.blends_off)
            if not stops[i] and i < n
            else None
            for i in range(len(at))
        ]
        used = fit_blends(w, at, asked)
        exact = [not s and u == 0.0 for s, u in zip(stops, used, strict=True)]
        if not self.exact_vias:
            joined, at = smooth_pass_through(joined, at, exact)
        deviation = np.full(len(joined.waypoints), problem.timing.max_deviation)
        radius = deviation.copy()
        for i, k in enumerate(at):
            if not stops[i] and not exact[i]:
                deviation[k] = radius[k] = used[i]
            elif exact[i] and self.exact_vias:  # through the posture itself, at speed
                deviation[k], radius[k] = EXACT_CORRIDOR, 0.0
        stop_at = [k for i, k in enumerate(at) if stops[i]]
        via_at = [k for i, k in enumerate(at) if not stops[i] and (self.exact_vias or not exact[i])]
        timing = path_timing(
            problem,
            joined,
            max_deviation=deviation,
            stop_at=stop_at,
            via_at=via_at,
            via_radius=radius,
        )
        detail = _Joined(
            tuple(plans),
            planning_time,
            modes,
            None,
            joined,
            tuple(at),
            tuple(stops),
            tuple(exact),
            tuple(turning),
            tuple(used),
            tuple(asked),
        )
        return Planned(PlanStatus.SOLVED, "", detail, timing)

    def answer(
        self, problem: MotionProblem, planned: Planned[_Joined], timed: Timed
    ) -> SequenceResult:
        """Step 6 and the answer: each leg's time span read from the trajectory; a timing
        failure is ``no_path`` (``timeout`` when the deadline passed), the legs kept."""
        joined = planned.detail
        if joined is None:  # stopped before planning (gravity at the start, the deadline)
            diagnostics = SequenceDiagnostics(planning_time_s=time.monotonic() - self.t0)
            return SequenceResult(planned.status, planned.message, (), diagnostics=diagnostics)
        diagnostics = SequenceDiagnostics(
            planning_time_s=joined.planning_time_s,
            modes=joined.modes,
            runner_up=self.extra.get("runner_up"),
            estimates=self.extra.get("estimates", 0),
        )
        if joined.failed is not None or joined.path is None:
            legs = tuple(Leg(i, p, _arrival_mode(p.path)) for i, p in enumerate(joined.plans))
            return SequenceResult(planned.status, planned.message, legs, diagnostics=diagnostics)
        n = len(self.targets)
        untimed_legs = tuple(
            Leg(i, p, _arrival_mode(p.path), waypoint_index=k)
            for i, (p, k) in enumerate(zip(joined.plans, joined.at, strict=True))
        )
        if timed.trajectory is None and timed.error is None:  # no timing asked
            message = solved_message(n, self.cycle, joined.modes, self.extra)
            return SequenceResult(
                PlanStatus.SOLVED, message, untimed_legs, joined.path, diagnostics=diagnostics
            )
        if timed.error is not None:
            status = PlanStatus.TIMEOUT if timed.late else PlanStatus.NO_PATH
            return SequenceResult(
                status,
                f"the legs were planned but could not be timed: {timed.error}",
                untimed_legs,
                joined.path,
                timing_error=timed.error,
                diagnostics=diagnostics,
            )
        result = self._timed_answer(problem, joined, timed, diagnostics)
        if not self.compare_stops:
            return result
        blended = [i for i, u in enumerate(joined.blends) if u > 0.0]
        if blended:  # every blend off (that answer compares its own exact passes)
            exactly = run(problem, replace(self, blends_off=True))
            result = _quicker_exactly(result, exactly, blended)
        exact_at = [i for i, e in enumerate(joined.exact) if e]
        if not exact_at:
            return result
        if not self.exact_vias:  # the exact passes as via states, the blends kept
            vias = run(problem, replace(self, exact_vias=True, compare_stops=False))
            result = _quicker_through_vias(result, vias, exact_at)
        stops = tuple(s or e for s, e in zip(joined.stops, joined.exact, strict=True))
        stopped = run(problem, replace(self, stops=stops, compare_stops=False))
        return _quicker_with_stops(result, stopped, exact_at)

    def _timed_answer(
        self,
        problem: MotionProblem,
        joined: _Joined,
        timed: Timed,
        diagnostics: SequenceDiagnostics,
    ) -> SequenceResult:
        """The solved answer: the legs with their times and transit crossings, the targets
        where the timing came to rest although passing was asked."""
        trajectory = timed.trajectory
        assert trajectory is not None and joined.path is not None
        n, at, stops = len(self.targets), list(joined.at), list(joined.stops)
        passes = [not s for s in stops]
        w = np.asarray(joined.path.waypoints, dtype=float)
        deviation = problem.timing.max_deviation
        reach = [(0.0 if stops[i] else joined.blends[i]) + deviation + 0.01 for i in range(len(at))]
        close = [(0.0 if stops[i] else joined.blends[i]) + SAMPLING_SLACK for i in range(len(at))]
        times = leg_times(trajectory, w, at, stops, reach, close)
        legs = []
        for i, (p, k) in enumerate(zip(joined.plans, at, strict=True)):
            begin = 0.0 if i == 0 else times[i - 1][0]
            t_k, dist, speed = times[i]
            assert p.path is not None
            crossings = transit_times(trajectory.curve, p.path, begin, t_k)
            legs.append(Leg(i, p, _arrival_mode(p.path), begin, t_k, k, dist, speed, crossings))
        by_timing = tuple(i for i, (_, _, v) in enumerate(times) if passes[i] and v <= 1e-9)
        turning = joined.turning
        uses = blend_uses(joined.asked, joined.blends)
        diagnostics = replace(
            diagnostics,
            timing_time_s=trajectory.computation_time_s,
            stopped_targets=tuple(sorted({*turning, *by_timing})),
            blends=uses,
            extra={"turning": tuple(turning)},
        )
        shown = () if self.blends_off else uses  # off: not shrunk, set aside (the caller says)
        message = solved_message(
            n, self.cycle, joined.modes, self.extra, trajectory.duration, by_timing, turning, shown
        )
        return SequenceResult(
            PlanStatus.SOLVED,
            message,
            tuple(legs),
            joined.path,
            trajectory,
            diagnostics=diagnostics,
        )


def _with_note(
    result: SequenceResult, note: str, rested: Sequence[int] = (), **diagnostics: Any
) -> SequenceResult:
    """``result`` with ``note`` added to its message and to ``diagnostics.extra["notes"]``
    (which the mode search's message keeps), ``rested`` to ``extra["rested"]`` (targets at
    rest because that was quicker, not because the timing had to), and ``diagnostics``
    fields replaced."""
    d = result.diagnostics
    extra = {
        **d.extra,
        "notes": (*d.extra.get("notes", ()), note),
        "rested": (*d.extra.get("rested", ()), *rested),
    }
    return replace(
        result,
        message=f"{result.message}; {note}",
        diagnostics=replace(d, extra=extra, **diagnostics),
    )


def _quicker_through_vias(
    smooth: SequenceResult, vias: SequenceResult, exact_at: list[int]
) -> SequenceResult:
    """The quicker of a sequence passing its exact targets (blend 0) on the straight pieces
    around them and the same one passing them as via states with the target's own posture
    and a free velocity (the moves within :data:`EXACT_CORRIDOR` of the plan). The via
    variant counts only where it did pass every such target exactly: where a chain was not
    kept (slower, or dropped by the re-check), its blended path rounds the corner within
    the corridor instead, which blend 0 does not allow."""
    if not (vias.solved and vias.cycle_time < smooth.cycle_time):
        return smooth
    passes = [vias.legs[i].pass_distance for i in exact_at]
    if any(not d <= EXACT_PASS_TOL for d in passes):
        return smooth
    return vias


def _quicker_exactly(
    blended: SequenceResult, exactly: SequenceResult, blended_at: list[int]
) -> SequenceResult:
    """The quicker of a sequence passing the targets ``blended_at`` within their blends and
    the same one passing them exactly (or at rest, whichever of those was quicker): the
    via states are kept within the blend of the planned segments, so a small blend can
    forbid the deviation that saves time while the exact pass runs straight through at
    speed (a 5 mm blend_radius was 0.3 % slower than passing exactly on examples/06's
    cycle). Where that wins, the message says so; diagnostics.blends keep what was asked,
    with ``used`` 0."""
    if not (exactly.solved and exactly.cycle_time < blended.cycle_time):
        return blended
    uses = tuple(replace(u, used=0.0) for u in blended.diagnostics.blends)
    note = (
        "blends not used at "
        + ", ".join(f"target {i}" for i in blended_at)
        + f" (passing exactly, or at rest, was quicker than within them: "
        f"{blended.cycle_time:.4g} s)"
    )
    return _with_note(exactly, note, blends=uses)


def _quicker_with_stops(
    passing: SequenceResult, stopped: SequenceResult, exact_at: list[int]
) -> SequenceResult:
    """The quicker of a sequence passing the targets ``exact_at`` exactly (blend 0) and the
    same one at rest there: passing a corner exactly makes the path run straight through it
    at speed, which can cost more than braking to it and starting again (slower in 4 of 16
    cycles, by up to 3.7 %, issue 36). Where stopping wins, those targets are listed in
    ``stopped_targets`` and the message says why."""
    if not (stopped.solved and stopped.cycle_time < passing.cycle_time):
        return passing
    at_rest = sorted({*passing.diagnostics.stopped_targets, *exact_at})
    note = (
        "at rest at pass-through "
        + ", ".join(f"target {i}" for i in exact_at)
        + f" (quicker than passing exactly with blend 0: {passing.cycle_time:.4g} s)"
    )
    return _with_note(stopped, note, exact_at, stopped_targets=tuple(at_rest))


def solved_message(
    n: int,
    cycle: bool,
    modes: Sequence[str],
    extra: dict,
    duration: float | None = None,
    stopped: Sequence[int] = (),
    turning: Sequence[int] = (),
    blends: Sequence[BlendUse] = (),
    notes: Sequence[str] = (),
) -> str:
    """The message of a solved sequence: its legs, its cycle time, the modes chosen for
    time and the runner-up, any pass-through target the timing had to stop at, the
    blends that shrank to fit, and ``notes`` (what a comparison of variants chose)."""
    legs = n + cycle
    parts = [f"{legs} leg{'s' if legs != 1 else ''}" + (" (a cycle)" if cycle else "")]
    if duration is not None:
        parts.append(f"cycle time {duration:.4g} s")
    runner = extra.get("runner_up")
    if "estimates" in extra:
        chosen = ", ".join(f"target {i}: {m}" for i, m in enumerate(modes) if m)
        text = f"working modes chosen for time: {chosen}"
        if runner is not None:
            text += f"; runner-up {' '.join(m for m in runner[0] if m)} at {runner[1]:.4g} s"
        parts.append(text)
    if turning:
        parts.append(
            "at rest at pass-through "
            + ", ".join(f"target {i}" for i in turning)
            + " (the path turns back there, or does not move)"
        )
    if stopped:
        parts.append(
            "the timing came to rest at pass-through "
            + ", ".join(f"target {i}" for i in stopped)
            + " (its blend could not be kept valid)"
        )
    shrunk = shrink_message(blends)
    if shrunk:
        parts.append(shrunk)
    parts.extend(notes)
    return "; ".join(parts)
