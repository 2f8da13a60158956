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
* stops (path start and end, requested stops, unblended corners) are reached at rest, and a
  rest-to-rest move with phase synchronisation is the straight segment itself.

The moves meet with equal position, velocity and acceleration, so q, qd and qdd are
continuous. Position limits are not in the community version: the caller checks joint limits.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, RuckigError, Synchronization
from ruckig import Trajectory as RuckigTrajectory

from planner.exceptions import TimingInfeasibleError
from planner.timing.limits import JointLimits
from planner.timing.path import ARC, BlendedPath
from planner.timing.toppra_method import PathProfile, check_deadline
from planner.timing.trajectory import check_sample_count

__all__ = ["RuckigCurve", "build_ruckig_curve"]

logger = logging.getLogger(__name__)

#: Target states are pulled this far inside the limits (relative): toppra meets its limits
#: to within solver tolerance, Ruckig rejects a target even 1 ulp beyond.
_INSIDE = 1.0 - 1e-9
#: Candidate slow-downs of each through-state's toppra velocity (see build_ruckig_curve).
SPEED_FACTORS = (1.0, 0.9, 0.8, 0.7, 0.6, 0.5)


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
        """Upper bound of |qd| during the move, rad/s: per joint, the largest |velocity| at a
        phase boundary or where the acceleration crosses zero inside a phase (velocity is
        quadratic in time within a constant-jerk phase); ``fallback`` for a braking move."""
        if self.braking:
            return fallback
        v0, v1 = np.abs(self.v[:, :-1]), np.abs(self.v[:, 1:])
        a0, a1 = self.a[:, :-1], self.a[:, 1:]
        crosses = (a0 * a1 < 0) & (self.jerk != 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            v_turn = np.where(crosses, np.abs(self.v[:, :-1] - a0**2 / (2 * self.jerk)), 0.0)
        per_joint = np.max(np.maximum(np.maximum(v0, v1), v_turn), axis=1)
        return float(np.linalg.norm(per_joint))

    def evaluate(self, tau: np.ndarray) -> tuple[np.ndarray, ...]:
        """q, qd, qdd, jerk at local times tau (M,) in [0, duration], shapes (M, 3)."""
        tau = np.clip(tau, 0.0, self.duration)
        if self.braking:
            rows = [self.source.at_time(float(x)) for x in tau]
            q = np.array([r[0] for r in rows])
            qd = np.array([r[1] for r in rows])
            qdd = np.array([r[2] for r in rows])
            return q, qd, qdd, np.full_like(q, np.nan)
        out = [np.empty((tau.shape[0], 3)) for _ in range(4)]
        for d in range(3):
            k = np.clip(np.searchsorted(self.cum[d], tau, side="right") - 1, 0, 6)
            x = tau - self.cum[d, k]
            j, a, v = self.jerk[d, k], self.a[d, k], self.v[d, k]
            out[0][:, d] = self.p[d, k] + x * (v + x * (a / 2 + x * j / 6))
            out[1][:, d] = v + x * (a + x * j / 2)
            out[2][:, d] = a + x * j
            out[3][:, d] = j
        return tuple(out)


def _solve_move(
    otg: Ruckig, inp: InputParameter, start: tuple, target: tuple, corners: tuple[int, ...]
) -> _Move:
    inp.current_position, inp.current_velocity, inp.current_acceleration = (
        np.asarray(x, dtype=float).tolist() for x in start
    )
    inp.target_position, inp.target_velocity, inp.target_acceleration = (
        np.asarray(x, dtype=float).tolist() for x in target
    )
    traj = RuckigTrajectory(3)
    try:
        result = otg.calculate(inp, traj)
    except RuckigError as exc:
        raise TimingInfeasibleError(f"ruckig rejected a move: {str(exc).strip()}") from exc
    if result not in (Result.Working, Result.Finished):
        raise TimingInfeasibleError(f"ruckig found no move: {result}")
    profiles = traj.profiles[0]
    cum = np.array([np.concatenate([[0.0], np.cumsum(pr.t)]) for pr in profiles])
    braking = any(pr.brake.duration > 0 or pr.accel.duration > 0 for pr in profiles)
    return _Move(
        duration=float(traj.duration),
        cum=cum,
        jerk=np.array([pr.j for pr in profiles]),
        p=np.array([pr.p for pr in profiles]),
        v=np.array([pr.v for pr in profiles]),
        a=np.array([pr.a for pr in profiles]),
        corners=corners,
        source=traj,
        braking=braking,
    )


def _reachable_acceleration(
    vel: np.ndarray, acc: np.ndarray, v_max: np.ndarray, a_max: np.ndarray, j_max: np.ndarray
) -> np.ndarray:
    """``acc`` shrunk (same direction, so phase synchronisation still applies) until the state
    is one a jerk-limited joint can pass through: ``|acc| <= a_max`` and
    ``|vel| + acc^2 / (2 j_max) <= v_max``. The second is the speed reached before the
    acceleration can be brought to zero (when it raises the speed, as a start state) or the
    speed it had when the acceleration was zero (when it lowers it, as a target state);
    Ruckig rejects a state beyond it, and every through-state is both."""
    factor = 1.0
    for d in range(3):
        if acc[d] == 0.0:
            continue
        factor = min(factor, a_max[d] * _INSIDE / abs(acc[d]))
        room = max(v_max[d] * _INSIDE - abs(vel[d]), 0.0)
        factor = min(factor, float(np.sqrt(2 * j_max[d] * room)) / abs(acc[d]))
    return acc * factor


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

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        t = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), 0.0, self.duration)
        idx = self.move_index(t)
        out = [np.empty((t.shape[0], 3)) for _ in range(4)]
        for k in np.unique(idx):
            sel = idx == k
            vals = self.moves[k].evaluate(t[sel] - self.start[k])
            for o, v in zip(out, vals, strict=True):
                o[sel] = v
        return out[0], out[1], out[2], out[3]

    def rest_times(self) -> np.ndarray:
        """Move boundaries strictly inside the motion where it is at rest (the stops), s."""
        inner = self.start[1:-1]
        if inner.size == 0:
            return inner
        _, qd, _, _ = self.evaluate(inner)
        return inner[np.all(np.abs(qd) <= 1e-12, axis=1)]

    def check_times(self, resolution: float) -> np.ndarray:
        """Per move, a uniform grid with step ``resolution / V`` where V bounds |qd| during
        that move (:meth:`_Move.speed_bound`), so consecutive postures are at most
        ``resolution`` apart; every move boundary is included."""
        counts = [
            max(2, int(np.ceil(m.duration * m.speed_bound(self.speed_bound) / resolution)) + 1)
            for m in self.moves
        ]
        check_sample_count(sum(counts))
        parts = [np.linspace(self.start[k], self.start[k + 1], n) for k, n in enumerate(counts)]
        return np.unique(np.concatenate([*parts, self.start]))

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


def build_ruckig_curve(
    path: BlendedPath,
    profile: PathProfile,
    limits: JointLimits,
    *,
    through_acceleration: bool = True,
    speed_factors: tuple[float, ...] = SPEED_FACTORS,
    deadline: float | None = None,
) -> RuckigCurve:
    """Chain Ruckig moves through the entry and exit states of every blend (module docstring).

    Parameters
    ----------
    path : BlendedPath
    profile : PathProfile
        The toppra profile of ``path`` under the same velocity and acceleration limits.
    limits : JointLimits
        With ``jerk`` set.
    through_acceleration : bool
        Give each through-state toppra's tangential acceleration (True) or zero.
    speed_factors : candidate slow-downs of each through-state, tried greedily.
    deadline : float, optional
        ``time.monotonic()`` value checked every 16 moves.

    Measured on seeded random 20-waypoint paths (``benchmarks/timing.py``): resting at every
    waypoint costs about 1.45x (jerk = 25 x acceleration /s) to 1.65x (10x) the toppra duration;
    these through-states cost about 1.1x and 1.3x, with a deviation from the polyline close to
    the blend size. Extra through-states inside the arcs were tried and made it worse (a
    rapidly turning toppra acceleration cannot be tracked under a jerk limit).

    Raises
    ------
    TimingInfeasibleError
        Ruckig rejects a move (``RuckigError``) or returns an error code.
    """
    v_max = limits.velocity_array
    a_max = limits.acceleration_array
    otg = Ruckig(3)
    inp = InputParameter(3)
    inp.max_velocity = v_max.tolist()
    inp.max_acceleration = a_max.tolist()
    j_max: np.ndarray = limits.jerk_array  # type: ignore[assignment]
    inp.max_jerk = j_max.tolist()
    inp.synchronization = Synchronization.Phase

    # Through-states in path order: (s, tag, corner); tag 0 rest, 1 entry, 2 exit.
    marks: list[tuple[float, int, int]] = []
    stops = path.stops
    for k in range(path.n_pieces):
        if path.kind[k] == ARC:
            marks.append((float(path.s0[k]), 1, int(path.corner[k])))
            marks.append((float(path.s0[k + 1]), 2, int(path.corner[k])))
    marks += [(float(s), 0, -1) for s in stops]
    marks.sort(key=lambda m: (m[0], m[1] != 2, m[1]))  # an exit before a coinciding entry
    # Two blends sharing a whole segment meet at one point: keep only the later one's entry.
    marks = [
        m
        for i, m in enumerate(marks)
        if not (m[1] == 2 and i + 1 < len(marks) and marks[i + 1][0] <= m[0])
    ]

    s_marks = np.array([m[0] for m in marks])
    q = path.evaluate(s_marks, 0)
    tangent = path.evaluate(s_marks, 1)
    tangent_left = path.evaluate(s_marks, 1, side="left")
    _, sd, sdd_right = profile.at_path(s_marks)
    _, _, sdd_left = profile.at_path(np.maximum(s_marks - 1e-9 * max(path.length, 1.0), 0.0))

    # Each through-state at full toppra speed, and its velocity direction and acceleration.
    base: list[tuple[np.ndarray, np.ndarray, np.ndarray] | None] = []
    for i, (_, tag, _) in enumerate(marks):
        if tag == 0:
            base.append(None)
            continue
        # Entry: straight side is before; exit: after. The tangent is continuous there.
        direction = tangent_left[i] if tag == 1 else tangent[i]
        acc_s = sdd_left[i] if tag == 1 else sdd_right[i]
        acc = direction * acc_s if through_acceleration else np.zeros(3)
        base.append((q[i], direction * sd[i], acc))

    def state(i: int, f: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Through-state i slowed by f: velocity times f, acceleration times f^2."""
        if base[i] is None:
            zero = np.zeros(3)
            return q[i], zero, zero
        qi, vel, acc = base[i]  # type: ignore[misc]
        vel = np.clip(vel * f, -v_max * _INSIDE, v_max * _INSIDE)
        return qi, vel, _reachable_acceleration(vel, acc * f**2, v_max, a_max, j_max)

    # Greedy speed choice per through-state. A joint at its velocity limit cannot stretch
    # its move to a longer common duration (Ruckig's blocked intervals), which can make a
    # synchronised move several times longer than each joint's own minimum; a slightly
    # slower through-state avoids that. For each state, the factor minimising the move into it
    # plus the move out of it (towards the next state at a middle factor) is kept.
    keep = [i for i in range(len(marks))
            if not (i > 0 and marks[i][1] == 0 and marks[i - 1][1] == 0
                    and s_marks[i] <= s_marks[i - 1])]  # fmt: skip
    chosen = {keep[0]: state(keep[0], 1.0)}
    moves: list[_Move] = []
    for pos in range(1, len(keep)):
        if pos % 16 == 0:
            check_deadline(deadline, "while timing the path with ruckig")
        i, prev = keep[pos], keep[pos - 1]
        nxt = keep[pos + 1] if pos + 1 < len(keep) else None
        (_, tag0, c0), (_, tag1, c1) = marks[prev], marks[i]
        corners = tuple(sorted({c for c, tag in ((c0, tag0), (c1, tag1)) if tag != 0}))
        factors = (1.0,) if base[i] is None else speed_factors
        best: tuple[float, _Move, tuple] | None = None
        for f in factors:
            target = state(i, f)
            try:
                move = _solve_move(otg, inp, chosen[prev], target, corners)
            except TimingInfeasibleError:
                continue
            cost = move.duration
            if nxt is not None and len(factors) > 1:
                try:
                    ahead = _solve_move(otg, inp, target, state(nxt, speed_factors[-2]), ())
                    cost += ahead.duration
                except TimingInfeasibleError:
                    cost = np.inf
            if best is None or cost < best[0]:
                best = (cost, move, target)
        if best is None:
            raise TimingInfeasibleError(
                f"ruckig found no move into the through-state at s = {s_marks[i]:.4g} rad"
            )
        moves.append(best[1])
        chosen[i] = best[2]
    start = np.concatenate([[0.0], np.cumsum([m.duration for m in moves])])
    return RuckigCurve(moves, start, float(np.linalg.norm(v_max)))
