"""Jerk-limited trajectories with the community Ruckig: a chain of state-to-state moves.

The community edition computes one move from a current state (q, qd, qdd) to a target state;
its intermediate-waypoint feature calls a cloud service and is never used here. The chain is
built from the time-optimal toppra profile on the blended path (:mod:`planner.timing.path`):

* at every blend (arc) we take two through-states from the toppra profile: the *entry* (where
  the arc leaves the incoming segment) and the *exit* (where it joins the outgoing one), each
  with toppra's path velocity along the segment's direction and toppra's tangential
  acceleration on the straight side, slowed by a factor chosen greedily per state (a joint at
  its velocity limit cannot stretch its move to a longer common duration, which can make a
  synchronised move several times longer than needed) and with the acceleration shrunk to a
  state a jerk-limited joint can pass through;
* consecutive states are joined by one Ruckig move with ``Synchronization.Phase``. Between an
  exit and the next entry, start velocity, start acceleration, target velocity, target
  acceleration and displacement are all parallel to the segment, so the phase-synchronised
  move stays exactly on the planned segment; around a corner the move bends near the arc
  (phase synchronisation falls back to time synchronisation) and its deviation is measured;
* a straight segment between two blends that toppra crosses faster than a joint can bring its
  acceleration to zero under the jerk limit (``max_j a_j / j_j``) gets one through-state at
  its middle instead of an exit and an entry: toppra leaves the first blend accelerating hard
  and enters the next braking hard, a swing no jerk-limited joint can follow in that time;
* stops (path start and end, requested stops, unblended corners) are reached at rest, and a
  rest-to-rest move with phase synchronisation is the straight segment itself.

The toppra profile is solved on a coarser grid than toppra's own method uses
(:data:`SEED_REFINE`): only its states at the through-states matter.

The moves meet with equal position, velocity and acceleration, so q, qd and qdd are
continuous. Position limits are not in the community version: the caller checks joint limits.
"""

from __future__ import annotations

import functools
import itertools
import logging
from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, RuckigError, Synchronization
from ruckig import Trajectory as RuckigTrajectory

from planner.exceptions import TimingInfeasibleError
from planner.timing.limits import JointLimits
from planner.timing.path import ARC, BlendedPath
from planner.timing.toppra_method import PathProfile, check_deadline, section_key
from planner.timing.trajectory import check_sample_count

__all__ = [
    "PATIENCE",
    "SEED_REFINE",
    "SPEED_FACTORS",
    "MoveCache",
    "RuckigCurve",
    "build_ruckig_curve",
]

logger = logging.getLogger(__name__)

#: Target states are pulled this far inside the limits (relative): toppra meets its limits
#: to within solver tolerance, Ruckig rejects a target even 1 ulp beyond.
_INSIDE = 1.0 - 1e-9
#: Candidate slow-downs of each through-state's toppra velocity (see build_ruckig_curve).
SPEED_FACTORS = (1.0, 0.9, 0.8, 0.7, 0.6, 0.5)
#: The greedy choice stops trying slower factors after this many in a row did worse than the
#: best so far (the cost is nearly unimodal in the factor: on the benchmark paths a patience
#: of 2 chooses as all six do, for about half the solves).
PATIENCE = 2
#: Grid refinement of the toppra pass that gives the through-states (see
#: :func:`~planner.timing.toppra_method.section_grid`): only the profile's states at the
#: blends' ends are used, and on a grid 3x coarser they barely change (ruckig/toppra duration
#: p50 +0.004 on the benchmark paths) while the pass costs about half.
SEED_REFINE = 1 / 3
#: Tags of the through-states.
_REST, _ENTRY, _EXIT, _MIDDLE = 0, 1, 2, 3


@dataclass(frozen=True, eq=False)
class _Move:
    """One Ruckig move: per joint, 7 constant-jerk phases.

    ``cum`` (3, 8) phase start times, ``jerk`` (3, 7), and ``p``, ``v``, ``a`` (3, 8) the state
    at each phase start. ``corners``: waypoint indices of the blends this move belongs to.
    """

    duration: float
    cum: np.ndarray
    jerk: np.ndarray
    p: np.ndarray
    v: np.ndarray
    a: np.ndarray
    corners: tuple[int, ...]
    source: RuckigTrajectory  # Ruckig's own trajectory object
    braking: bool  # a brake phase precedes the profile: evaluate with Ruckig's at_time

    def speed_bound(self, fallback: float) -> float:
        """Upper bound of |qd| during the move, rad/s (:func:`_speed_bounds`); ``fallback``
        for a braking move."""
        if self.braking:
            return fallback
        return float(_speed_bounds(self.v[None], self.a[None], self.jerk[None])[0])

    def evaluate(self, tau: np.ndarray) -> tuple[np.ndarray, ...]:
        """q, qd, qdd, jerk at local times tau (M,) in [0, duration], shapes (M, 3)."""
        tau = np.clip(np.atleast_1d(np.asarray(tau, dtype=float)), 0.0, self.duration)
        if self.braking:
            return _evaluate_with_ruckig(self.source, tau)
        table = tuple(x[None] for x in (self.cum, self.jerk, self.p, self.v, self.a))
        return _integrate(table, np.zeros(tau.shape[0], dtype=int), tau)


def _speed_bounds(v: np.ndarray, a: np.ndarray, jerk: np.ndarray) -> np.ndarray:
    """Upper bound of |qd| during each of K moves, rad/s, shape (K,): per joint, the largest
    |velocity| at a phase boundary or where the acceleration crosses zero inside a phase
    (velocity is quadratic in time within a constant-jerk phase), and the norm over joints.
    ``v``, ``a``: shape (K, 3, 8) at the phase starts; ``jerk``: shape (K, 3, 7)."""
    v0, v1 = np.abs(v[..., :-1]), np.abs(v[..., 1:])
    a0, a1 = a[..., :-1], a[..., 1:]
    crosses = (a0 * a1 < 0) & (jerk != 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        v_turn = np.where(crosses, np.abs(v[..., :-1] - a0**2 / (2 * jerk)), 0.0)
    per_joint = np.max(np.maximum(np.maximum(v0, v1), v_turn), axis=-1)
    return np.linalg.norm(per_joint, axis=-1)


def _integrate(
    table: tuple[np.ndarray, ...], move: np.ndarray, tau: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """q, qd, qdd, jerk, shapes (M, 3), at local times ``tau`` (M,) of moves ``move`` (M,):
    per joint, the constant-jerk phase holding tau, integrated from its start state.

    ``table`` = (cum (K, 3, 8) phase start times, jerk (K, 3, 7), p, v, a (K, 3, 8) the
    states at the phase starts) of K moves. A phase boundary belongs to the later phase (as
    ``searchsorted(side="right")``); the last phase extends past its end."""
    cum, jerk, p, v, a = table
    c = cum[move]  # (M, 3, 8)
    k = np.clip(np.sum(c <= tau[:, None, None], axis=2) - 1, 0, 6)[..., None]  # (M, 3, 1)
    x = tau[:, None] - np.take_along_axis(c, k, axis=2)[..., 0]
    j = np.take_along_axis(jerk[move], k, axis=2)[..., 0]
    a0 = np.take_along_axis(a[move], k, axis=2)[..., 0]
    v0 = np.take_along_axis(v[move], k, axis=2)[..., 0]
    p0 = np.take_along_axis(p[move], k, axis=2)[..., 0]
    q = p0 + x * (v0 + x * (a0 / 2 + x * j / 6))
    return q, v0 + x * (a0 + x * j / 2), a0 + x * j, j


def _evaluate_with_ruckig(
    traj: RuckigTrajectory, tau: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """q, qd, qdd (and NaN jerk) by Ruckig's own ``at_time``: for a move with brake phases,
    which the phase tables do not hold."""
    rows = [traj.at_time(float(x)) for x in tau]
    q = np.array([r[0] for r in rows]).reshape(-1, 3)
    qd = np.array([r[1] for r in rows]).reshape(-1, 3)
    qdd = np.array([r[2] for r in rows]).reshape(-1, 3)
    return q, qd, qdd, np.full_like(q, np.nan)


def _calculate(
    otg: Ruckig, inp: InputParameter, start: tuple, target: tuple, traj: RuckigTrajectory
) -> str:
    """One Ruckig move from ``start`` to ``target`` ((q, qd, qdd), each 3 numbers) into
    ``traj``: "" when solved, else the reason Ruckig gave none (``RuckigError`` or an error
    code). The lean path: the candidate moves of :func:`build_ruckig_curve` need only their
    durations, so nothing else is read here (that costs as much as the solve itself)."""
    inp.current_position, inp.current_velocity, inp.current_acceleration = start
    inp.target_position, inp.target_velocity, inp.target_acceleration = target
    try:
        result = otg.calculate(inp, traj)
    except RuckigError as exc:
        return f"ruckig rejected a move: {str(exc).strip()}"
    if result not in (Result.Working, Result.Finished):
        return f"ruckig found no move: {result}"
    return ""


def _phase_rows(traj: RuckigTrajectory) -> tuple[list, list, bool]:
    """One solved trajectory's phase table as lists: per joint (t, j) of its 7 phases, (p, v,
    a) at its 8 phase starts, and whether a brake phase precedes the profile."""
    profiles = traj.profiles[0]
    rows = [(pr.t, pr.j) for pr in profiles]
    states = [(pr.p, pr.v, pr.a) for pr in profiles]
    braking = any(pr.brake.duration > 0 or pr.accel.duration > 0 for pr in profiles)
    return rows, states, braking


def _moves_from(
    trajs: list[RuckigTrajectory],
    corners: list[tuple[int, ...]],
    cache: MoveCache | None = None,
) -> list[_Move]:
    """The phase tables of solved Ruckig trajectories, for vectorised evaluation (read in one
    pass: per-move numpy conversions would cost as much as the solves; a trajectory read in
    an earlier round is taken from ``cache``)."""
    read = [cache.rows(tr) if cache is not None else _phase_rows(tr) for tr in trajs]
    phases = np.array([r[0] for r in read], dtype=float).reshape(len(trajs), 3, 2, 7)
    at = np.array([r[1] for r in read], dtype=float).reshape(len(trajs), 3, 3, 8)
    cum = np.concatenate([np.zeros((len(trajs), 3, 1)), np.cumsum(phases[:, :, 0], axis=2)], 2)
    out = []
    for k, tr in enumerate(trajs):
        out.append(
            _Move(
                duration=float(tr.duration),
                cum=cum[k],
                jerk=phases[k, :, 1],
                p=at[k, :, 0],
                v=at[k, :, 1],
                a=at[k, :, 2],
                corners=corners[k],
                source=tr,
                braking=read[k][2],
            )
        )
    return out


class MoveCache:
    """The Ruckig moves of every rest-to-rest section already chained in one
    :func:`~planner.timing.time_path` call, and the phase tables already read.

    Why: a repair round re-times the whole path, but a blend shrunk at one corner changes
    only the section (between two stops) that holds it. A section's chain starts and ends at
    rest, so it is a function of the section alone: its vertices and blends (the key of its
    toppra profile, :func:`~planner.timing.toppra_method.section_key`), the profile's path
    velocities on it (exactly those of the earlier round when toppra took the section from
    its own cache), the limits and the speed factors. With the cache a round chains again
    only the sections its repair changed, so the work of all rounds is linear in the number
    of waypoints; a cached chain is the very chain of the earlier round, so nothing changes
    but the work.
    """

    def __init__(self) -> None:
        self._chains: dict[tuple, tuple[list[RuckigTrajectory], list[tuple[int, ...]]]] = {}
        self._rows: dict[int, tuple[list, list, bool]] = {}

    def chain(self, key: tuple) -> tuple[list[RuckigTrajectory], list[tuple[int, ...]]] | None:
        """The moves and their corners of a section chained before, or None."""
        return self._chains.get(key)

    def keep(
        self, key: tuple, trajs: list[RuckigTrajectory], corners: list[tuple[int, ...]]
    ) -> None:
        self._chains[key] = (trajs, corners)

    def rows(self, traj: RuckigTrajectory) -> tuple[list, list, bool]:
        """:func:`_phase_rows` of ``traj``, read once (the cache keeps ``traj`` alive)."""
        got = self._rows.get(id(traj))
        if got is None:
            got = self._rows[id(traj)] = _phase_rows(traj)
        return got


def _solve_duration(
    otg: Ruckig, inp: InputParameter, start: tuple, target: tuple
) -> RuckigTrajectory | None:
    """A candidate move of the greedy chain (:func:`_calculate`), None when Ruckig has none."""
    traj = RuckigTrajectory(3)
    return None if _calculate(otg, inp, start, target, traj) else traj


def _solve_move(
    otg: Ruckig, inp: InputParameter, start: tuple, target: tuple, corners: tuple[int, ...]
) -> _Move:
    """One Ruckig move from ``start`` to ``target`` (arrays or lists), as a :class:`_Move`.

    Raises
    ------
    TimingInfeasibleError
        Ruckig rejects the move or returns an error code.
    """
    start_lists, target_lists = (
        tuple(np.asarray(x, dtype=float).tolist() for x in st) for st in (start, target)
    )
    traj = RuckigTrajectory(3)
    error = _calculate(otg, inp, start_lists, target_lists, traj)
    if error:
        raise TimingInfeasibleError(error)
    return _moves_from([traj], [corners])[0]


def _reachable_acceleration(
    vel: np.ndarray, acc: np.ndarray, v_max: np.ndarray, a_max: np.ndarray, j_max: np.ndarray
) -> np.ndarray:
    """``acc`` shrunk (same direction, so phase synchronisation still applies) until the state
    is one a jerk-limited joint can pass through: ``|acc| <= a_max`` and
    ``|vel| + acc^2 / (2 j_max) <= v_max``. The second is the speed reached before the
    acceleration can be brought to zero (when it raises the speed, as a start state) or the
    speed it had when the acceleration was zero (when it lowers it, as a target state);
    Ruckig rejects a state beyond it, and every through-state is both.

    ``vel``, ``acc``: shape (..., 3), any number of states at once."""
    mag = np.abs(acc)
    room = np.maximum(v_max * _INSIDE - np.abs(vel), 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        per_joint = np.minimum(a_max * _INSIDE / mag, np.sqrt(2 * j_max * room) / mag)
    factor = np.min(np.where(mag > 0.0, per_joint, 1.0), axis=-1, initial=1.0)
    return acc * factor[..., None]


@dataclass(frozen=True, eq=False)
class RuckigCurve:
    """A chain of Ruckig moves, the first starting at t = 0.

    Attributes
    ----------
    moves : list of moves
    start : shape (K + 1,), s -- start time of each move, and the end.
    speed_bound : float, rad/s -- upper bound of |qd| (the norm of the velocity limits).
    """

    moves: list[_Move]
    start: np.ndarray
    speed_bound: float

    @property
    def duration(self) -> float:
        return float(self.start[-1])

    def move_index(self, t: np.ndarray) -> np.ndarray:
        """Index of the move active at each time (a boundary belongs to the later move)."""
        return np.clip(np.searchsorted(self.start, t, side="right") - 1, 0, len(self.moves) - 1)

    @functools.cached_property
    def _table(self) -> tuple[np.ndarray, ...]:
        """The moves' phase tables stacked, shape (K, 3, 8) or (K, 3, 7) (see
        :func:`_integrate`), plus ``braking`` (K,) and ``durations`` (K,)."""
        m = self.moves
        return (
            np.stack([x.cum for x in m]),
            np.stack([x.jerk for x in m]),
            np.stack([x.p for x in m]),
            np.stack([x.v for x in m]),
            np.stack([x.a for x in m]),
            np.array([x.braking for x in m]),
            np.array([x.duration for x in m]),
        )

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """q, qd, qdd, jerk at times t (M,), shapes (M, 3): every move's phase table at
        once (a braking move by Ruckig's ``at_time``, its jerk NaN)."""
        t = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), 0.0, self.duration)
        idx = self.move_index(t)
        *table, braking, durations = self._table
        tau = np.clip(t - self.start[idx], 0.0, durations[idx])
        q, qd, qdd, jerk = _integrate(tuple(table), idx, tau)
        for k in np.flatnonzero(braking):
            sel = idx == k
            if np.any(sel):
                q[sel], qd[sel], qdd[sel], jerk[sel] = _evaluate_with_ruckig(
                    self.moves[k].source, tau[sel]
                )
        return q, qd, qdd, jerk

    def rest_times(self) -> np.ndarray:
        """Move boundaries strictly inside the motion where it is at rest (the stops), s."""
        inner = self.start[1:-1]
        if inner.size == 0:
            return inner
        _, qd, _, _ = self.evaluate(inner)
        return inner[np.all(np.abs(qd) <= 1e-12, axis=1)]

    def check_times(self, resolution: float) -> np.ndarray:
        """Per move, a uniform grid with step ``resolution / V`` where V bounds |qd| during
        that move (:func:`_speed_bounds`; the norm of the velocity limits for a braking move),
        so consecutive postures are at most ``resolution`` apart; every move boundary is
        included."""
        _, jerk, _, v, a, braking, durations = self._table
        speed = np.where(braking, self.speed_bound, _speed_bounds(v, a, jerk))
        counts = np.maximum(2, np.ceil(durations * speed / resolution).astype(int) + 1)
        check_sample_count(int(np.sum(counts)))
        move = np.repeat(np.arange(len(self.moves)), counts)
        first = np.concatenate([[0], np.cumsum(counts)[:-1]])
        frac = (np.arange(move.shape[0]) - first[move]) / (counts[move] - 1)
        t = self.start[move] + frac * durations[move]
        return np.unique(np.concatenate([t, self.start]))

    def plan_segments(self, t: np.ndarray) -> np.ndarray:
        """A move through blends k..m stands for segments k-1..m; a rest-to-rest move
        (phase-synchronised: on its planned segment) for none (-1, -1)."""
        table = np.array(
            [[min(m.corners) - 1, max(m.corners)] if m.corners else [-1, -1] for m in self.moves]
        )
        return table[self.move_index(np.atleast_1d(t))]

    def corners_at(self, t: np.ndarray) -> list[tuple[int, ...]]:
        """For each time, the blends whose move covers it (empty: a rest-to-rest move)."""
        return [self.moves[k].corners for k in self.move_index(np.atleast_1d(t))]


def _through_marks(path: BlendedPath, profile: PathProfile, t_merge: float) -> list[tuple]:
    """Through-states in path order, as (s, tag, blends): a rest (``_REST``, no blend) at every
    stop, the entry and exit of every blend (``_ENTRY``, ``_EXIT``, with the blend's
    waypoint). A move between two states stands for the blends of both (and the segments
    around them: :meth:`RuckigCurve.plan_segments`).

    Two blends sharing a whole segment meet at one point: only the later one's entry is kept.
    A straight segment between two blends that toppra crosses in less than ``t_merge`` s gets
    one state at its middle (``_MIDDLE``, with both blends) instead of the exit and the entry,
    so that the moves into and out of it stand for both blends and the segment: toppra
    accelerates hard out of the first blend and brakes hard into the next, and a joint under
    a jerk limit cannot follow such a swing in so short a time (Ruckig then needs a move many
    times longer than toppra's, measured up to 30x), while it can pass a single state."""
    marks: list[tuple[float, int, tuple[int, ...]]] = []
    for k in range(path.n_pieces):
        if path.kind[k] == ARC:
            marks.append((float(path.s0[k]), _ENTRY, (int(path.corner[k]),)))
            marks.append((float(path.s0[k + 1]), _EXIT, (int(path.corner[k]),)))
    marks += [(float(s), _REST, ()) for s in path.stops]
    marks.sort(key=lambda m: (m[0], m[1] != _EXIT, m[1]))  # an exit before a coinciding entry
    marks = [
        m
        for i, m in enumerate(marks)
        if not (m[1] == _EXIT and i + 1 < len(marks) and marks[i + 1][0] <= m[0])
    ]
    # consecutive rests at one position (a stop at the path's end) are one
    marks = [
        m
        for i, m in enumerate(marks)
        if not (i > 0 and m[1] == _REST and marks[i - 1][1] == _REST and m[0] <= marks[i - 1][0])
    ]
    t_marks, _, _ = profile.at_path(np.array([m[0] for m in marks]))
    out: list[tuple[float, int, tuple[int, ...]]] = []
    i = 0
    while i < len(marks):
        m = marks[i]
        if (
            m[1] == _EXIT
            and i + 1 < len(marks)
            and marks[i + 1][1] == _ENTRY
            and t_marks[i + 1] - t_marks[i] < t_merge
        ):
            out.append((0.5 * (m[0] + marks[i + 1][0]), _MIDDLE, m[2] + marks[i + 1][2]))
            i += 2
            continue
        out.append(m)
        i += 1
    return out


def build_ruckig_curve(
    path: BlendedPath,
    profile: PathProfile,
    limits: JointLimits,
    *,
    through_acceleration: bool = True,
    speed_factors: tuple[float, ...] = SPEED_FACTORS,
    deadline: float | None = None,
    cache: MoveCache | None = None,
) -> RuckigCurve:
    """Chain Ruckig moves through the entry and exit states of every blend (module docstring).

    Parameters
    ----------
    path : BlendedPath
    profile : PathProfile
        The toppra profile of ``path`` under the same velocity and acceleration limits (it
        gives the through-states; it need not meet the limits between its grid points, the
        states are pulled inside the limits here).
    limits : JointLimits
        With ``jerk`` set.
    through_acceleration : bool
        Give each through-state toppra's tangential acceleration (True) or zero.
    speed_factors : candidate slow-downs of each through-state, tried greedily in order.
    deadline : float, optional
        ``time.monotonic()`` value checked every 16 moves.
    cache : MoveCache, optional
        Sections chained earlier in the same timing (see :class:`MoveCache`); a fresh one
        when absent.

    Measured on seeded random 20-waypoint paths (``benchmarks/timing.py``): resting at every
    waypoint costs about 1.45x (jerk = 25 x acceleration /s) to 1.65x (10x) the toppra duration;
    these through-states cost about 1.1x and 1.3x, with a deviation from the polyline close to
    the blend size. Extra through-states inside the arcs were tried and made it worse (a
    rapidly turning toppra acceleration cannot be tracked under a jerk limit); so is a short
    segment's pair of states, which is why it becomes one (:func:`_through_marks`).

    Raises
    ------
    TimingInfeasibleError
        Ruckig rejects a move (``RuckigError``) or returns an error code.
    """
    v_max = limits.velocity_array
    otg, inp = Ruckig(3), _ruckig_input(limits)
    cache = cache if cache is not None else MoveCache()
    settings = (
        *v_max.tolist(),
        *limits.acceleration_array.tolist(),
        *limits.jerk_array.tolist(),  # type: ignore[union-attr]
        through_acceleration,
        *speed_factors,
    )
    states = _through_states(path, profile, limits, through_acceleration, speed_factors)
    # Section by section (rest to rest): a section chained in an earlier round of the same
    # timing, with the same profile on it, is taken from the cache (:class:`MoveCache`).
    trajs: list[RuckigTrajectory] = []
    corners: list[tuple[int, ...]] = []
    rests = np.flatnonzero(states.tags == _REST)
    for r0, r1 in itertools.pairwise(rests):
        lo, hi = states.s[r0], states.s[r1]
        inside = (profile.s >= lo) & (profile.s <= hi)
        key = (section_key(path, lo, hi), profile.sd[inside].tobytes(), settings)
        got = cache.chain(key)
        if got is None:
            got = _chain_section(otg, inp, states, int(r0), int(r1), deadline)
            cache.keep(key, *got)
        trajs += got[0]
        corners += got[1]
    moves = _moves_from(trajs, corners, cache)
    start = np.concatenate([[0.0], np.cumsum([m.duration for m in moves])])
    return RuckigCurve(moves, start, float(np.linalg.norm(v_max)))


def _ruckig_input(limits: JointLimits) -> InputParameter:
    """Ruckig's input of three joints under ``limits`` (velocity, acceleration, jerk), with
    phase synchronisation (a move between states parallel to a segment stays on it)."""
    inp = InputParameter(3)
    inp.max_velocity = limits.velocity_array.tolist()
    inp.max_acceleration = limits.acceleration_array.tolist()
    inp.max_jerk = limits.jerk_array.tolist()  # type: ignore[union-attr]
    inp.synchronization = Synchronization.Phase
    return inp


@dataclass(frozen=True, eq=False)
class _ThroughStates:
    """The through-states of a chain (:func:`_through_states`): per mark (in path order),
    its (s, tag, blends) of :func:`_through_marks`, its s (rad) and tag as arrays, and its
    posture, velocities and accelerations at every speed factor (nested lists, as Ruckig
    takes them: ``vel[i][k]`` of mark i at factor index k)."""

    marks: list[tuple[float, int, tuple[int, ...]]]
    s: np.ndarray
    tags: np.ndarray
    q: list
    vel: list
    acc: list
    n_factors: int

    def state(self, i: int, k: int) -> tuple[list, list, list]:
        """Through-state i at speed factor index k, as lists for Ruckig."""
        if self.tags[i] == _REST:
            return self.q[i], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
        return self.q[i], self.vel[i][k], self.acc[i][k]


def _through_states(
    path: BlendedPath,
    profile: PathProfile,
    limits: JointLimits,
    through_acceleration: bool,
    speed_factors: tuple[float, ...],
) -> _ThroughStates:
    """The first step of :func:`build_ruckig_curve`: the marks of :func:`_through_marks`
    and their states from the toppra ``profile`` at every speed factor."""
    v_max = limits.velocity_array
    a_max = limits.acceleration_array
    j_max: np.ndarray = limits.jerk_array  # type: ignore[assignment]
    # the time a joint needs to bring its largest acceleration to zero under its jerk limit
    marks = _through_marks(path, profile, t_merge=float(np.max(a_max / j_max)))
    s_marks = np.array([m[0] for m in marks])
    tags = np.array([m[1] for m in marks])
    q = path.evaluate(s_marks, 0)
    tangent = path.evaluate(s_marks, 1)
    tangent_left = path.evaluate(s_marks, 1, side="left")
    _, sd, sdd_right = profile.at_path(s_marks)
    _, _, sdd_left = profile.at_path(np.maximum(s_marks - 1e-9 * max(path.length, 1.0), 0.0))

    # Every through-state at every speed factor at once, shape (marks, factors, 3): toppra's
    # velocity times f (clipped inside the limits) and its acceleration times f^2, made
    # reachable. An entry's straight side is before it, an exit's (and a middle's) after.
    entry = tags == _ENTRY
    direction = np.where(entry[:, None], tangent_left, tangent)
    acc_s = np.where(entry, sdd_left, sdd_right)
    f = np.asarray(speed_factors, dtype=float)[None, :, None]
    vel = np.clip((direction * sd[:, None])[:, None, :] * f, -v_max * _INSIDE, v_max * _INSIDE)
    acc = (direction * acc_s[:, None])[:, None, :] * f**2
    if not through_acceleration:
        acc = np.zeros_like(acc)
    acc = _reachable_acceleration(vel, acc, v_max, a_max, j_max)
    return _ThroughStates(
        marks, s_marks, tags, q.tolist(), vel.tolist(), acc.tolist(), len(speed_factors)
    )


def _chain_section(
    otg: Ruckig,
    inp: InputParameter,
    states: _ThroughStates,
    r0: int,
    r1: int,
    deadline: float | None,
) -> tuple[list[RuckigTrajectory], list[tuple[int, ...]]]:
    """The greedy chain from the rest state r0 to the rest state r1: its moves, and the
    blends each stands for."""
    # Greedy speed choice per through-state. A joint at its velocity limit cannot stretch
    # its move to a longer common duration (Ruckig's blocked intervals), which can make a
    # synchronised move several times longer than each joint's own minimum; a slightly
    # slower through-state avoids that. For each state, the factor minimising the move into it
    # plus the move out of it (towards the next state at the second slowest factor) is kept;
    # slower factors stop being tried after PATIENCE worse ones. Candidate moves are solved
    # for their durations only (:func:`_calculate`); the phase tables are read from the
    # chosen ones.
    n_f, marks, state = states.n_factors, states.marks, states.state
    ahead_k = max(n_f - 2, 0)  # the look-ahead's factor (the second slowest)
    chosen = state(r0, 0)
    trajs: list[RuckigTrajectory] = []
    corners: list[tuple[int, ...]] = []
    known: RuckigTrajectory | None = None  # the chosen state's look-ahead move, reused
    for i in range(r0 + 1, r1 + 1):
        if i % 16 == 0:
            check_deadline(deadline, "while timing the path with ruckig")
        moving = states.tags[i] != _REST
        look_ahead = moving and n_f > 1 and i + 1 < len(marks)
        best: tuple[float, RuckigTrajectory, tuple, RuckigTrajectory | None] | None = None
        worse = 0
        for k in range(n_f if moving else 1):
            target = state(i, k)
            if known is not None and k == ahead_k:
                traj, known = known, None  # solved as the previous state's look-ahead
            else:
                traj = _solve_duration(otg, inp, chosen, target)
                if traj is None:
                    continue
            cost = traj.duration
            ahead: RuckigTrajectory | None = None
            if look_ahead:
                ahead = _solve_duration(otg, inp, target, state(i + 1, ahead_k))
                cost = np.inf if ahead is None else cost + ahead.duration
            if best is None or cost < best[0]:
                best, worse = (cost, traj, target, ahead), 0
            elif best[0] < cost < np.inf:
                worse += 1
                if worse >= PATIENCE:
                    break
        if best is None:
            raise TimingInfeasibleError(
                f"ruckig found no move into the through-state at s = {states.s[i]:.4g} rad"
            )
        corners.append(tuple(sorted(set(marks[i - 1][2]) | set(marks[i][2]))))
        trajs.append(best[1])
        chosen, known = best[2], best[3]
    return trajs, corners
