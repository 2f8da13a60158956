"""A part on a belt seen by the robot (:mod:`planner.sequence.moving`'s geometry): where its
straight path is reachable and trackable in each working mode, and the tracking span as a
curve the timing's dense re-check reads like any other.

The part moves at constant velocity v: P_part(t) = p + v (t - t0). Tracking it means
q(t) = IK_m(P_part(t)) in one working mode m (:func:`planner.kinematics.inverse_batch`, the
product's closed-form inverse kinematics), so the tool point is on the part by construction,
to the inverse kinematics' round-off, at every instant of the span. The joint rates are the
time derivatives of that posture, taken by central differences in time of the exact inverse
(:data:`FD_STEP_S`): qd = J^-1 v to about 1e-10 rad/s, so the tool's velocity equals the part's.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from planner.design import Design
from planner.kinematics import WORKING_MODES, inverse_batch
from planner.sequence.problem import MovingTarget
from planner.timing.limits import JointLimits
from planner.validity import ValidityChecker

__all__ = [
    "FD_STEP_S",
    "SCAN_STEP_M",
    "ChainCurve",
    "HoldCurve",
    "PartPath",
    "TrackingCurve",
    "ik_in_mode",
    "scan_part",
    "scan_times",
    "shift_near",
    "track_states",
]

#: Step of the central differences in time of the tracking posture, s: the truncation error
#: is O(h^2) (1e-8 of the derivatives' scale), the round-off O(1e-15 / h^k) (1e-3 rad/s^3 for
#: the jerk's fourth-order stencil), both far below any limit.
FD_STEP_S = 1e-4
#: Spacing of the part's path when it is scanned for reachability, m along the belt (at most
#: :data:`SCAN_STEP_S` in time): the windows found are exact to this; the spans chosen in them
#: are then checked densely.
SCAN_STEP_M = 0.002
SCAN_STEP_S = 0.01
#: Spacing of the tracking span's whole-turn reference, s.
TURNS_STEP_S = 0.05
#: A part that stands still (velocity 0) is scanned over this long, s.
STILL_HORIZON_S = 60.0


def shift_near(q_raw: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
    """``q_raw`` (M, 3) shifted by whole turns per joint to lie within pi of ``q_ref``."""
    return q_raw + 2 * math.pi * np.round((q_ref - q_raw) / (2 * math.pi))


def ik_in_mode(design: Design, points: np.ndarray, mode: str, assembly_mode: str) -> np.ndarray:
    """The inverse-kinematics postures of ``points`` (M, 3) in ``mode``, NaN where that mode
    does not reach a point in ``assembly_mode``."""
    slot = WORKING_MODES.index(mode)
    ik = inverse_batch(design, points)
    q = ik.q[:, slot].copy()
    want = 1 if assembly_mode == "+" else -1
    bad = ~ik.ok[:, slot] | (ik.assembly_mode_signs[:, slot] != want) | ik.degenerate
    q[bad] = np.nan
    return q


@dataclass(frozen=True, eq=False)
class PartPath:
    """The part's path scanned in one working mode: sample times ``t`` (M,), s, the postures
    ``q`` (M, 3) continuous in time (whole turns chosen near ``q_ref``), and ``ok`` (M,):
    reached, valid under the checker's rules and within the velocity and acceleration limits
    when tracked there."""

    mode: str
    t: np.ndarray
    q: np.ndarray
    ok: np.ndarray

    def windows(self) -> list[tuple[float, float]]:
        """The time intervals where ``ok`` holds, s."""
        out = []
        edges = np.diff(np.concatenate([[0], self.ok.astype(int), [0]]))
        for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1, strict=True):
            out.append((float(self.t[a]), float(self.t[b])))
        return out

    def trackable(self, t_meet: float, dwell: float) -> bool:
        """Whether every scanned sample of [t_meet, t_meet + dwell] is ``ok`` (and the span
        lies within the scan)."""
        if t_meet < self.t[0] or t_meet + dwell > self.t[-1]:
            return False
        a = int(np.searchsorted(self.t, t_meet, side="right")) - 1
        b = int(np.searchsorted(self.t, t_meet + dwell, side="left"))
        return bool(np.all(self.ok[max(a, 0) : b + 1]))


def scan_times(design: Design, target: MovingTarget, t_from: float) -> np.ndarray:
    """Sample times of the part's path where it may be reachable, from ``t_from``: until it
    leaves the ball of radius L0/2 + L1 + L2 around the base for good (the reach of either
    leg), every :data:`SCAN_STEP_M` of belt travel (at most :data:`SCAN_STEP_S`)."""
    v = target.velocity
    speed = float(np.linalg.norm(v))
    if speed == 0.0:
        return np.linspace(t_from, t_from + STILL_HORIZON_S, 2)
    radius = 0.5 * design.L0 + design.reach
    p, vv = target.p, float(v @ v)
    b, c = float(p @ v) / vv, (float(p @ p) - radius**2) / vv
    disc = b * b - c
    if disc <= 0.0:
        return np.empty(0)
    t_in, t_out = target.t0 - b - math.sqrt(disc), target.t0 - b + math.sqrt(disc)
    lo = max(t_in, t_from)
    if t_out <= lo:
        return np.empty(0)
    step = min(SCAN_STEP_M / speed, SCAN_STEP_S)
    return np.linspace(lo, t_out, max(3, math.ceil((t_out - lo) / step) + 1))


def scan_part(
    design: Design,
    target: MovingTarget,
    checker: ValidityChecker,
    limits: JointLimits,
    q_ref: np.ndarray,
    t_from: float,
) -> PartPath:
    """The part's path from ``t_from`` in the checker's working mode (:class:`PartPath`):
    reached and valid at each sample (its posture, whole turns continued in time, within
    the design's joint limits and the checker's rules), and within the joint velocity and acceleration limits
    when tracked (the rates by differences over the samples)."""
    mode = checker.working_mode
    t = scan_times(design, target, t_from)
    if t.size == 0:
        return PartPath(mode, t, np.empty((0, 3)), np.zeros(0, bool))
    q = ik_in_mode(design, target.at(t), mode, checker.assembly_mode)
    reached = np.all(np.isfinite(q), axis=1)
    q_cont = np.full_like(q, np.nan)
    if np.any(reached):
        first = int(np.flatnonzero(reached)[0])
        q_cont[reached] = np.unwrap(q[reached], axis=0)
        # whole turns: the first reached posture nearest q_ref, the rest continuous from it
        q_cont[reached] += shift_near(q_cont[first][None], q_ref[None])[0] - q_cont[first]
    ok = reached.copy()
    if np.any(ok):
        lo, hi = np.asarray(design.joint_min), np.asarray(design.joint_max)
        inside = np.all((q_cont[ok] >= lo) & (q_cont[ok] <= hi), axis=1)
        ok[ok] = inside & checker.is_valid(q_cont[ok])
    if t.size >= 3 and np.any(ok):
        qd = np.gradient(np.nan_to_num(q_cont), t, axis=0)
        qdd = np.gradient(qd, t, axis=0)
        inside = np.all(np.abs(qd) <= limits.velocity_array, axis=1) & np.all(
            np.abs(qdd) <= limits.acceleration_array, axis=1
        )
        ok &= inside
    return PartPath(mode, t, q_cont, ok)


def track_states(
    design: Design,
    target: MovingTarget,
    mode: str,
    assembly_mode: str,
    t: np.ndarray,
    q_ref: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The tracking state at sequence times ``t`` (M,): q = IK_mode(P_part(t)) (whole turns
    within pi of ``q_ref`` (M, 3)) and its first three time derivatives by fourth-order
    central differences of step :data:`FD_STEP_S` (one inverse-kinematics call for all);
    NaN where the mode does not reach the part."""
    m, h = t.shape[0], FD_STEP_S
    offsets = np.arange(-2, 3) * h
    q = ik_in_mode(design, target.at((t[None, :] + offsets[:, None]).ravel()), mode, assembly_mode)
    q = q.reshape(5, m, 3)
    centre = shift_near(q[2], q_ref)
    qm2, qm1, q0, qp1, qp2 = (shift_near(q[k], centre) for k in range(5))
    qd = (qm2 - 8 * qm1 + 8 * qp1 - qp2) / (12 * h)
    qdd = (-qm2 + 16 * qm1 - 30 * q0 + 16 * qp1 - qp2) / (12 * h * h)
    jerk = (-qm2 + 2 * qm1 - 2 * qp1 + qp2) / (2 * h**3)
    return q0, qd, qdd, jerk


@dataclass(frozen=True, eq=False)
class TrackingCurve:
    """The tool on the part for ``dwell`` s from sequence time ``t_meet``: q(tau) =
    IK_mode(P_part(t_meet + tau)), whole turns chosen continuously from ``q_meet`` (a
    :class:`~planner.timing.trajectory.Curve`; its jerk by differences too)."""

    design: Design
    target: MovingTarget
    mode: str
    assembly_mode: str
    t_meet: float
    dwell: float
    q_meet: np.ndarray
    speed_bound: float

    @property
    def duration(self) -> float:
        return self.dwell

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        tau = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), 0.0, self.dwell)
        grid, q_grid = self._turns
        ref = np.stack([np.interp(tau, grid, q_grid[:, j]) for j in range(3)], axis=1)
        return track_states(
            self.design, self.target, self.mode, self.assembly_mode, self.t_meet + tau, ref
        )

    @functools.cached_property
    def _turns(self) -> tuple[np.ndarray, np.ndarray]:
        """The span's postures every :data:`TURNS_STEP_S` s, whole turns continued from
        ``q_meet`` (a joint moves at most 0.1 rad between two of them under 2 rad/s), the
        reference each evaluated posture takes its whole turns from."""
        n = max(2, math.ceil(self.dwell / TURNS_STEP_S) + 1)
        grid = np.linspace(0.0, self.dwell, n)
        q = ik_in_mode(
            self.design, self.target.at(self.t_meet + grid), self.mode, self.assembly_mode
        )
        q[0] = shift_near(q[0][None], self.q_meet[None])[0]
        for k in range(1, n):
            q[k] = shift_near(q[k][None], q[k - 1][None])[0]
        return grid, q

    def state(self, tau: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, qd, qdd) at ``tau`` s into the span."""
        q, qd, qdd, _ = self.evaluate(np.array([tau]))
        return q[0], qd[0], qdd[0]

    def rest_times(self) -> np.ndarray:
        return np.empty(0)

    def check_times(self, resolution: float) -> np.ndarray:
        n = max(2, math.ceil(self.dwell * self.speed_bound / resolution) + 1)
        return np.linspace(0.0, self.dwell, n)

    def plan_segments(self, t: np.ndarray) -> np.ndarray:
        return np.full((np.shape(np.atleast_1d(t))[0], 2), -1)


@dataclass(frozen=True, eq=False)
class HoldCurve:
    """At rest at ``q`` for ``hold`` s (waiting for the part)."""

    q: np.ndarray
    hold: float

    @property
    def duration(self) -> float:
        return self.hold

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        m = np.atleast_1d(t).shape[0]
        zeros = np.zeros((m, 3))
        return np.broadcast_to(self.q, (m, 3)).copy(), zeros, zeros.copy(), zeros.copy()

    def check_times(self, resolution: float) -> np.ndarray:
        return np.array([0.0, self.hold])

    def rest_times(self) -> np.ndarray:
        return np.empty(0)

    def plan_segments(self, t: np.ndarray) -> np.ndarray:
        return np.full((np.shape(np.atleast_1d(t))[0], 2), -1)


@dataclass(frozen=True, eq=False)
class ChainCurve:
    """Curves one after the other on one time axis (each starts where the previous one ends,
    in the same state); the instants between two pieces at rest are its rest times."""

    pieces: tuple

    @property
    def starts(self) -> np.ndarray:
        return np.concatenate([[0.0], np.cumsum([c.duration for c in self.pieces])])

    @property
    def duration(self) -> float:
        return float(self.starts[-1])

    def _index(self, t: np.ndarray) -> np.ndarray:
        s = self.starts
        return np.clip(np.searchsorted(s, t, side="right") - 1, 0, len(self.pieces) - 1)

    def evaluate(
        self, t: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        t = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), 0.0, self.duration)
        idx, s = self._index(t), self.starts
        q, qd, qdd = (np.zeros((t.shape[0], 3)) for _ in range(3))
        jerk: np.ndarray | None = np.zeros((t.shape[0], 3))
        for k, c in enumerate(self.pieces):
            sel = idx == k
            if not np.any(sel):
                continue
            a, b, d, j = c.evaluate(np.clip(t[sel] - s[k], 0.0, c.duration))
            q[sel], qd[sel], qdd[sel] = a, b, d
            jerk = None if j is None or jerk is None else jerk
            if jerk is not None and j is not None:
                jerk[sel] = j
        return q, qd, qdd, jerk

    def rest_times(self) -> np.ndarray:
        s = self.starts
        out = [c.rest_times() + s[k] for k, c in enumerate(self.pieces)]
        inner = s[1:-1]
        if inner.size:
            _, qd, _, _ = self.evaluate(inner)
            out.append(inner[np.all(np.abs(qd) <= 1e-12, axis=1)])
        t = np.unique(np.concatenate(out)) if out else np.empty(0)
        return t[(t > 0.0) & (t < self.duration)]

    def check_times(self, resolution: float) -> np.ndarray:
        s = self.starts
        out = [c.check_times(resolution) + s[k] for k, c in enumerate(self.pieces)]
        return np.unique(np.concatenate([*out, s]))

    def plan_segments(self, t: np.ndarray) -> np.ndarray:
        return np.full((np.shape(np.atleast_1d(t))[0], 2), -1)
