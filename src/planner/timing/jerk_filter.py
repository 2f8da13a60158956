"""A jerk limit for toppra's trajectory: its profile smoothed by a moving average in time.

toppra (TOPP-RA) is a second-order method: its path acceleration is constant between grid
points and jumps at them, and on the blended path the joint acceleration jumps too where a
line meets an arc (``q''`` jumps there), so its jerk is unbounded. A jerk limit is a
third-order constraint: TOPP-RA cannot take it (its reachability sets are intervals of
``sd^2`` because the constraints are linear in ``sdd`` and ``sd^2``; jerk adds ``sddd``).
When ``limits.jerk`` is asked with ``method="toppra"``, every rest-to-rest section of
toppra's trajectory ``B`` is passed through a moving-average (FIR) filter of width ``T``
(Biagiotti and Melchiorri, "FIR filters for online trajectory planning with time- and
frequency-domain specifications", Control Eng. Practice 2012)::

    F(u) = 1/T int_{u-T}^{u} B(x) dx,    B held at its resting ends outside the section,

so that ``F' = (B(u) - B(u-T)) / T``, ``F'' = (B'(u) - B'(u-T)) / T`` and
``F''' = (B''(u) - B''(u-T)) / T``: every derivative of F is an exact function of B's,
evaluated here in closed form (only F itself needs B's integral: a cumulative Hermite
quadrature, exact for cubics, on a grid of ``T / 64`` that holds every grid time of
toppra's profile, so that no acceleration jump lies inside a quadrature step). Why this filter and not a re-timing
by a jerk-limited state-to-state chain (that is ``method="ruckig"``):

* velocity and acceleration: each is an average of B's over the window, and a per-joint box
  is convex, so F keeps B's limits exactly (no re-check slack is spent on them);
* jerk: ``|F'''_j| <= max |B''_j(u) - B''_j(u-T)| / T``, at most ``2 a_j / T``; ``T`` is the
  smallest of ``a/j x (0.5, 0.75, ..., 2)`` whose measured bound holds (a trapezoid's
  jumps are ``a``: ``T = a/j``, the ramp time of the jerk-limited optimum), else ``2 a/j``
  scaled by any excess measured;
* time: each section takes exactly ``T`` longer than toppra's time-optimal one (on the
  benchmark paths, default limits: 0.04-0.08 s per rest-to-rest section, where the
  jerk-limited chain costs 11 % of the whole motion, ``docs/timing.md``);
* rests stay exact: the section is filtered alone, held at its resting ends, so F rests on
  the same vertices (a stop, a transit) and reaches them exactly;
* the cost is geometric: at a blend the window averages postures on both sides, so F cuts
  inside the arc. The dense re-check measures the deviation like any other (the postures
  stand for every corner their window covers) and a corner that strays too far has its
  blend shrunk (:func:`planner.timing.parameterize.time_path`'s repair), as for Ruckig.

Limits that are not convex boxes of the averaged quantity (the Cartesian speed of P, the
torques, validity) are re-checked densely on F; the repair slows toppra's profile.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from planner.timing.limits import JointLimits
from planner.timing.trajectory import Curve, ToppraCurve, check_sample_count

__all__ = ["WINDOW_FACTORS", "JerkFilteredCurve", "filter_jerk", "jerk_limited"]

#: Candidate windows, in units of ``max_j a_j / j_j``: the smallest that holds is taken.
WINDOW_FACTORS = (0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0)
#: The window's jerk bound aims this far inside the limit (relative).
_JERK_MARGIN = 1e-3
#: Quadrature grid of F's position, per window.
_Q_STEPS = 64


@dataclass(frozen=True, eq=False)
class _Section:
    """One rest-to-rest section of the base: base times ``[b0, b0 + length]``, filtered
    with window ``window``; on F's axis it starts at ``start`` and lasts
    ``length + window``. ``grid``, ``cum_q``: the quadrature grid (local time) and B's
    integral from 0 at it."""

    b0: float
    length: float
    window: float
    start: float
    grid: np.ndarray
    cum_q: np.ndarray

    @property
    def end(self) -> float:
        return self.start + self.length + self.window


@dataclass(frozen=True, eq=False)
class JerkFilteredCurve:
    """A toppra curve with each rest-to-rest section moving-averaged (module docstring)."""

    base: ToppraCurve
    sections: tuple[_Section, ...]
    speed: float

    @property
    def duration(self) -> float:
        return self.sections[-1].end

    def _split(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Section index and local time (0 at the section's start) of each time."""
        t = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), 0.0, self.duration)
        starts = np.array([s.start for s in self.sections])
        k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(self.sections) - 1)
        return k, t - starts[k]

    def _base(self, sec: _Section, x: np.ndarray) -> tuple[np.ndarray, ...]:
        """B's q, qd, qdd at local times x, held at rest outside ``[0, length]``."""
        inside = (x >= 0.0) & (x <= sec.length)
        q, qd, qdd, _ = self.base.evaluate(sec.b0 + np.clip(x, 0.0, sec.length))
        return q, qd * inside[:, None], qdd * inside[:, None]

    def _integral(self, sec: _Section, x: np.ndarray) -> np.ndarray:
        """B's integral from local time 0 to x (B held at rest outside the section)."""
        xc = np.clip(x, 0.0, sec.length)
        i = np.clip(np.searchsorted(sec.grid, xc, side="right") - 1, 0, sec.grid.shape[0] - 1)
        g = sec.grid[i]
        q_g, qd_g, _, _ = self.base.evaluate(sec.b0 + g)
        q_x, qd_x, _, _ = self.base.evaluate(sec.b0 + xc)
        h = (xc - g)[:, None]
        local = h / 2 * (q_g + q_x) + h**2 / 12 * (qd_g - qd_x)  # Hermite: exact for cubics
        held = (x - xc)[:, None] * q_x  # before 0 (negative) or after the end: at rest
        return sec.cum_q[i] + local + held

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        k, u = self._split(t)
        out = [np.zeros((u.shape[0], 3)) for _ in range(4)]
        for j, sec in enumerate(self.sections):
            sel = k == j
            if not np.any(sel):
                continue
            uj, w = u[sel], sec.window
            q1, qd1, qdd1 = self._base(sec, uj)
            q0, qd0, qdd0 = self._base(sec, uj - w)
            at_rest = np.abs(uj) <= 0.0  # exactly the resting start: B's own posture
            q = (self._integral(sec, uj) - self._integral(sec, uj - w)) / w
            q[at_rest] = q1[at_rest]
            out[0][sel] = q
            out[1][sel] = (q1 - q0) / w
            out[2][sel] = (qd1 - qd0) / w
            out[3][sel] = (qdd1 - qdd0) / w
        return out[0], out[1], out[2], out[3]

    def rest_times(self) -> np.ndarray:
        return np.array([s.start for s in self.sections[1:]])

    def check_times(self, resolution: float) -> np.ndarray:
        """Per section: the base's grid times (where its acceleration jumps) and their
        midpoints, the same plus the window (where F's jerk, a difference of B's
        accelerations, changes), a grid at which no posture moves more than ``resolution``
        (|qd_j| <= its velocity limit: ``speed``
        is their norm), and the midpoints of all of them (between
        breakpoints the jerk of a straight piece is constant: a midpoint sees its value)."""
        prof, speed = self.base.profile, self.speed
        out = []
        for sec in self.sections:
            x = _knots(prof.time, sec)
            span = sec.length + sec.window
            n = int(np.ceil(span * speed / resolution)) + 1
            check_sample_count(4 * (n + 2 * x.shape[0]))
            u = np.unique(np.concatenate([x, x + sec.window, np.linspace(0.0, span, n)]))
            u = np.unique(np.concatenate([u, (u[1:] + u[:-1]) / 2]))
            out.append(sec.start + u)
        return np.unique(np.clip(np.concatenate(out), 0.0, self.duration))

    def _window_pieces(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The first and last piece of the blended path under each time's window."""
        k, u = self._split(t)
        b0 = np.array([s.b0 for s in self.sections])[k]
        length = np.array([s.length for s in self.sections])[k]
        w = np.array([s.window for s in self.sections])[k]
        prof, path = self.base.profile, self.base.path
        s_a, _, _ = prof.at_time(b0 + np.clip(u - w, 0.0, length))
        s_b, _, _ = prof.at_time(b0 + np.clip(u, 0.0, length))
        return path.piece_index(s_a), path.piece_index(s_b, side="left")

    def _corner_range(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The first and last blend (waypoint index) under each time's window; first >
        last where the window covers no blend (then it lies on one straight piece, or on
        one segment held at a rest: F is on the planned segment)."""
        path = self.base.path
        if path.n_pieces == 0:
            n = np.atleast_1d(t).shape[0]
            return np.zeros(n, int), np.full(n, -1)
        lo, hi = self._window_pieces(np.atleast_1d(np.asarray(t, dtype=float)))
        corner = path.corner
        big = np.iinfo(np.int64).max
        nxt = np.where(corner >= 0, corner, big)[::-1]
        first_after = np.minimum.accumulate(nxt)[::-1]  # smallest blend at or after piece p
        last_before = np.maximum.accumulate(np.where(corner >= 0, corner, -1))
        return first_after[lo], last_before[np.maximum(hi, lo)]

    def plan_segments(self, t: np.ndarray) -> np.ndarray:
        """The segments around every blend the window covers (a posture is an average of
        them), or (-1, -1) where the window lies on one planned segment."""
        first, last = self._corner_range(t)
        covered = first <= last
        return np.where(covered[:, None], np.stack([first - 1, last], axis=1), -1)

    def corners_at(self, t: np.ndarray) -> list[tuple[int, ...]]:
        """For each time, the blends its window covers (empty: on a planned segment)."""
        first, last = self._corner_range(t)
        corners = np.unique(self.base.path.corner[self.base.path.corner >= 0])
        return [
            tuple(int(c) for c in corners if a <= c <= b) for a, b in zip(first, last, strict=True)
        ]


def _knots(times: np.ndarray, sec: _Section | tuple[float, float]) -> np.ndarray:
    """The base's grid times inside a section (local time; its ends included) and their
    midpoints: B's acceleration is constant between grid times on a straight piece."""
    b0, length = (sec.b0, sec.length) if isinstance(sec, _Section) else sec
    x = times[(times >= b0) & (times <= b0 + length)] - b0
    x = np.unique(np.concatenate([[0.0, length], x]))
    return np.unique(np.concatenate([x, (x[1:] + x[:-1]) / 2]))


def _window(
    base: ToppraCurve,
    b0: float,
    length: float,
    jerk: np.ndarray,
    a_over_j: float,
    knots: np.ndarray,
) -> float:
    """The smallest window of :data:`WINDOW_FACTORS` under which the filtered section's
    jerk holds (measured on the knots, the knots shifted by the window and their
    midpoints), or the largest scaled by the excess measured under it."""
    ratio = np.inf
    window = a_over_j
    for f in WINDOW_FACTORS:
        window = f * a_over_j
        u = np.unique(np.concatenate([knots, knots + window]))
        u = np.unique(np.concatenate([u, (u[1:] + u[:-1]) / 2]))
        x1, x0 = u, u - window
        acc = []
        for x in (x1, x0):
            inside = ((x >= 0.0) & (x <= length))[:, None]
            acc.append(base.evaluate(b0 + np.clip(x, 0.0, length))[2] * inside)
        ratio = float(np.max(np.abs(acc[0] - acc[1]) / (jerk * window)))
        if ratio <= 1.0 - _JERK_MARGIN:
            return window
    return window * ratio / (1.0 - _JERK_MARGIN)


def filter_jerk(base: ToppraCurve, limits: JointLimits) -> JerkFilteredCurve:
    """``base`` with every rest-to-rest section moving-averaged so that its jerk holds
    ``|F'''_j| <= jerk[j]`` (module docstring).

    Parameters
    ----------
    base : toppra's curve (within ``limits``' velocity and acceleration).
    limits : with ``jerk``.
    """
    jerk = limits.jerk_array
    assert jerk is not None
    a_over_j = float(np.max(limits.acceleration_array / jerk))
    ends = np.concatenate([[0.0], base.rest_times(), [base.duration]])
    sections, start = [], 0.0
    for b0, b1 in itertools.pairwise(ends):
        length = float(b1 - b0)
        knots = _knots(base.profile.time, (float(b0), length))
        window = _window(base, float(b0), length, jerk, a_over_j, knots)
        n = max(2, int(np.ceil(length * _Q_STEPS / window)) + 1)
        check_sample_count(n + knots.shape[0])
        grid = np.union1d(np.linspace(0.0, length, n), knots)  # no acceleration jump inside
        q, qd, _, _ = base.evaluate(b0 + grid)
        h = np.diff(grid)[:, None]
        steps = h / 2 * (q[1:] + q[:-1]) + h**2 / 12 * (qd[:-1] - qd[1:])
        cum = np.concatenate([np.zeros((1, 3)), np.cumsum(steps, axis=0)])
        sections.append(_Section(float(b0), length, window, start, grid, cum))
        start += length + window
    return JerkFilteredCurve(base, tuple(sections), float(np.linalg.norm(limits.velocity_array)))


def jerk_limited(curve: Curve, limits: JointLimits) -> Curve:
    """``curve`` (toppra's) filtered for ``limits.jerk`` (:func:`filter_jerk`), or as it is
    when no jerk is asked (or the motion has no duration)."""
    if limits.jerk is None or not isinstance(curve, ToppraCurve) or curve.duration <= 0.0:
        return curve
    return filter_jerk(curve, limits)
