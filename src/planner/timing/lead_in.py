"""A moving start: a trajectory that begins in a given state (q, qd, qdd), not at rest.

:func:`planner.timing.time_path` times a path from rest to rest. A start that is moving
(a replacement mid-motion, a new goal while the arm travels) gets a **lead-in**: one Ruckig
move from the start state onto that rest-to-rest trajectory T, joining it at a time ``tau``
with T's own position, velocity and acceleration; from there on the answer is T itself
(shifted in time). Why this construction, and not a toppra profile with a non-zero start
velocity: it is one rule for both methods and for every start (along the path or not), it
touches neither method's solver, and the part after the join is the trajectory the timing
already certified.

* **Which move.** ``ruckig``: jerk-limited, so q, qd and qdd are continuous through the start
  and the join. ``toppra``: second order (Ruckig with infinite jerk: bang-bang acceleration,
  the time-optimal profile of a straight move under velocity and acceleration limits, which is
  exactly what toppra computes on a straight segment), so q and qd are continuous and the
  acceleration may jump after the start sample, as toppra's does at its grid points. Every
  move is phase-synchronised: where the start velocity (and acceleration) lie along the
  first planned segment and the join is on that segment, the lead-in stays *on the planned
  path*; otherwise it bends onto it, and its postures are checked densely.
* **Where to join.** ``CANDIDATES`` + 1 join times spread over the part of T on the first
  planned segment (the lead-in joins the path where it begins, and the rest of the plan is
  followed as planned); each move's duration gives
  the answer's total duration ``move + (T.duration - tau)``; the quickest candidates are
  checked in turn (at most ``TRIES``): joint limits, assembly, the path's validity rules
  (``check_states``) at postures ``resolution`` apart, and the velocity, acceleration (and
  jerk) limits. The first that passes is the answer.
* **Fallback.** If none passes: brake to rest (:func:`brake_move`, the same move a stop
  makes, velocity interface), return to the start posture on a rest-to-rest move (phase
  synchronised, so it is the straight segment back; when the start velocity and acceleration
  are parallel, the braking was straight too and the return retraces checked postures), then
  T from its beginning. If that fails too, :class:`~planner.exceptions.TrajectoryCheckError`.
* **Invalid start.** A start state whose braking at the limits already leaves the valid set
  (:func:`braking_failure`) cannot be kept valid by any trajectory: the pipeline answers
  ``invalid_start`` with the rule, the time and the posture, before planning.

The start state must be within the limits (:func:`check_start_rates`): ``|qd| <= velocity``,
``|qdd| <= acceleration``, and with a jerk limit ``|qd + qdd |qdd| / (2 jerk)| <= velocity``
(the speed reached before the acceleration can be brought to zero); else a
:class:`~planner.exceptions.LimitsError` names ``start.qd`` or ``start.qdd``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from ruckig import ControlInterface, InputParameter, Result, Ruckig, RuckigError, Synchronization
from ruckig import Trajectory as RuckigTrajectory

from planner.design import Design
from planner.exceptions import InputError, LimitsError, TimingInfeasibleError, TrajectoryCheckError
from planner.kinematics import forward_batch
from planner.timing.checks import LIMIT_RTOL, StateChecker
from planner.timing.limits import JointLimits
from planner.timing.ruckig_method import _evaluate_with_ruckig, _moves_from
from planner.timing.trajectory import Curve, Trajectory, p_velocity, sample_times

__all__ = [
    "CANDIDATES",
    "TRIES",
    "LeadIn",
    "LeadInCurve",
    "LineMove",
    "MoveChain",
    "StartState",
    "brake_move",
    "braking_failure",
    "check_start_rates",
    "with_moving_start",
]

#: Join times tried on the rest-to-rest trajectory (spread over it, the start included).
CANDIDATES = 24
#: Most candidate lead-ins checked densely before the fallback.
TRIES = 6
#: Times scanned for the part of the trajectory along the first planned segment.
SCAN = 200
#: A join state this close (rad, rad/s, rad/s^2) to the first segment's line lies on it.
ON_LINE = 1e-9

Evaluation = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]


@dataclass(frozen=True, eq=False)
class StartState:
    """Where a trajectory begins: q (3,) rad, qd (3,) rad/s, qdd (3,) rad/s^2."""

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray

    @classmethod
    def of(
        cls, q: object, qd: object = (0.0, 0.0, 0.0), qdd: object = (0.0, 0.0, 0.0)
    ) -> StartState:
        """The checked state (3 finite numbers each; ``start.qd``, ``start.qdd`` named)."""
        out = []
        for name, value in (("start.q", q), ("start.qd", qd), ("start.qdd", qdd)):
            try:
                a = np.asarray(value, dtype=float).reshape(3)
            except (TypeError, ValueError) as exc:
                raise InputError(f"{name} must be 3 numbers, got {value!r}", field=name) from exc
            if not np.all(np.isfinite(a)):
                raise InputError(f"{name} must be finite, got {a.tolist()}", field=name)
            out.append(a)
        return cls(*out)

    @property
    def moving(self) -> bool:
        """Not at rest (a velocity or an acceleration is not zero)."""
        return bool(np.any(self.qd != 0.0) or np.any(self.qdd != 0.0))


def check_start_rates(state: StartState, limits: JointLimits, *, jerk_limited: bool) -> None:
    """:class:`~planner.exceptions.LimitsError` at ``start.qd`` or ``start.qdd`` when the
    start state is beyond the limits (module docstring), with the joint and the values."""
    if jerk_limited:  # ruckig's moves: the asked jerk, else RUCKIG_DEFAULT_JERK (as time_path)
        limits = limits.with_ruckig_jerk()
    v, a = limits.velocity_array, limits.acceleration_array
    tol = 1.0 + LIMIT_RTOL
    for name, x, lim, what in (
        ("qd", state.qd, v, "velocity"),
        ("qdd", state.qdd, a, "acceleration"),
    ):
        over = np.abs(x) > lim * tol
        if np.any(over):
            j = int(np.argmax(over))
            raise LimitsError(
                f"start.{name}[{j}] = {x[j]:.10g} exceeds limits.{what}[{j}] = {lim[j]:.10g}",
                field=f"start.{name}",
            )
    jerk = limits.jerk_array
    if jerk_limited and jerk is not None:
        reach = state.qd + state.qdd * np.abs(state.qdd) / (2.0 * jerk)
        over = np.abs(reach) > v * tol
        if np.any(over):
            j = int(np.argmax(over))
            raise LimitsError(
                f"start.qdd[{j}] = {state.qdd[j]:.10g} drives joint {j + 1} to "
                f"{reach[j]:.10g} rad/s before limits.jerk[{j}] = {jerk[j]:.10g} can bring its "
                f"acceleration to zero, beyond limits.velocity[{j}] = {v[j]:.10g}",
                field="start.qdd",
            )


def _input(limits: JointLimits, jerk_limited: bool) -> InputParameter:
    inp = InputParameter(3)
    inp.max_velocity = limits.velocity_array.tolist()
    inp.max_acceleration = limits.acceleration_array.tolist()
    jerk = limits.jerk_array
    inp.max_jerk = jerk.tolist() if jerk_limited and jerk is not None else [math.inf] * 3
    inp.synchronization = Synchronization.Phase
    return inp


def _solve(inp: InputParameter, start: tuple, target: tuple | None) -> RuckigTrajectory | str:
    """One Ruckig move (``target`` None: to rest by the velocity interface), or why none."""
    inp.current_position, inp.current_velocity, inp.current_acceleration = (
        np.asarray(x, dtype=float).tolist() for x in start
    )
    if target is None:
        inp.control_interface = ControlInterface.Velocity
        inp.target_velocity, inp.target_acceleration = [0.0] * 3, [0.0] * 3
    else:
        inp.control_interface = ControlInterface.Position
        inp.target_position, inp.target_velocity, inp.target_acceleration = (
            np.asarray(x, dtype=float).tolist() for x in target
        )
    traj = RuckigTrajectory(3)
    try:
        result = Ruckig(3).calculate(inp, traj)
    except RuckigError as exc:
        return f"ruckig rejected the move: {str(exc).strip()}"
    if result not in (Result.Working, Result.Finished):
        return f"ruckig found no move: {result}"
    return traj


@dataclass(frozen=True, eq=False)
class LineMove:
    """A move along the straight line ``origin + s u`` (u a unit joint direction): one Ruckig
    move of the path coordinate s (rad), under the joint limits projected onto the line
    (``min_j limit_j / |u_j|``). Every posture lies on the line exactly (a 3-joint move
    between collinear states need not: Ruckig synchronises their phases only when it can)."""

    source: RuckigTrajectory
    origin: np.ndarray
    u: np.ndarray

    @property
    def duration(self) -> float:
        return float(self.source.duration)

    def evaluate(self, tau: np.ndarray) -> Evaluation:
        rows = [self.source.at_time(float(x)) for x in tau]
        s, sd, sdd = (np.array([r[i][0] for r in rows]) for i in range(3))
        u = self.u[None, :]
        return self.origin + s[:, None] * u, sd[:, None] * u, sdd[:, None] * u, None


def _line_move(
    segment: np.ndarray, start: tuple, target: tuple, limits: JointLimits, jerk_limited: bool
) -> LineMove | str:
    """The move between two states on the line of ``segment`` ((2, 3)), in its coordinate."""
    a, b = segment
    u = (b - a) / np.linalg.norm(b - a)
    inp = InputParameter(1)
    scale = np.where(np.abs(u) > 0, 1.0 / np.maximum(np.abs(u), 1e-300), np.inf)
    inp.max_velocity = [float(np.min(limits.velocity_array * scale))]
    inp.max_acceleration = [float(np.min(limits.acceleration_array * scale))]
    jerk = limits.jerk_array
    inp.max_jerk = [float(np.min(jerk * scale)) if jerk_limited and jerk is not None else math.inf]
    inp.current_position, inp.current_velocity, inp.current_acceleration = (
        [float((np.asarray(x) - base) @ u)] for x, base in zip(start, (a, 0.0, 0.0), strict=True)
    )
    inp.target_position, inp.target_velocity, inp.target_acceleration = (
        [float((np.asarray(x) - base) @ u)] for x, base in zip(target, (a, 0.0, 0.0), strict=True)
    )
    traj = RuckigTrajectory(1)
    try:
        result = Ruckig(1).calculate(inp, traj)
    except RuckigError as exc:
        return f"ruckig rejected the move: {str(exc).strip()}"
    if result not in (Result.Working, Result.Finished):
        return f"ruckig found no move: {result}"
    return LineMove(traj, a, u)


@dataclass(frozen=True, eq=False)
class MoveChain:
    """Ruckig moves one after the other from t = 0 (jerk-limited ones read from their phase
    tables, with their jerk; second-order ones by Ruckig's ``at_time``)."""

    moves: tuple[RuckigTrajectory | LineMove, ...]
    jerk_limited: bool

    @functools.cached_property
    def starts(self) -> np.ndarray:
        return np.concatenate([[0.0], np.cumsum([m.duration for m in self.moves])])

    @functools.cached_property
    def duration(self) -> float:
        return float(self.starts[-1])

    @functools.cached_property
    def _tables(self) -> list:
        """The jerk-limited moves' phase tables, read once (None for a line move)."""
        if not self.jerk_limited:
            return []
        return [None if isinstance(m, LineMove) else _moves_from([m], [()])[0] for m in self.moves]

    def evaluate(self, t: np.ndarray, *, jerk: bool = True) -> Evaluation:
        """q, qd, qdd and (``jerk``, jerk-limited moves) the jerk at times t (M,), (M, 3)
        each; without the jerk, Ruckig's own ``at_time`` (cheaper for a few hundred
        samples than the phase tables)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        starts = self.starts
        k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(self.moves) - 1)
        q, qd, qdd = (np.zeros((t.shape[0], 3)) for _ in range(3))
        j = np.full((t.shape[0], 3), np.nan)
        for i, move in enumerate(self.moves):
            sel = k == i
            if not np.any(sel):
                continue
            tau = np.clip(t[sel] - starts[i], 0.0, move.duration)
            if isinstance(move, LineMove):
                got = move.evaluate(tau)
            elif self.jerk_limited and jerk:
                got = self._tables[i].evaluate(tau)
            else:
                got = _evaluate_with_ruckig(move, tau)
            q[sel], qd[sel], qdd[sel] = got[0], got[1], got[2]
            if got[3] is not None:
                j[sel] = got[3]
        return q, qd, qdd, (j if self.jerk_limited and not np.all(np.isnan(j)) else None)

    def rest_times(self) -> np.ndarray:
        """The ends of inner moves that end at rest (a brake before a return)."""
        ends = self.starts[1:-1]
        if ends.size == 0:
            return ends
        _, qd, _, _ = self.evaluate(ends)
        return ends[np.all(qd == 0.0, axis=1)]

    def check_times(self, resolution: float, speed: float) -> np.ndarray:
        """Times at which consecutive postures are at most ``resolution`` apart, for a
        speed bound ``speed`` (rad/s, joint-space norm), plus every move's ends."""
        n = max(2, int(np.ceil(self.duration * speed / resolution)) + 1)
        return np.unique(np.concatenate([np.linspace(0.0, self.duration, n), self.starts]))


def brake_move(state: StartState, limits: JointLimits, *, jerk_limited: bool) -> MoveChain:
    """The quickest braking to rest from ``state`` under ``limits`` (Ruckig's velocity
    interface, phase-synchronised: a straight line when qd and qdd are parallel).

    Raises
    ------
    TimingInfeasibleError
        Ruckig has no braking move (a state beyond the limits).
    """
    if jerk_limited:  # ruckig's moves: the asked jerk, else RUCKIG_DEFAULT_JERK (as time_path)
        limits = limits.with_ruckig_jerk()
    got = _solve(_input(limits, jerk_limited), (state.q, state.qd, state.qdd), None)
    if isinstance(got, str):
        raise TimingInfeasibleError(got)
    return MoveChain((got,), jerk_limited)


def _speed(limits: JointLimits, brake_from: StartState | None = None) -> float:
    """A bound of |qd| (joint-space norm, rad/s) of any move within ``limits``; of a brake
    from ``brake_from``, per joint the speed reached before its acceleration is zero,
    ``|qd| + qdd^2 / (2 jerk)`` (a brake only slows down after that; second order: ``|qd|``),
    if lower."""
    bound = float(np.linalg.norm(limits.velocity_array))
    if brake_from is not None:
        jerk = limits.jerk_array
        rise = 0.0 if jerk is None else brake_from.qdd**2 / (2.0 * jerk)
        bound = min(bound, float(np.linalg.norm(np.abs(brake_from.qd) + rise)))
    return max(bound, 1e-9) * (1.0 + LIMIT_RTOL)


def _first_failure(
    chain: MoveChain,
    design: Design,
    assembly_mode: str,
    limits: JointLimits,
    check_states: StateChecker | None,
    resolution: float,
    inherited: StartState | None = None,
    speed: float | None = None,
) -> str | None:
    """Why ``chain`` is not acceptable (joint limits, assembly, validity, rate limits at
    postures ``resolution`` apart), naming the rule, the time and the posture; None: it is.
    ``inherited``: a start state whose velocity or acceleration already exceeds a limit (a
    running trajectory read between its samples), which the chain may keep up to. ``speed``:
    a bound of the chain's joint speed (rad/s; default :func:`_speed` of the limits), which
    spaces the checked postures."""
    t = chain.check_times(resolution, _speed(limits) if speed is None else speed)
    q, qd, qdd, _ = chain.evaluate(t, jerk=False)
    # the jerk by differences of qdd (what a controller sees; the moves keep it exactly)
    jerk = (
        np.diff(qdd, axis=0) / np.maximum(np.diff(t), 1e-300)[:, None]
        if chain.jerk_limited
        else None
    )
    lo, hi = np.asarray(design.joint_min), np.asarray(design.joint_max)
    bad = np.any((q < lo) | (q > hi), axis=1)
    rule = "joint_limits"
    if not np.any(bad):
        bad, rule = ~forward_batch(design, q, assembly_mode).ok, "assembly"
    if not np.any(bad) and check_states is not None:
        bad, rule = ~np.asarray(check_states(q), dtype=bool), "validity"
    if np.any(bad):
        i = int(np.argmax(bad))
        return f"{rule} at t = {t[i]:.4f} s, q = {np.round(q[i], 6).tolist()}"
    tol = 1.0 + LIMIT_RTOL
    v_max, a_max = limits.velocity_array, limits.acceleration_array
    if inherited is not None:
        v_max = np.maximum(v_max, np.abs(inherited.qd))
        a_max = np.maximum(a_max, np.abs(inherited.qdd))
    for name, x, lim in (
        ("velocity", qd, v_max),
        ("acceleration", qdd, a_max),
        ("jerk", jerk, limits.jerk_array),
    ):
        if x is None or lim is None:
            continue
        ratio = float(np.max(np.where(np.isnan(x), 0.0, np.abs(x)) / lim))
        if ratio > tol:
            return f"the {name} limit exceeded by a factor {ratio:.6f}"
    return None


def braking_failure(
    design: Design,
    state: StartState,
    assembly_mode: str,
    limits: JointLimits,
    check_states: StateChecker | None,
    resolution: float,
    *,
    jerk_limited: bool,
) -> str | None:
    """Why ``state`` cannot be kept valid: its quickest braking (:func:`brake_move`)
    already leaves the valid set (the rule, time and posture); None when the braking stays
    valid."""
    if jerk_limited:  # ruckig's moves: the asked jerk, else RUCKIG_DEFAULT_JERK (as time_path)
        limits = limits.with_ruckig_jerk()
    try:
        chain = brake_move(state, limits, jerk_limited=jerk_limited)
    except TimingInfeasibleError as exc:
        return f"no braking move from the start state: {exc}"
    speed = _speed(limits, state)
    why = _first_failure(
        chain, design, assembly_mode, limits, check_states, resolution, None, speed
    )
    if why is None:
        return None
    return (
        f"the moving start cannot be kept valid: braking at the limits from start.qd = "
        f"{np.round(state.qd, 6).tolist()}, start.qdd = {np.round(state.qdd, 6).tolist()} "
        f"fails {why}"
    )


@dataclass(frozen=True, eq=False)
class LeadIn:
    """How a moving start joins its trajectory: the lead-in's ``duration`` (s), the time
    ``joins_at`` of the rest-to-rest trajectory where it joins it (s), and ``kind``:
    ``"direct"`` (one move onto it) or ``"brake_and_return"`` (the fallback)."""

    duration: float
    joins_at: float
    kind: str


@dataclass(frozen=True, eq=False)
class LeadInCurve:
    """The lead-in (a :class:`MoveChain`) and then ``rest`` from its time ``lead_in.joins_at``
    on (a :class:`~planner.timing.trajectory.Curve`)."""

    lead: MoveChain
    rest: Curve
    lead_in: LeadIn
    speed: float  # bound of |qd| on the lead-in, rad/s (joint-space norm)

    @property
    def _shift(self) -> float:
        return self.lead.duration - self.lead_in.joins_at

    @property
    def duration(self) -> float:
        return self._shift + self.rest.duration

    def evaluate(self, t: np.ndarray) -> Evaluation:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        first = t < self.lead.duration
        q, qd, qdd = (np.zeros((t.shape[0], 3)) for _ in range(3))
        jerk = np.full((t.shape[0], 3), np.nan)
        for sel, curve, tt in (
            (first, self.lead, t[first]),
            (~first, self.rest, t[~first] - self._shift),
        ):
            if np.any(sel):
                a, b, c, d = curve.evaluate(tt)
                q[sel], qd[sel], qdd[sel] = a, b, c
                if d is not None:
                    jerk[sel] = d
        return q, qd, qdd, (None if np.all(np.isnan(jerk)) else jerk)

    def rest_times(self) -> np.ndarray:
        later = self.rest.rest_times() + self._shift
        return np.concatenate([self.lead.rest_times(), later[later > self.lead.duration]])

    def check_times(self, resolution: float) -> np.ndarray:
        later = self.rest.check_times(resolution) + self._shift
        lead = self.lead.check_times(resolution, self.speed)
        return np.unique(np.concatenate([lead, later[later >= self.lead.duration]]))

    def plan_segments(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        out = self.rest.plan_segments(np.maximum(t - self._shift, 0.0))
        out[t < self.lead.duration] = 0  # the lead-in stands for the first planned segment
        return out


def _join_times(rest: Curve, first_segment: np.ndarray | None, near: float) -> np.ndarray:
    """Candidate join times: spread over the part of ``rest`` that runs along the first
    planned segment ``first_segment`` ((2, 3), rad; None: over the whole of it), within
    ``near`` rad of it (its corner allowance), the start included. The lead-in joins the
    path where it begins, so the rest of the plan is followed."""
    grid = np.linspace(0.0, rest.duration, SCAN + 1)
    if first_segment is not None:
        a, b = np.asarray(first_segment, dtype=float)
        q = rest.evaluate(grid)[0]
        d = b - a
        u = np.clip((q - a) @ d / max(float(d @ d), 1e-300), 0.0, 1.0)
        on = np.linalg.norm(q - (a + u[:, None] * d), axis=1) <= max(near, 1e-9)
        last = int(np.argmin(on)) - 1 if not np.all(on) else len(grid) - 1
        grid = grid[: max(last, 0) + 1]
    pick = np.unique(np.round(np.linspace(0, len(grid) - 1, CANDIDATES + 1)).astype(int))
    return grid[pick]


def _onto_segment(
    segment: np.ndarray, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Join states that lie on the segment's line (within ``ON_LINE``: position, velocity and
    acceleration) made exactly collinear with it, and which of them do (M,) bool."""
    a, b = segment
    length = float(np.linalg.norm(b - a))
    if length == 0.0:
        return q, qd, qdd, np.zeros(q.shape[0], bool)
    u = (b - a) / length
    out = []
    for x, base in ((q, a), (qd, 0.0), (qdd, 0.0)):
        along = (x - base) @ u
        out.append(
            (base + along[:, None] * u, np.linalg.norm(x - base - along[:, None] * u, axis=1))
        )
    on = (out[0][1] <= ON_LINE) & (out[1][1] <= ON_LINE) & (out[2][1] <= ON_LINE)
    fixed = [np.where(on[:, None], proj, x) for (proj, _), x in zip(out, (q, qd, qdd), strict=True)]
    return fixed[0], fixed[1], fixed[2], on


def _join_candidates(
    state: StartState,
    rest: Curve,
    limits: JointLimits,
    jerk_limited: bool,
    first_segment: np.ndarray | None,
    near: float,
) -> list[tuple[float, float, RuckigTrajectory | LineMove]]:
    """(total duration, join time, move) of every candidate lead-in, quickest first: a move
    along the first segment's line where the start and the join both lie on it, else a
    3-joint move."""
    taus = _join_times(rest, first_segment, near)
    q, qd, qdd, _ = rest.evaluate(taus)
    on_line = np.zeros(taus.shape[0], bool)
    segment = None if first_segment is None else np.asarray(first_segment, dtype=float)
    if segment is not None and np.linalg.norm(segment[1] - segment[0]) > 0.0:
        start = _onto_segment(segment, state.q[None], state.qd[None], state.qdd[None])[3]
        q, qd, qdd, on_line = _onto_segment(segment, q, qd, qdd)
        on_line &= bool(start[0])
    inp = _input(limits, jerk_limited)
    found = []
    for k, tau in enumerate(taus):
        if tau == rest.duration:
            qd[k] = qdd[k] = 0.0
        begin, end = (state.q, state.qd, state.qdd), (q[k], qd[k], qdd[k])
        got: RuckigTrajectory | LineMove | str
        if on_line[k] and segment is not None:
            got = _line_move(segment, begin, end, limits, jerk_limited)
        else:
            got = _solve(inp, begin, end)
        if not isinstance(got, str):
            found.append((got.duration + rest.duration - float(tau), float(tau), got))
    found.sort(key=lambda x: x[0])
    return found


def _lead_in(
    state: StartState,
    rest: Curve,
    design: Design,
    assembly_mode: str,
    limits: JointLimits,
    check_states: StateChecker | None,
    resolution: float,
    jerk_limited: bool,
    first_segment: np.ndarray | None,
    near: float,
) -> LeadInCurve:
    """The quickest acceptable lead-in onto ``rest``, or the fallback (module docstring)."""
    failures = []
    candidates = _join_candidates(state, rest, limits, jerk_limited, first_segment, near)
    for _, tau, move in candidates[:TRIES]:  # (a line move: on the path by construction)
        chain = MoveChain((move,), jerk_limited)
        why = _first_failure(chain, design, assembly_mode, limits, check_states, resolution)
        if why is None:
            return LeadInCurve(chain, rest, LeadIn(chain.duration, tau, "direct"), _speed(limits))
        failures.append(why)
    brake = brake_move(state, limits, jerk_limited=jerk_limited)
    q_b = brake.evaluate(np.array([brake.duration]))[0][0]
    zero = np.zeros(3)
    back = _solve(_input(limits, jerk_limited), (q_b, zero, zero), (state.q, zero, zero))
    if isinstance(back, str):
        raise TrajectoryCheckError(f"no lead-in from the moving start: {back}", rule="lead_in")
    chain = MoveChain((brake.moves[0], back), jerk_limited)
    why = _first_failure(chain, design, assembly_mode, limits, check_states, resolution)
    if why is not None:
        tried = "; ".join(failures[:2])
        raise TrajectoryCheckError(
            f"no valid lead-in from the moving start (direct moves: {tried or 'none'}; "
            f"braking and returning: {why})",
            rule="lead_in",
        )
    return LeadInCurve(chain, rest, LeadIn(chain.duration, 0.0, "brake_and_return"), _speed(limits))


def with_moving_start(
    trajectory: Trajectory,
    state: StartState,
    *,
    design: Design,
    assembly_mode: str,
    limits: JointLimits,
    check_states: StateChecker | None,
    resolution: float,
    sample_rate_hz: float,
    first_segment: np.ndarray | None = None,
    near: float = 0.0,
    torques: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray] | None = None,
) -> Trajectory:
    """``trajectory`` (timed from rest at ``state.q``) beginning in ``state`` instead: a
    lead-in onto it (module docstring), sampled at ``sample_rate_hz``. The first sample is
    ``state`` exactly; the last is the trajectory's end, at rest. Unchanged when ``state``
    is at rest. ``first_segment`` ((2, 3), rad: the path's first two waypoints) keeps the
    join on the planned path's first segment or within ``near`` (rad, the corner allowance)
    of it (None: anywhere on the trajectory).

    Raises
    ------
    LimitsError
        The start state is beyond the limits (:func:`check_start_rates`).
    TrajectoryCheckError
        No lead-in passes the dense check (rule ``"lead_in"``).
    """
    if not state.moving:
        return trajectory
    jerk_limited = trajectory.method == "ruckig"
    if jerk_limited:  # ruckig's moves: the asked jerk, else RUCKIG_DEFAULT_JERK (as time_path)
        limits = limits.with_ruckig_jerk()
    check_start_rates(state, limits, jerk_limited=jerk_limited)
    curve = _lead_in(
        state,
        trajectory.curve,
        design,
        assembly_mode,
        limits,
        check_states,
        resolution,
        jerk_limited,
        first_segment,
        near,
    )
    t = np.union1d(sample_times(curve.duration, sample_rate_hz), curve.rest_times())
    q, qd, qdd, jerk = curve.evaluate(t)
    q[0], qd[0], qdd[0] = state.q, state.qd, state.qdd
    q[-1], qd[-1], qdd[-1] = trajectory.q[-1], 0.0, 0.0
    rest = np.isin(t, curve.rest_times())
    qd[rest] = qdd[rest] = 0.0
    if jerk is not None and not np.all(np.isfinite(jerk)):
        jerk = None
    p, v_p, _ = p_velocity(design, q, qd, assembly_mode)
    return Trajectory(
        method=trajectory.method,
        duration=curve.duration,
        t=t,
        q=q,
        qd=qd,
        qdd=qdd,
        jerk=jerk,
        p=p,
        p_speed=np.linalg.norm(v_p, axis=1),
        max_deviation_q=trajectory.max_deviation_q,
        max_deviation_p=trajectory.max_deviation_p,
        repairs=trajectory.repairs,
        checked_samples=trajectory.checked_samples,
        computation_time_s=trajectory.computation_time_s,
        curve=curve,
        tau=None if torques is None else torques(q, qd, qdd),
        max_torque_ratio=None,
    )
