"""Time-optimal moves between two joint states (position, velocity, acceleration): the moves
into and out of a moving target's tracking span (:mod:`planner.sequence.moving`).

A conveyor pick meets the part at speed: the tool arrives on the part's posture with the
part's velocity (and, jerk-limited, its acceleration), and leaves it at speed. Those two ends
are states, not rests, so the path timings (toppra on a blended path, Ruckig through a path's
states) do not apply; each is one Ruckig move, time-optimal and synchronised over the three
joints, as the via chains of :mod:`planner.timing.vias` are: second-order (acceleration-
limited, jerk unbounded: the limits toppra times under) for ``toppra``, jerk-limited for
``ruckig``. A move is a :class:`~planner.timing.ruckig_method.RuckigCurve` of one move, so it
is evaluated, sampled and densely re-checked as any Ruckig trajectory.

Ruckig lives here (the timing's room); the sequence asks only for durations and curves.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from ruckig import ControlInterface, InputParameter, Result, Ruckig, RuckigError
from ruckig import Trajectory as RuckigTrajectory

from planner.timing.limits import JointLimits
from planner.timing.ruckig_method import RuckigCurve, _moves_from, _phase_rows

__all__ = ["StateMover", "position_extrema"]

#: A state a move cannot reach (Ruckig refuses it) costs this much, s.
REFUSED = math.inf

#: A joint state (q, qd, qdd): 3 numbers each (rad, rad/s, rad/s^2), lists or arrays.
_State = tuple[
    Sequence[float] | np.ndarray, Sequence[float] | np.ndarray, Sequence[float] | np.ndarray
]


def position_extrema(traj: RuckigTrajectory) -> tuple[np.ndarray, np.ndarray] | None:
    """The least and largest position of each joint over a solved move, rad, (3,) each:
    from its phase table, the ends of every phase and wherever the velocity (a quadratic in
    time within a constant-jerk phase) crosses zero inside one. Ruckig's own
    ``position_extrema`` is wrong for second-order moves (unbounded jerk: it gave the start
    as the largest position of a joint that overshot it by 0.09 rad). None for a move with a
    brake phase (its table does not hold it)."""
    rows, states, braking = _phase_rows(traj)
    if braking:
        return None
    lo, hi = np.empty(3), np.empty(3)
    for j in range(3):  # plain floats: a move has 21 phases, numpy's overhead would dominate
        (dts, jks), (ps, vs, accs) = rows[j], states[j]
        low = high = float(ps[0])
        for k in range(7):
            dt, p, v, a = float(dts[k]), float(ps[k]), float(vs[k]), float(accs[k])
            jk = float(jks[k]) if math.isfinite(jks[k]) else 0.0
            low, high = min(low, float(ps[k + 1])), max(high, float(ps[k + 1]))
            if dt <= 0.0:
                continue
            for x in _velocity_zeros(v, a, jk):
                if 0.0 < x < dt:
                    pos = p + x * (v + x * (a / 2 + x * jk / 6))
                    low, high = min(low, pos), max(high, pos)
        lo[j], hi[j] = low, high
    return lo, hi


def _velocity_zeros(v: float, a: float, jk: float) -> tuple[float, ...]:
    """The times x where v + a x + jk x^2 / 2 = 0."""
    if jk == 0.0:
        return (-v / a,) if a != 0.0 else ()
    disc = a * a - 2.0 * jk * v
    if disc < 0.0:
        return ()
    r = math.sqrt(disc)
    return ((-a + r) / jk, (-a - r) / jk)


class StateMover:
    """Ruckig moves between joint states under ``limits``; ``jerk``: jerk-limited (the
    ``ruckig`` method) or second-order (``toppra``: acceleration-limited, the target
    acceleration then free and set to 0, where toppra's acceleration may jump as well).

    The states are (q, qd, qdd), 3 numbers each (rad, rad/s, rad/s^2)."""

    def __init__(self, limits: JointLimits, *, jerk: bool) -> None:
        # ruckig's moves are jerk-limited: by the asked jerk, else RUCKIG_DEFAULT_JERK (as
        # time_path's ruckig method); toppra's are second order
        self.limits = limits.with_ruckig_jerk() if jerk else limits
        self.jerk = jerk
        limits = self.limits
        self.otg = Ruckig(3)
        self.inp = InputParameter(3)
        self.inp.max_velocity = limits.velocity_array.tolist()
        self.inp.max_acceleration = limits.acceleration_array.tolist()
        j = limits.jerk_array if self.jerk else None
        self.inp.max_jerk = [math.inf] * 3 if j is None else j.tolist()
        self.calls = 0

    def _solve(self, a: _State, b: _State | None) -> RuckigTrajectory | None:
        """The move from state ``a`` to state ``b`` (None: to rest anywhere, as fast as the
        limits allow: Ruckig's velocity interface)."""
        inp = self.inp
        zero = [0.0, 0.0, 0.0]
        inp.current_position = [float(x) for x in a[0]]
        inp.current_velocity = [float(x) for x in a[1]]
        inp.current_acceleration = [float(x) for x in a[2]] if self.jerk else zero
        if b is None:
            inp.control_interface = ControlInterface.Velocity
            inp.target_position = list(inp.current_position)
            inp.target_velocity, inp.target_acceleration = zero, zero
        else:
            inp.control_interface = ControlInterface.Position
            inp.target_position = [float(x) for x in b[0]]
            inp.target_velocity = [float(x) for x in b[1]]
            inp.target_acceleration = [float(x) for x in b[2]] if self.jerk else zero
        self.calls += 1
        traj = RuckigTrajectory(3)
        try:
            result = self.otg.calculate(inp, traj)
        except RuckigError:
            return None
        return traj if result in (Result.Working, Result.Finished) else None

    def duration(
        self, a: _State, b: _State | None, bounds: tuple[np.ndarray, np.ndarray] | None = None
    ) -> float:
        """The least time of a move from ``a`` to ``b`` (None: to rest), s; ``inf`` when
        Ruckig has none (a state outside the limits) or, with ``bounds`` (lo, hi: rad per
        joint), when the move leaves them (a move that arrives or leaves at speed may
        overshoot its ends: :func:`position_extrema`)."""
        traj = self._solve(a, b)
        if traj is None:
            return REFUSED
        if bounds is not None:
            ext = position_extrema(traj)
            if ext is not None and (
                np.any(ext[0] < bounds[0] - 1e-9) or np.any(ext[1] > bounds[1] + 1e-9)
            ):
                return REFUSED
        return float(traj.duration)

    def curve(self, a: _State, b: _State | None) -> RuckigCurve | None:
        """The move as a curve on [0, its duration] (None when Ruckig has none)."""
        traj = self._solve(a, b)
        if traj is None:
            return None
        moves = _moves_from([traj], [()])
        start = np.array([0.0, float(traj.duration)])
        return RuckigCurve(moves, start, float(np.linalg.norm(self.limits.velocity_array)))
