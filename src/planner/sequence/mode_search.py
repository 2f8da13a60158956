"""Working modes chosen for time (``objective="time"`` of :func:`planner.sequence.solve_sequence`).

Each Cartesian target in working mode "any" may be reached in several working modes, each
with its own posture; the cycle time depends on the whole assignment (a leg's duration
depends on the modes at both of its ends, and on whether the trajectory stops there). The
search is exact with respect to what it evaluates:

1. **candidates**: per target, the modes whose inverse-kinematics posture is valid (the
   plan's rules: joint limits, margins, obstacles), on both sides of the axis AB (a leg
   into another ``s_axis`` crosses it through a transit with P on the axis, which the
   plan finds; the quickest cycle often does, issue 36); a joint goal, or a target with a
   given mode, has one candidate;
2. **lower bounds**: every leg between two candidate postures gets a bound no motion can
   beat (:func:`leg_lower_bound`): per joint, the least time to cover its displacement
   under its velocity and acceleration limits, from rest and to rest where the trajectory
   stops, at any speed where it passes through (less the blends, which may cut the
   distance); the leg's bound is the largest over the joints, and the sum over the legs
   bounds the cycle time of the assignment from below, transits and obstacles included (a
   detour only adds time);
3. **best first**: the assignments are enumerated in increasing order of their bound (a
   best-first search over targets x modes, the exact remaining bound of the dynamic
   programme as its heuristic, so each completed assignment popped is the next best);
4. **refined by real plans**: each popped assignment is planned and timed for real
   (:class:`~planner.sequence.motion.SequenceMotion` through the pipeline, leg plans shared
   between assignments),
   until the next assignment's bound is no smaller than the best real cycle time found: no
   assignment left can beat it, so the best found is the optimum over every assignment (of
   the cycle times the planner and the timing give). At most :data:`MAX_REFINED` are
   evaluated.

``diagnostics.extra["gap_s"]`` is what the search proves, never more: the best real cycle
time less the least bound it did not beat, over the assignments left when it stopped (the
cap or the deadline) and those whose plan failed without a proof (a longer search might
solve them; a goal proven unreachable or a leg proven to have no path is out for good). 0
means the choice is proven the best; absent without timing (``method`` "none": only bounds
were compared).

At least two solved assignments are evaluated when two exist (within the cap), so that the
runner-up's cycle time is a real one (the message names it; none when no other assignment
was solved).
"""

from __future__ import annotations

import heapq
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from planner.design import Design
from planner.geometry import Obstacle
from planner.kinematics import WORKING_MODES
from planner.motion import MotionProblem, run
from planner.planning import CartesianTarget, JointPosture, PlanStatus, goal_candidates
from planner.planning.single_mode import posture_mode
from planner.sequence.blends import AskedBlend
from planner.sequence.motion import SequenceMotion, solved_message
from planner.sequence.problem import SequenceDiagnostics, SequenceResult, SequenceTarget
from planner.timing.limits import JointLimits
from planner.validity import Margins, ValidityChecker

__all__ = ["MAX_REFINED", "Candidate", "assignment_bounds", "choose_modes", "leg_lower_bound"]

#: Most assignments planned and timed for real by the search.
MAX_REFINED = 8


@dataclass(frozen=True, slots=True)
class Candidate:
    """One way to reach a target: its ``goal`` (with the mode settled), the ``mode`` label
    and the posture ``q`` (rad) the bounds use."""

    goal: JointPosture | CartesianTarget
    mode: str
    q: np.ndarray


def _joint_time(d: np.ndarray, v: np.ndarray, a: np.ndarray, rests: int) -> np.ndarray:
    """Least time per joint to move ``d`` (>= 0, rad) under ``v``, ``a``: ``rests`` = 2 from
    rest to rest (a trapezoid or a triangle), 1 from rest to any speed (or back), 0 at any
    speed (``d / v``)."""
    if rests == 0:
        return d / v
    if rests == 1:
        ramp = v**2 / (2 * a)
        return np.where(d >= ramp, d / v + v / (2 * a), np.sqrt(2 * d / a))
    ramp = v**2 / a
    return np.where(d >= ramp, d / v + v / a, 2 * np.sqrt(d / a))


def leg_lower_bound(
    q_a: np.ndarray,
    q_b: np.ndarray,
    limits: JointLimits,
    *,
    stop_a: bool,
    stop_b: bool,
    slack: float = 0.0,
) -> float:
    """A time no motion from posture ``q_a`` to ``q_b`` can beat, s: per joint, the least
    time to cover its displacement (less ``slack`` rad: the blends at the two ends may cut
    it) at rest at each end that stops, under the joint's velocity and acceleration limits;
    the largest over the joints."""
    d = np.maximum(np.abs(np.asarray(q_b) - np.asarray(q_a)) - slack, 0.0)
    t = _joint_time(d, limits.velocity_array, limits.acceleration_array, int(stop_a) + int(stop_b))
    return float(np.max(t))


def _candidates(
    design: Design,
    start: JointPosture,
    goal: JointPosture | CartesianTarget,
    margins: Margins,
    obstacles: Sequence[Obstacle],
) -> list[Candidate]:
    """Step 1: the ways to reach one target (see the module docstring)."""
    if isinstance(goal, JointPosture):
        return [Candidate(goal, posture_mode(design, goal) or "", np.asarray(goal.q))]
    if goal.working_mode != "any":
        modes = [goal.working_mode]
    else:
        modes = list(WORKING_MODES)
    out = []
    for mode in modes:
        checker = ValidityChecker(design, margins, obstacles, start.assembly_mode, mode)
        cands, _ = goal_candidates(design, CartesianTarget(goal.p, mode), checker, start.q)
        if len(cands):
            out.append(Candidate(CartesianTarget(goal.p, mode), mode, cands[0]))
    if not out and goal.working_mode == "any":  # let the plan say why: unreachable
        out.append(Candidate(goal, "any", np.full(3, np.nan)))
    return out


def _largest_blend(
    problem: MotionProblem, target: SequenceTarget, layer: Sequence[Candidate], index: int
) -> float:
    """How far (rad) the trajectory may pass from a pass-through target, for the bounds: its
    blend as asked (before any shrinking, which only lengthens a motion: the bound stays a
    lower bound) plus the corner allowance; a blend in metres at the largest joint radius
    it means over the target's candidate postures."""
    asm = problem.start.assembly_mode
    radii = [
        AskedBlend.of(problem.design, index, target, c.q, asm).rad
        for c in layer
        if np.all(np.isfinite(c.q))
    ]
    return max(radii, default=target.blend) + problem.timing.max_deviation


def assignment_bounds(
    start_q: np.ndarray,
    layers: Sequence[Sequence[Candidate]],
    stops: Sequence[bool],
    blends: Sequence[float],
    limits: JointLimits,
):
    """Step 2 and 3: the assignments (one candidate index per target) in increasing order
    of their lower bound, as a generator of (bound, assignment).

    ``blends[i]``: the distance the trajectory may pass from target i (0 at a stop). The
    heuristic ``h[i][m]`` is the exact least bound from target i in candidate m to the end
    (dynamic programming backwards), so the best-first search pops complete assignments in
    order of their bound."""
    n = len(layers)

    def leg(i: int, a: int | None, b: int) -> float:
        qa = start_q if i == 0 else layers[i - 1][a].q  # type: ignore[index]
        qb = layers[i][b].q
        if np.any(~np.isfinite(qb)) or np.any(~np.isfinite(qa)):
            return 0.0  # an unreachable target: the real plan will say so
        stop_a = True if i == 0 else stops[i - 1]
        slack = (blends[i - 1] if i > 0 else 0.0) + blends[i]
        return leg_lower_bound(qa, qb, limits, stop_a=stop_a, stop_b=stops[i], slack=slack)

    h = [np.zeros(len(layer)) for layer in layers]
    for i in range(n - 2, -1, -1):
        for a in range(len(layers[i])):
            h[i][a] = min(leg(i + 1, a, b) + h[i + 1][b] for b in range(len(layers[i + 1])))
    heap: list[tuple[float, float, tuple[int, ...]]] = []
    for b in range(len(layers[0])):
        g = leg(0, None, b)
        heapq.heappush(heap, (g + h[0][b], g, (b,)))
    while heap:
        f, g, prefix = heapq.heappop(heap)
        i = len(prefix)
        if i == n:
            yield f, prefix
            continue
        for b in range(len(layers[i])):
            g2 = g + leg(i, prefix[-1], b)
            heapq.heappush(heap, (g2 + h[i][b], g2, (*prefix, b)))


def _proven_out(result: SequenceResult) -> bool:
    """Whether a failed assignment can never be solved: a leg's goal unreachable or
    invalid, or a leg proven to have no path. A budget that ran out proves nothing, nor does
    a timing that failed (another path of the same modes might be timed)."""
    if result.status in (PlanStatus.UNREACHABLE, PlanStatus.INVALID_GOAL, PlanStatus.INVALID_START):
        return True
    return any(leg.plan.diagnostics.proven_infeasible for leg in result.legs)


def choose_modes(
    problem: MotionProblem,
    targets: Sequence[SequenceTarget],
    goals: Sequence[JointPosture | CartesianTarget],
    stops: Sequence[bool],
    cycle: bool,
    t0: float,
) -> SequenceResult:
    """The sequence with each "any" target's working mode chosen for the shortest cycle
    (module docstring); its message names the modes chosen and the runner-up's cycle time,
    ``diagnostics.estimates`` counts the assignments evaluated, ``diagnostics.extra`` holds
    ``gap_s`` (0 when the optimum is proven) and ``bound_s`` (the best assignment's bound)."""
    start, timing, limits = problem.start, problem.timing, problem.limits
    deadline = problem.budget.deadline
    layers = [
        _candidates(problem.design, start, g, problem.margins, problem.obstacles) for g in goals
    ]
    n = len(targets)

    def motion(chosen: Sequence[JointPosture | CartesianTarget]) -> SequenceMotion:
        return SequenceMotion(tuple(targets), tuple(chosen), tuple(stops), cycle, t0, cache)

    cache: dict = {}
    if not all(layers):
        # a target with no candidate in its own working mode (unreachable there, or invalid):
        # no assignment exists; the targets as given say which and why
        return run(problem, motion(goals))
    blends = [
        0.0 if stops[i] or i >= n else _largest_blend(problem, targets[i], layers[i], i)
        for i in range(len(goals))
    ]
    attempts = 0
    evaluated: list[tuple[float, tuple[str, ...], SequenceResult]] = []
    first_bound = math.nan
    # the least bound of the assignments not evaluated (inf: none left), and the bounds of
    # those whose plan failed without a proof (a longer search might still solve them)
    rest, unproven = math.inf, []
    late = False
    for bound, assignment in assignment_bounds(np.asarray(start.q), layers, stops, blends, limits):
        if math.isnan(first_bound):
            first_bound = bound
        best = min((e[0] for e in evaluated), default=math.inf)
        solved = sum(math.isfinite(e[0]) for e in evaluated)
        if solved >= 2 and bound >= best:
            rest = bound  # no assignment left can beat the best
            break
        attempts += 1
        over = len(evaluated) >= MAX_REFINED or attempts > 4 * MAX_REFINED
        late = deadline is not None and time.monotonic() > deadline
        if over or late:
            rest = bound
            break
        chosen = [layers[i][m] for i, m in enumerate(assignment)]
        result = run(problem, motion([c.goal for c in chosen]))
        cost = result.cycle_time if result.solved else math.inf
        if timing.method == "none" and result.status is PlanStatus.SOLVED:
            cost = bound  # no timing asked: the bound is all there is to compare
        if not result.solved and not _proven_out(result):
            unproven.append(bound)
        evaluated.append((cost, tuple(c.mode for c in chosen), result))
    if not evaluated:  # the budget ran out before any assignment was planned
        return SequenceResult(
            PlanStatus.TIMEOUT,
            "the deadline passed before any working-mode assignment of the targets was "
            f"planned ({attempts - 1} tried)",
            (),
            diagnostics=SequenceDiagnostics(planning_time_s=time.monotonic() - t0),
        )
    evaluated.sort(key=lambda e: e[0])
    cost, modes, result = evaluated[0]
    if not math.isfinite(cost):  # every assignment failed: the first one's answer says why
        return result

    def shown_modes(labels: tuple[str, ...]) -> tuple[str, ...]:
        # the modes of the Cartesian targets (a joint goal's is its own)
        return tuple(
            m if isinstance(g, CartesianTarget) else "" for m, g in zip(labels, goals, strict=True)
        )

    runner = next(((shown_modes(e[1]), e[0]) for e in evaluated[1:] if math.isfinite(e[0])), None)
    extra = {"runner_up": runner, "estimates": len(evaluated)}
    shown = shown_modes(modes)
    # what the search proves: no assignment's cycle (as planned and timed) is shorter than
    # the least of the bounds it did not beat; without timing it compared bounds only
    proven = {} if timing.method == "none" else {"gap_s": max(cost - min([rest, *unproven]), 0.0)}
    diagnostics = replace(
        result.diagnostics,
        planning_time_s=time.monotonic() - t0 - result.diagnostics.timing_time_s,
        modes=shown,
        runner_up=runner,
        estimates=len(evaluated),
        extra={**result.diagnostics.extra, **proven, "bound_s": first_bound},
    )
    duration = result.cycle_time if result.trajectory is not None else None
    turning = result.diagnostics.extra.get("turning", ())
    rested = result.diagnostics.extra.get("rested", ())
    by_timing = [
        i for i in result.diagnostics.stopped_targets if i not in turning and i not in rested
    ]
    uses = result.diagnostics.blends
    notes = result.diagnostics.extra.get("notes", ())
    message = solved_message(n, cycle, shown, extra, duration, by_timing, turning, uses, notes)
    return replace(result, message=message, diagnostics=diagnostics)
