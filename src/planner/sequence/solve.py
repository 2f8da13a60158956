"""Task sequences: :func:`solve_sequence`, one trajectory through many targets.

A robot cell runs a cycle (pick, lift, move, place, return), and its figure of merit is the
cycle time. The steps, each a function here:

1. the targets checked (:func:`_checked_targets`: at least one, at most
   :data:`~planner.sequence.problem.MAX_SEQUENCE_TARGETS`, each blend >= 0);
2. with ``objective="time"``, each Cartesian target in working mode "any" gets the mode
   that makes the whole cycle shortest (:func:`planner.sequence.mode_search.choose_modes`);
3. every leg planned in turn from the previous arrival posture by :func:`planner.solve`
   (the plan with its validity rules, obstacles and margins; timing off), so a leg is
   planned exactly as a single plan is (:func:`_plan_legs`); the first leg that fails
   gives the sequence its status, its index in the message;
4. the legs joined into one path (:func:`_join_legs`), each blend checked against its legs
   (at most half the shorter adjacent leg), an exact pass-through (blend 0) made smooth by
   two short straight pieces around the target (:func:`_smooth_pass_through`);
5. the joined path timed once by :func:`planner.solver.time_plan`, the timing step of
   :func:`planner.solve` (the same limits, the path's own rules re-checked densely, the
   stops at rest and the pass-through targets passed within their ``blend``: as free via
   states, ``via_at``, where a stretch between stops holds only pass-throughs, else on
   arcs, :mod:`planner.timing.vias`): one
   trajectory, one time axis, strictly increasing, no stamp repeated between legs;
6. each leg's time span read from the trajectory (:func:`_leg_times`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from planner.design import Design
from planner.dynamics import DEFAULT_GRAVITY, Inertia
from planner.exceptions import InputError, TimingDeadlineError, TimingError
from planner.geometry import Obstacle
from planner.planning import (
    CartesianTarget,
    JointPosture,
    PlanOptions,
    PlanPath,
    PlanResult,
    PlanStatus,
    Segment,
    Transit,
)
from planner.sequence.problem import (
    MAX_SEQUENCE_TARGETS,
    OBJECTIVES,
    Leg,
    SequenceDiagnostics,
    SequenceResult,
    SequenceTarget,
)
from planner.solver import solve, time_plan
from planner.timing.limits import JointLimits
from planner.timing.options import TimingOptions
from planner.validity import Margins

__all__ = ["PASS_OFFSET", "leg_name", "solve_sequence", "solve_with_goals"]

#: An exact pass-through (blend 0) at a corner: the path runs straight through the target
#: over this distance on either side (rad; at most a quarter of the adjacent segments), and
#: the two new corners there are blended as any other.
PASS_OFFSET = 0.05
#: How much farther than its ball a sampled closest approach may seem (rad): half the
#: 0.01 rad spacing of the samples :func:`_leg_times` reads, and a little.
_SAMPLING_SLACK = 0.006
#: A corner turning by more than pi minus this (rad) cannot be passed at speed: the target
#: is a stop (the timing could not blend it either).
_REVERSAL = 1e-3


def leg_name(index: int, n_targets: int) -> str:
    """How a message names leg ``index``: "target 3", or the cycle's return to the start."""
    return "the return to the start" if index == n_targets else f"target {index}"


def _checked_targets(targets: Sequence[SequenceTarget]) -> list[SequenceTarget]:
    """Step 1: at least one target, at most :data:`MAX_SEQUENCE_TARGETS`, each a
    :class:`SequenceTarget` (its own checks: goal, blend >= 0)."""
    targets = list(targets)
    if not targets:
        raise InputError("targets must hold at least one target", field="targets")
    if len(targets) > MAX_SEQUENCE_TARGETS:
        raise InputError(
            f"at most {MAX_SEQUENCE_TARGETS} targets per sequence, got {len(targets)}",
            field="targets",
        )
    for i, t in enumerate(targets):
        if not isinstance(t, SequenceTarget):
            raise InputError(
                f"targets[{i}] must be a SequenceTarget, got {t!r}", field=("targets", i)
            )
    return targets


def _plan_legs(
    design: Design,
    start: JointPosture,
    goals: Sequence[JointPosture | CartesianTarget],
    *,
    obstacles: Sequence[Obstacle],
    margins: Margins,
    options: PlanOptions,
    deadline: float | None,
    cache: dict | None = None,
) -> tuple[list[PlanResult], int | None]:
    """Step 3: each leg planned by :func:`planner.solve` (timing off) from the previous
    arrival posture; stops at the first leg that fails and returns its index (else None).
    ``cache``: plans already made, by (leg, start posture, goal)."""
    plans: list[PlanResult] = []
    q = np.asarray(start.q, dtype=float)
    for i, goal in enumerate(goals):
        key = (i, q.tobytes(), _goal_key(goal))
        result = cache.get(key) if cache is not None else None
        if result is None:
            result = solve(
                design,
                JointPosture(q, start.assembly_mode),
                goal,
                obstacles=obstacles,
                margins=margins,
                options=options,
                timing=TimingOptions(method="none"),
                deadline=deadline,
            ).plan
            if cache is not None:
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


def _arrival_mode(path: PlanPath) -> str:
    return path.segments[-1].working_mode if path.segments else ""


def _join_legs(start_q: np.ndarray, plans: Sequence[PlanResult]) -> tuple[PlanPath, list[int]]:
    """Step 4: the legs' paths as one path (segments of one working mode merged across a
    target, transits shifted), and each target's waypoint index in it."""
    w = [np.asarray(start_q, dtype=float)]
    segs: list[Segment] = []
    transits: list[Transit] = []
    at: list[int] = []
    for plan in plans:
        path = plan.path
        assert path is not None
        off = len(w) - 1
        w.extend(np.asarray(path.waypoints, dtype=float)[1:])
        for s in path.segments:
            s = replace(s, start_index=s.start_index + off, end_index=s.end_index + off)
            last = segs[-1] if segs else None
            if (
                last is not None
                and last.working_mode == s.working_mode
                and last.end_index == s.start_index
            ):
                segs[-1] = replace(last, end_index=s.end_index)
            else:
                segs.append(s)
        transits += [replace(t, index=t.index + off) for t in path.transits]
        at.append(len(w) - 1)
    return PlanPath(np.array(w), tuple(segs), tuple(transits)), at


def _leg_length(w: np.ndarray, a: int, b: int) -> float:
    return float(np.sum(np.linalg.norm(np.diff(w[a : b + 1], axis=0), axis=1)))


def _check_blends(
    w: np.ndarray, at: list[int], passes: list[bool], targets: Sequence[SequenceTarget]
) -> None:
    """A pass-through target's blend is at most half the shorter of its two legs (the
    corner's blend may take at most half of either side): else an
    :class:`~planner.exceptions.InputError` at ``targets[i].blend``."""
    for i, passing in enumerate(passes):
        if not passing or i >= len(targets):
            continue
        before = _leg_length(w, at[i - 1] if i > 0 else 0, at[i])
        after = _leg_length(w, at[i], at[i + 1])
        limit = 0.5 * min(before, after)
        if targets[i].blend > limit:
            raise InputError(
                f"targets[{i}].blend = {targets[i].blend:g} rad is larger than half the "
                f"shorter adjacent leg ({limit:.4g} rad)",
                field=("targets", i, "blend"),
            )


def _turning_back(w: np.ndarray, at: list[int], passes: list[bool]) -> list[int]:
    """The pass-through targets that cannot be passed at speed: the path turns back there
    (a corner within :data:`_REVERSAL` of pi) or does not move on either side (a leg of
    zero length). They are stops."""
    out = []
    for i, k in enumerate(at):
        if not passes[i]:
            continue
        if k <= 0 or k >= len(w) - 1:
            out.append(i)
            continue
        d_in, d_out = w[k] - w[k - 1], w[k + 1] - w[k]
        l_in, l_out = float(np.linalg.norm(d_in)), float(np.linalg.norm(d_out))
        if l_in == 0.0 or l_out == 0.0:
            out.append(i)
            continue
        cos = float(np.clip(d_in @ d_out / (l_in * l_out), -1.0, 1.0))
        if math.acos(cos) > math.pi - _REVERSAL:
            out.append(i)
    return out


def _smooth_pass_through(
    path: PlanPath, at: list[int], exact: list[bool]
) -> tuple[PlanPath, list[int]]:
    """An exact pass-through target (blend 0) at a corner: the waypoints
    ``T - e b`` and ``T + e b`` inserted around it (``b`` the corner's bisecting direction,
    ``e`` = :data:`PASS_OFFSET` or a quarter of the shorter segment), so the path runs
    straight through T and the trajectory passes it exactly, at speed (a target where the
    path turns back is a stop already, :func:`_turning_back`). Returns the new path and the
    targets' new waypoint indices."""
    w = np.asarray(path.waypoints, dtype=float)
    insert: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for i, k in enumerate(at):
        if not exact[i] or k <= 0 or k >= len(w) - 1:
            continue
        d_in, d_out = w[k] - w[k - 1], w[k + 1] - w[k]
        l_in, l_out = float(np.linalg.norm(d_in)), float(np.linalg.norm(d_out))
        if l_in == 0.0 or l_out == 0.0:
            continue
        u1, u2 = d_in / l_in, d_out / l_out
        angle = math.acos(float(np.clip(u1 @ u2, -1.0, 1.0)))
        if angle < 1e-9 or angle > math.pi - _REVERSAL:
            continue  # straight already, or a stop
        b = (u1 + u2) / np.linalg.norm(u1 + u2)
        e = min(PASS_OFFSET, 0.25 * l_in, 0.25 * l_out)
        insert[k] = (w[k] - e * b, w[k] + e * b)
    if not insert:
        return path, list(at)
    new_index = np.zeros(len(w), dtype=int)
    rows: list[np.ndarray] = []
    for k, q in enumerate(w):
        if k in insert:
            rows.append(insert[k][0])
        new_index[k] = len(rows)
        rows.append(q)
        if k in insert:
            rows.append(insert[k][1])

    # the point inserted before a target lies in the segment that ends there, the one after
    # it in the segment that starts there
    segs = tuple(
        replace(s, start_index=int(new_index[s.start_index]), end_index=int(new_index[s.end_index]))
        for s in path.segments
    )
    transits = tuple(replace(t, index=int(new_index[t.index])) for t in path.transits)
    return PlanPath(np.array(rows), segs, transits), [int(new_index[k]) for k in at]


def _leg_times(
    trajectory,
    w: np.ndarray,
    at: list[int],
    stops: list[bool],
    reach: list[float],
    close: list[float],
) -> list[tuple[float, float, float]]:
    """Step 6: for each target in order, (time, distance, speed) where the trajectory
    reaches it: a stop at its rest instant, a pass-through at its first closest approach
    within ``close`` (its ball and the sampling's slack, rad), else within ``reach``, after
    the previous target. Sampled at the dense re-check's spacing and
    refined between the neighbouring samples."""
    curve = trajectory.curve
    t = np.union1d(curve.check_times(0.01), trajectory.t)
    q = curve.evaluate(t)[0]
    rests = np.concatenate([curve.rest_times(), [curve.duration]])
    out: list[tuple[float, float, float]] = []
    t_prev = 0.0
    for i, k in enumerate(at):
        target = w[k]
        after = t >= t_prev
        dist = np.where(after, np.linalg.norm(q - target, axis=1), np.inf)
        # the first closest approach (a local minimum of the distance) within the target's
        # ball (plus the sampling's slack), else within ``reach``: a pass-through whose blend
        # is near half its leg stays within reach through the next target and back (a
        # pick-and-place cycle passes each top corner twice), and a short first leg starts
        # within it, so neither the first sample within reach nor the overall minimum will do
        prev = np.concatenate([[np.inf], dist[:-1]])
        nxt = np.concatenate([dist[1:], [np.inf]])
        minima = np.flatnonzero(after & (dist <= prev) & (dist <= nxt))
        j = int(np.argmin(dist))
        for limit in (close[i], reach[i]):
            good = minima[dist[minima] <= limit]
            if good.size:
                j = int(good[0])
                break
        lo, hi = t[max(j - 1, 0)], t[min(j + 1, len(t) - 1)]
        fine = np.linspace(max(lo, t_prev), hi, 201)
        qf = curve.evaluate(fine)[0]
        m = int(np.argmin(np.linalg.norm(qf - target, axis=1)))
        t_k = float(fine[m])
        if stops[i]:
            r = rests[np.argmin(np.abs(rests - t_k))]
            if abs(r - t_k) <= max(hi - lo, 1e-9):
                t_k = float(r)
        qk, qdk = curve.evaluate(np.array([t_k]))[:2]
        out.append((t_k, float(np.linalg.norm(qk[0] - target)), float(np.linalg.norm(qdk[0]))))
        t_prev = t_k
    return out


def _transit_times(curve, path: PlanPath, begin: float, end: float) -> tuple[float, ...]:
    """When the trajectory crosses each working-mode transit of a leg's path (``path.
    transits``, in order): its closest approach to the transit posture between the leg's
    ``begin`` and ``end``, after the previous transit (at rest there with
    ``stop_at_transits``; else within the corner allowance of it). Sampled every 1 ms,
    then refined between the neighbours of the closest sample."""
    out: list[float] = []
    lo = begin
    for tr in path.transits:
        q_tr = np.asarray(tr.q, dtype=float)
        a, b, best = lo, end, lo
        for n in (max(3, int((end - lo) / 1e-3) + 1), 201):
            t = np.linspace(a, b, n)
            j = int(np.argmin(np.linalg.norm(curve.evaluate(t)[0] - q_tr, axis=1)))
            best, a, b = float(t[j]), float(t[max(j - 1, 0)]), float(t[min(j + 1, n - 1)])
        out.append(best)
        lo = best
    return tuple(out)


def solve_sequence(
    design: Design,
    start: JointPosture,
    targets: Sequence[SequenceTarget],
    *,
    cycle: bool = False,
    objective: str = "time",
    obstacles: Sequence[Obstacle] = (),
    margins: Margins | None = None,
    options: PlanOptions | None = None,
    timing: TimingOptions | None = None,
    limits: JointLimits | None = None,
    inertia: Inertia | None = None,
    gravity: tuple[float, float, float] = DEFAULT_GRAVITY,
    deadline: float | None = None,
) -> SequenceResult:
    """Plan and time one trajectory from ``start`` through every target in order (and back
    to ``start`` with ``cycle``): at rest at each ``stop`` target, passing through each other
    one within its ``blend`` without stopping. See the module docstring for the steps.

    Parameters
    ----------
    design, start, obstacles, margins, options :
        As for :func:`planner.solve`; every leg is planned with them (``options`` per leg).
    targets : at least one :class:`~planner.sequence.SequenceTarget`. The last one (without
        ``cycle``) is where the trajectory ends, at rest, whatever its ``stop``.
    cycle : return to ``start`` at the end (the return leg's ``target_index`` is
        ``len(targets)``).
    objective : "time" (default: each Cartesian target in working mode "any" gets the mode
        that makes the whole trajectory shortest, :mod:`planner.sequence.mode_search`) or "fixed"
        (each target as given; "any" is the single plan's rule).
    timing, limits : as for :func:`planner.solve`; ``timing.method="none"`` plans the legs
        only. ``timing.max_deviation`` is the corner allowance of the legs' own corners.
    inertia, gravity : as for :func:`planner.solve`: the joined trajectory's torques (with
        ``limits.torque``, bounded by them; the mode search's lower bounds stay lower bounds,
        since a torque limit only lengthens a motion).
    deadline : a :func:`time.monotonic` value for the whole answer, or None.

    Returns
    -------
    SequenceResult
        ``solved`` when every leg is planned and the joined path timed; else the status of
        the first leg that failed with "target i" (or "the return to the start") in its
        message, or ``no_path``/``timeout`` when the timing failed (``timing_error``).

    Raises
    ------
    InputError
        No targets, too many, a negative blend or one larger than half the shorter adjacent
        leg (``field`` = ``targets`` or ``("targets", i, "blend")``), an unknown objective,
        or a timing input error (under ``timing.``).
    """
    t0 = time.perf_counter()
    targets = _checked_targets(targets)
    if objective not in OBJECTIVES:
        raise InputError(
            f"objective must be one of {', '.join(OBJECTIVES)}, got {objective!r}",
            field="objective",
        )
    margins = margins if margins is not None else Margins()
    options = options if options is not None else PlanOptions()
    timing = timing if timing is not None else TimingOptions()
    limits = limits if limits is not None else JointLimits.default()
    goals: list[JointPosture | CartesianTarget] = [t.goal for t in targets]
    if cycle:
        goals.append(JointPosture(np.asarray(start.q), start.assembly_mode))
    # the end of the trajectory is at rest: the last target without a cycle, the start with one
    stops = [t.stop for t in targets] + ([True] if cycle else [])
    stops[-1] = True

    kwargs = {
        "obstacles": tuple(obstacles),
        "margins": margins,
        "options": options,
        "timing": timing,
        "limits": limits,
        "deadline": deadline,
        "inertia": inertia,
        "gravity": gravity,
    }
    if objective == "time" and any(
        isinstance(g, CartesianTarget) and g.working_mode == "any" for g in goals
    ):
        from planner.sequence.mode_search import choose_modes

        return choose_modes(design, start, targets, goals, stops, cycle, t0, **kwargs)
    return solve_with_goals(design, start, targets, goals, stops, cycle, t0, **kwargs)


def solve_with_goals(
    design: Design,
    start: JointPosture,
    targets: Sequence[SequenceTarget],
    goals: Sequence[JointPosture | CartesianTarget],
    stops: Sequence[bool],
    cycle: bool,
    t0: float,
    *,
    obstacles: Sequence[Obstacle],
    margins: Margins,
    options: PlanOptions,
    timing: TimingOptions,
    limits: JointLimits,
    deadline: float | None,
    inertia: Inertia | None = None,
    gravity: tuple[float, float, float] = DEFAULT_GRAVITY,
    plan_cache: dict | None = None,
    extra: dict | None = None,
    compare_stops: bool = True,
) -> SequenceResult:
    """Steps 3-6 of :func:`solve_sequence` for goals whose working modes are settled (the
    targets' own, or an assignment of :mod:`planner.sequence.mode_search`): plan the legs
    (``plan_cache``: leg plans already made, by leg, start posture and goal), join, time,
    read the legs' times. ``extra``: the mode search's diagnostics (``runner_up``,
    ``estimates``). With ``compare_stops``, a sequence passing targets exactly (blend 0) is
    timed again with those targets as stops, and the quicker is the answer
    (:func:`_quicker_with_stops`)."""
    n = len(targets)
    stops = list(stops)
    extra = extra or {}
    plan_cache = {} if plan_cache is None else plan_cache
    plans, failed = _plan_legs(
        design,
        start,
        goals,
        obstacles=obstacles,
        margins=margins,
        options=options,
        deadline=deadline,
        cache=plan_cache,
    )
    planning_time = time.perf_counter() - t0
    modes = tuple(
        _arrival_mode(p.path) if p.path is not None and isinstance(g, CartesianTarget) else ""
        for p, g in zip(plans, goals, strict=False)
    )
    diagnostics = SequenceDiagnostics(
        planning_time_s=planning_time,
        modes=modes,
        runner_up=extra.get("runner_up"),
        estimates=extra.get("estimates", 0),
    )
    if failed is not None:
        bad = plans[failed]
        legs = tuple(
            Leg(i, p, _arrival_mode(p.path) if p.path is not None else "")
            for i, p in enumerate(plans)
        )
        return SequenceResult(
            bad.status, f"{leg_name(failed, n)}: {bad.message}", legs, diagnostics=diagnostics
        )

    joined, at = _join_legs(np.asarray(start.q, dtype=float), plans)
    asked = [not s for s in stops]  # the pass-through targets asked for
    turning = _turning_back(np.asarray(joined.waypoints), at, asked)
    for i in turning:
        stops[i] = True
    passes = [not s for s in stops]
    _check_blends(np.asarray(joined.waypoints), at, passes, targets)
    exact = [p and (i >= n or targets[i].blend == 0.0) for i, p in enumerate(passes)]
    joined, at = _smooth_pass_through(joined, at, exact)
    w = np.asarray(joined.waypoints, dtype=float)
    deviation = np.full(len(w), timing.max_deviation)
    for i, k in enumerate(at):
        if not stops[i] and not exact[i]:
            deviation[k] = targets[i].blend
    stop_at = [k for i, k in enumerate(at) if stops[i]]
    via_at = [k for i, k in enumerate(at) if not stops[i] and not exact[i]]

    def legs_with(times: list[tuple[float, float, float]] | None, curve=None) -> tuple[Leg, ...]:
        out = []
        for i, (p, k) in enumerate(zip(plans, at, strict=True)):
            if times is None:
                out.append(Leg(i, p, _arrival_mode(p.path), waypoint_index=k))
                continue
            begin = 0.0 if i == 0 else times[i - 1][0]
            t_k, dist, speed = times[i]
            crossings = _transit_times(curve, p.path, begin, t_k)
            out.append(Leg(i, p, _arrival_mode(p.path), begin, t_k, k, dist, speed, crossings))
        return tuple(out)

    if timing.method == "none":
        return SequenceResult(
            PlanStatus.SOLVED,
            _solved_message(n, cycle, modes, extra),
            legs_with(None),
            joined,
            diagnostics=diagnostics,
        )
    try:
        trajectory = time_plan(
            design,
            joined,
            obstacles=obstacles,
            margins=margins,
            timing=timing,
            limits=limits,
            stop_at_transits=options.stop_at_transits,
            deadline=deadline,
            max_deviation=deviation,
            stop_at=stop_at,
            via_at=via_at,
            inertia=inertia,
            gravity=gravity,
        )
    except TimingError as exc:
        late = isinstance(exc, TimingDeadlineError)
        status = PlanStatus.TIMEOUT if late else PlanStatus.NO_PATH
        return SequenceResult(
            status,
            f"the legs were planned but could not be timed: {exc}",
            legs_with(None),
            joined,
            timing_error=exc,
            diagnostics=diagnostics,
        )
    reach = [
        (0.0 if stops[i] else (targets[i].blend if i < n else 0.0)) + timing.max_deviation + 0.01
        for i in range(len(at))
    ]
    close = [
        (0.0 if stops[i] or i >= n else targets[i].blend) + _SAMPLING_SLACK for i in range(len(at))
    ]
    times = _leg_times(trajectory, w, at, stops, reach, close)
    by_timing = tuple(i for i, (_, _, v) in enumerate(times) if passes[i] and v <= 1e-9)
    diagnostics = replace(
        diagnostics,
        timing_time_s=trajectory.computation_time_s,
        stopped_targets=tuple(sorted({*turning, *by_timing})),
        extra={"turning": tuple(turning)},
    )
    message = _solved_message(n, cycle, modes, extra, trajectory.duration, by_timing, turning)
    result = SequenceResult(
        PlanStatus.SOLVED,
        message,
        legs_with(times, trajectory.curve),
        joined,
        trajectory,
        diagnostics=diagnostics,
    )
    exact_at = [i for i, e in enumerate(exact) if e]
    if not (compare_stops and exact_at):
        return result
    stopped = solve_with_goals(
        design,
        start,
        targets,
        goals,
        [s or e for s, e in zip(stops, exact, strict=True)],
        cycle,
        t0,
        obstacles=obstacles,
        margins=margins,
        options=options,
        timing=timing,
        limits=limits,
        deadline=deadline,
        inertia=inertia,
        gravity=gravity,
        plan_cache=plan_cache,
        extra=extra,
        compare_stops=False,
    )
    return _quicker_with_stops(result, stopped, exact_at)


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
    diagnostics = replace(stopped.diagnostics, stopped_targets=tuple(at_rest))
    message = (
        f"{stopped.message}; at rest at pass-through "
        + ", ".join(f"target {i}" for i in exact_at)
        + f" (quicker than passing exactly with blend 0: {passing.cycle_time:.4g} s)"
    )
    return replace(stopped, message=message, diagnostics=diagnostics)


def _solved_message(
    n: int,
    cycle: bool,
    modes: Sequence[str],
    extra: dict,
    duration: float | None = None,
    stopped: Sequence[int] = (),
    turning: Sequence[int] = (),
) -> str:
    """The message of a solved sequence: its legs, its cycle time, the modes chosen for
    time and the runner-up, and any pass-through target the timing had to stop at."""
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
    return "; ".join(parts)
