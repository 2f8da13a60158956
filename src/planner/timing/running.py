"""A running trajectory as a controller reads it: samples joined by quintic Hermite pieces.

A trajectory on the wire (``t``, ``q``, ``qd``, ``qdd``: the arrays form, and equally the
points of ROS's ``FollowJointTrajectory``) is a list of states, not a curve. Between two
samples we read it the way ROS 2's ``joint_trajectory_controller`` does when positions,
velocities and accelerations are all given: per joint, the quintic polynomial that matches
q, qd and qdd at both ends of the interval. So the state at a sample time is that sample,
exactly, and between samples q, qd and qdd are continuous (the jerk is the quintic's, and may
jump at the samples). Replacement (:mod:`planner.timing.lead_in`) and the stop
(:mod:`planner.timing.braking`) read the running trajectory through this one class, so what
they splice onto is what a controller is executing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from planner.exceptions import InputError

__all__ = ["RunningTrajectory"]

#: Most samples of a running trajectory (the wire's answer bound).
MAX_RUNNING_SAMPLES = 1_000_000


def _array(name: str, value: Any, shape_tail: tuple[int, ...]) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numbers", field=name) from exc
    if a.ndim != 1 + len(shape_tail) or a.shape[1:] != shape_tail:
        want = "(M,)" if not shape_tail else "(M, 3)"
        raise InputError(f"{name} must have shape {want}, got {a.shape}", field=name)
    if not np.all(np.isfinite(a)):
        raise InputError(f"{name} must be finite (no NaN or infinity)", field=name)
    return a


@dataclass(frozen=True, eq=False)
class RunningTrajectory:
    """The trajectory a controller is executing (see the module docstring).

    Attributes
    ----------
    t : shape (M,), s, strictly increasing (any origin: the running clock).
    q, qd, qdd : shape (M, 3), rad, rad/s, rad/s^2.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray

    @classmethod
    def of(
        cls, t: Any, q: Any, qd: Any, qdd: Any, *, prefix: str = "trajectory"
    ) -> RunningTrajectory:
        """The checked running trajectory of four arrays; an
        :class:`~planner.exceptions.InputError` names the field (``{prefix}.t``, ...) and the
        rule (shapes, finite, at least 2 samples, ``t`` strictly increasing, equal lengths)."""
        tt = _array(f"{prefix}.t", t, ())
        arrays = [_array(f"{prefix}.{n}", v, (3,)) for n, v in (("q", q), ("qd", qd), ("qdd", qdd))]
        if not 2 <= tt.shape[0] <= MAX_RUNNING_SAMPLES:
            raise InputError(
                f"{prefix}.t must hold 2 to {MAX_RUNNING_SAMPLES} samples, got {tt.shape[0]}",
                field=f"{prefix}.t",
            )
        for name, a in zip(("q", "qd", "qdd"), arrays, strict=True):
            if a.shape[0] != tt.shape[0]:
                raise InputError(
                    f"{prefix}.{name} has {a.shape[0]} samples, {prefix}.t has {tt.shape[0]}",
                    field=f"{prefix}.{name}",
                )
        steps = np.diff(tt)
        if np.any(steps <= 0.0):
            i = int(np.argmax(steps <= 0.0))
            raise InputError(
                f"{prefix}.t must increase strictly: t[{i + 1}] = {float(tt[i + 1])!r} <= "
                f"t[{i}] = {float(tt[i])!r}",
                field=f"{prefix}.t",
            )
        return cls(tt, *arrays)

    @property
    def start(self) -> float:
        """Its first time, s."""
        return float(self.t[0])

    @property
    def end(self) -> float:
        """Its last time, s."""
        return float(self.t[-1])

    def check_time(self, at: float, field: str = "at") -> float:
        """``at`` as a float inside [start, end], else an
        :class:`~planner.exceptions.InputError` naming ``field``."""
        x = float(at)
        if not (np.isfinite(x) and self.start <= x <= self.end):
            raise InputError(
                f"{field} = {at!r} lies outside the running trajectory's times "
                f"[{self.start!r}, {self.end!r}]",
                field=field,
            )
        return x

    def _coefficients(self, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The quintic of each interval k (M,): h (M, 1) and coefficients (M, 6, 3) of
        q(tau) = sum c_i tau^i, tau the time since the interval's start."""
        h = (self.t[k + 1] - self.t[k])[:, None]
        p0, v0, a0 = self.q[k], self.qd[k], self.qdd[k]
        p1, v1, a1 = self.q[k + 1], self.qd[k + 1], self.qdd[k + 1]
        dp = p1 - p0
        c3 = (20 * dp - (8 * v1 + 12 * v0) * h - (3 * a0 - a1) * h**2) / (2 * h**3)
        c4 = (-30 * dp + (14 * v1 + 16 * v0) * h + (3 * a0 - 2 * a1) * h**2) / (2 * h**4)
        c5 = (12 * dp - 6 * (v1 + v0) * h - (a0 - a1) * h**2) / (2 * h**5)
        return h, np.stack([p0, v0, a0 / 2, c3, c4, c5], axis=1)

    def evaluate(self, t: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """q, qd, qdd, jerk (each shape (M, 3)) at times t (M,) in [start, end]; at a sample
        time, that sample exactly (jerk: the later interval's)."""
        tt = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), self.start, self.end)
        k = np.clip(np.searchsorted(self.t, tt, side="right") - 1, 0, self.t.shape[0] - 2)
        used, which = np.unique(k, return_inverse=True)  # each interval's quintic once
        _, c = self._coefficients(used)
        c = c[which]
        x = (tt - self.t[k])[:, None]
        q = c[:, 0] + x * (c[:, 1] + x * (c[:, 2] + x * (c[:, 3] + x * (c[:, 4] + x * c[:, 5]))))
        qd = c[:, 1] + x * (2 * c[:, 2] + x * (3 * c[:, 3] + x * (4 * c[:, 4] + x * 5 * c[:, 5])))
        qdd = 2 * c[:, 2] + x * (6 * c[:, 3] + x * (12 * c[:, 4] + x * 20 * c[:, 5]))
        jerk = 6 * c[:, 3] + x * (24 * c[:, 4] + x * 60 * c[:, 5])
        # at a sample time x = 0, and the polynomial gives that sample bit for bit (c0, c1 and
        # 2 * (a0 / 2) are exact); only the last sample lies at the end of its interval
        last = tt >= self.end
        if np.any(last):
            q[last], qd[last], qdd[last] = self.q[-1], self.qd[-1], self.qdd[-1]
        return q, qd, qdd, jerk

    def state_at(self, at: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q, qd, qdd (each (3,)) at time ``at`` (inside [start, end]): :meth:`evaluate` at
        one time, without its array overhead (a stop reads one state per call)."""
        t = self.t
        k = int(np.searchsorted(t, at, side="right")) - 1
        if k >= t.shape[0] - 1 or at >= t[-1]:
            return self.q[-1].copy(), self.qd[-1].copy(), self.qdd[-1].copy()
        k = max(k, 0)
        x = float(at) - float(t[k])
        if x <= 0.0:
            return self.q[k].copy(), self.qd[k].copy(), self.qdd[k].copy()
        h = float(t[k + 1] - t[k])
        p0, v0, a0 = self.q[k], self.qd[k], self.qdd[k]
        p1, v1, a1 = self.q[k + 1], self.qd[k + 1], self.qdd[k + 1]
        dp = p1 - p0
        c3 = (20 * dp - (8 * v1 + 12 * v0) * h - (3 * a0 - a1) * h**2) / (2 * h**3)
        c4 = (-30 * dp + (14 * v1 + 16 * v0) * h + (3 * a0 - 2 * a1) * h**2) / (2 * h**4)
        c5 = (12 * dp - 6 * (v1 + v0) * h - (a0 - a1) * h**2) / (2 * h**5)
        q = p0 + x * (v0 + x * (a0 / 2 + x * (c3 + x * (c4 + x * c5))))
        qd = v0 + x * (a0 + x * (3 * c3 + x * (4 * c4 + x * 5 * c5)))
        qdd = a0 + x * (6 * c3 + x * (12 * c4 + x * 20 * c5))
        return q, qd, qdd
