"""Where and when to meet a part on a belt, in one working mode: the interception search of
:mod:`planner.sequence.moving`.

The robot rests at ``q_s`` from sequence time ``t_s`` (the previous target, or a staging
posture in the mode). Meeting the part at time t means: a time-optimal move from rest at
``q_s`` into the tracking state at t (:class:`planner.timing.state_moves.StateMover`), after
waiting at rest for whatever time is left; the tracking span [t, t + dwell]
(:class:`planner.sequence.belt.TrackingCurve`); a time-optimal move from the state at
t + dwell to rest at the landing posture (the next target, or anywhere for a last target). So
with T_app(t) and T_dep(t) those moves' least durations:

* t is feasible when the span is trackable (reached, valid, within the joint, velocity and
  acceleration limits at every scanned sample), t_s + T_app(t) <= t, and neither move
  leaves the joint limits (a move that arrives or leaves at speed may overshoot its ends:
  Ruckig's position extrema say by how much);
* ``objective="time"`` minimises the time at rest at the landing, c(t) = t + dwell + T_dep(t)
  (waiting at rest is always allowed, so arriving earlier at a rest posture never delays
  what follows); ``objective="fixed"`` meets as early as possible, c(t) = t.

The search (:func:`intercept`): c and the feasibility on a grid of :data:`GRID` meeting
times over the part's trackable window after t_s (each point two Ruckig solves, microseconds),
then refined around the best grid point: the earliest feasible time by repeated sectioning
when the point before it is infeasible (the optimum sits on that boundary whenever T_dep falls more
slowly than time passes), and a zoom on c between the grid neighbours (finer grids, each
round on the best point's neighbours). The
candidates are kept in order of cost, so that the caller can verify them by their real
curves and dense re-checks in turn (:meth:`Interception.build`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.design import Design
from planner.sequence.belt import PartPath, TrackingCurve, ik_in_mode, shift_near, track_states
from planner.sequence.problem import MovingTarget
from planner.timing.checks import CheckReport, dense_check
from planner.timing.limits import JointLimits
from planner.timing.ruckig_method import RuckigCurve
from planner.timing.state_moves import StateMover
from planner.timing.torque import TorqueModel
from planner.validity import ValidityChecker

__all__ = ["GRID", "BuiltPick", "Interception", "Meeting", "intercept"]

#: Meeting times per mode on the search's coarse grid: at least this many, at most
#: :data:`MAX_GRID_STEP_S` apart, and :data:`WINDOW_POINTS` in each trackable window (the
#: feasible meetings of a window can be a few tens of ms wide: where the part is about to
#: leave, the robot just arrives; one case of 50 lost 59 % to a coarser grid).
GRID = 48
MAX_GRID_STEP_S = 0.02
WINDOW_POINTS = 16
#: The refinements around the best grid point cut an interval into this many parts, this
#: many times (the grid step / 256: under 0.1 ms).
ZOOM = 16
ZOOMS = 2
#: Joint-space resolution of the dense re-check of the moves and the span, rad (the timing's).
CHECK_RESOLUTION = 0.01


@dataclass(frozen=True, slots=True)
class Meeting:
    """One candidate meeting: time ``t`` (s, sequence time) and its cost (s)."""

    t: float
    cost: float


@dataclass(frozen=True, eq=False)
class BuiltPick:
    """The verified curves of one meeting: a wait at rest (``hold`` s), the approach move,
    the tracking span and the departure move; ``report`` the failing check, or None."""

    meeting: Meeting
    hold: float
    approach: RuckigCurve
    tracking: TrackingCurve
    departure: RuckigCurve
    report: CheckReport | None

    @property
    def ok(self) -> bool:
        return self.report is None


@dataclass(eq=False)
class Interception:
    """The search's context for one moving target in one working mode (module docstring)."""

    design: Design
    target: MovingTarget
    dwell: float
    checker: ValidityChecker
    limits: JointLimits
    mover: StateMover
    path: PartPath
    q_s: np.ndarray
    t_s: float
    landing: np.ndarray | None
    objective: str = "time"
    evaluations: int = 0

    @property
    def mode(self) -> str:
        return self.checker.working_mode

    def tracking(self, t: float) -> TrackingCurve:
        """The tracking span from meeting time ``t``, whole turns as the scanned path's."""
        p = self.path
        ref = np.array([np.interp(t, p.t, p.q[:, j]) for j in range(3)])
        q = ik_in_mode(self.design, self.target.at(t), self.mode, self.checker.assembly_mode)[0]
        q_meet = shift_near(q[None], ref[None])[0]
        speed = float(np.linalg.norm(self.limits.velocity_array))
        return TrackingCurve(
            self.design,
            self.target,
            self.mode,
            self.checker.assembly_mode,
            t,
            self.dwell,
            q_meet,
            speed,
        )

    def _rest(self, q: np.ndarray) -> tuple:
        return (q, np.zeros(3), np.zeros(3))

    def _states(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """The tracking states at the meetings ``t`` (M,) and at the leaves ``t + dwell``,
        (q, qd, qdd) each (2M, 3), meetings first (one inverse-kinematics call)."""
        p = self.path
        both = np.concatenate([t, t + self.dwell])
        ref = np.stack([np.interp(both, p.t, p.q[:, j]) for j in range(3)], axis=1)
        q, qd, qdd, _ = track_states(
            self.design, self.target, self.mode, self.checker.assembly_mode, both, ref
        )
        return q, qd, qdd

    def costs(self, t: np.ndarray) -> np.ndarray:
        """c(t) at each meeting time (module docstring), ``inf`` where t is not feasible."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        self.evaluations += t.shape[0]
        out = np.full(t.shape[0], math.inf)
        ok = [bool(x >= self.t_s and self.path.trackable(float(x), self.dwell)) for x in t]
        if not any(ok):
            return out
        q, qd, qdd = self._states(t)
        m = t.shape[0]
        start = self._rest(self.q_s)
        end = None if self.landing is None else self._rest(self.landing)
        bounds = (np.asarray(self.design.joint_min), np.asarray(self.design.joint_max))
        for k in np.flatnonzero(ok):
            if not np.all(np.isfinite(q[k])) or not np.all(np.isfinite(q[m + k])):
                continue
            t_app = self.mover.duration(start, (q[k], qd[k], qdd[k]), bounds)
            if self.t_s + t_app > t[k] + 1e-12:
                continue
            if self.objective == "fixed":
                out[k] = t[k]
                continue
            leave = (q[m + k], qd[m + k], qdd[m + k])
            out[k] = t[k] + self.dwell + self.mover.duration(leave, end, bounds)
        return out

    def cost(self, t: float) -> float:
        """c(t) at one meeting time."""
        return float(self.costs(np.array([t]))[0])

    def build(
        self, meeting: Meeting, *, torque: TorqueModel | None, v_cart: float | None
    ) -> BuiltPick | None:
        """The real curves of ``meeting``, each re-checked densely (validity in the mode,
        joint limits, assembly, the velocity, acceleration, jerk, tool-speed and torque
        limits); None when Ruckig has no move."""
        tr = self.tracking(meeting.t)
        meet, leave = tr.state(0.0), tr.state(self.dwell)
        approach = self.mover.curve(self._rest(self.q_s), meet)
        end = None if self.landing is None else self._rest(self.landing)
        departure = self.mover.curve(leave, end)
        if approach is None or departure is None:
            return None
        hold = max(meeting.t - approach.duration - self.t_s, 0.0)
        failed = None
        for curve in (approach, tr, departure):
            report = dense_check(
                curve,
                design=self.design,
                assembly_mode=self.checker.assembly_mode,
                waypoints=np.zeros((2, 3)),
                limits=self.limits,
                resolution=CHECK_RESOLUTION,
                extra_times=np.array([0.0, curve.duration]),
                check_states=self.checker.is_valid,
                max_cartesian_speed=v_cart,
                torque_model=torque,
            )
            if not report.ok:
                failed = report
                break
        return BuiltPick(meeting, hold, approach, tr, departure, failed)


def _earliest(ic: Interception, lo: float, hi: float) -> Meeting:
    """The earliest feasible meeting in (lo, hi] (``hi`` feasible, ``lo`` not): the interval
    cut into :data:`ZOOM` parts, the first feasible one kept, :data:`ZOOMS` times (one batch
    of costs per round)."""
    cost = ic.cost(hi)
    for _ in range(ZOOMS):
        t = np.linspace(lo, hi, ZOOM + 1)[1:]
        c = ic.costs(t)
        k = int(np.flatnonzero(np.isfinite(c))[0])
        lo, hi, cost = (float(t[k - 1]) if k > 0 else lo), float(t[k]), float(c[k])
    return Meeting(hi, cost)


def _lowest(ic: Interception, lo: float, hi: float) -> Meeting | None:
    """The least cost in [lo, hi]: a grid of :data:`ZOOM` + 1 points, narrowed to the best
    one's neighbours :data:`ZOOMS` times (one batch of costs per round)."""
    best: Meeting | None = None
    for _ in range(ZOOMS):
        t = np.linspace(lo, hi, ZOOM + 1)
        c = ic.costs(t)
        k = int(np.argmin(c))
        if not math.isfinite(c[k]):
            break
        if best is None or c[k] < best.cost:
            best = Meeting(float(t[k]), float(c[k]))
        lo, hi = float(t[max(k - 1, 0)]), float(t[min(k + 1, ZOOM)])
    return best


def _grid(ic: Interception) -> np.ndarray:
    """The coarse grid of meeting times (:data:`GRID`) over the part's scanned path after
    ``t_s`` (the span ending within it), and :data:`WINDOW_POINTS` in each trackable
    window (its start included: the earliest meetings lie there)."""
    p = ic.path
    if p.t.size == 0:
        return np.empty(0)
    lo, hi = max(ic.t_s, float(p.t[0])), float(p.t[-1]) - ic.dwell
    if hi < lo:
        return np.empty(0)
    n = max(GRID, math.ceil((hi - lo) / MAX_GRID_STEP_S) + 1)
    grid = [np.linspace(lo, hi, n) if hi > lo else np.array([lo])]
    for a, b in p.windows():  # each window's own points: a narrow one is not stepped over
        a, b = max(a, lo), min(b - ic.dwell, hi)
        if b >= a:
            grid.append(np.linspace(a, b, WINDOW_POINTS))
    return np.unique(np.concatenate(grid))


def intercept(ic: Interception) -> list[Meeting]:
    """The candidate meetings of ``ic`` in increasing cost (module docstring): the refined
    best first, then the feasible grid points; empty when none is feasible."""
    grid = _grid(ic)
    if grid.size == 0:
        return []
    costs = ic.costs(grid)
    feasible = np.isfinite(costs)
    if not np.any(feasible):
        return []
    j = int(np.argmin(costs))
    found = [Meeting(float(grid[j]), float(costs[j]))]
    if j > 0 and not feasible[j - 1]:
        found.append(_earliest(ic, float(grid[j - 1]), float(grid[j])))
    a, b = float(grid[max(j - 1, 0)]), float(grid[min(j + 1, grid.size - 1)])
    if b > a:
        low = _lowest(ic, a, b)
        if low is not None:
            found.append(low)
    found += [Meeting(float(t), float(c)) for t, c in zip(grid, costs, strict=True) if c < math.inf]
    found = [m for m in found if math.isfinite(m.cost)]
    found.sort(key=lambda m: (m.cost, m.t))
    return found
