"""The reference a simulated controller follows: a sampled trajectory (t, q, qd, qdd) read at
any time by quintic Hermite interpolation between its samples, held at its last posture after
its end; and the trajectory's stops (where it is at rest).

Between two samples the reference is the one quintic polynomial per joint that takes the
samples' q, qd and qdd at both ends: at the samples it is the trajectory itself, and a
trajectory sampled at the controller's rate is followed sample for sample. After the last
sample the reference holds that posture at rest (qd = qdd = 0), whatever the last sample's
rates: a trajectory ends at rest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.exceptions import InputError

__all__ = ["REST_SPEED", "Reference", "Stop", "find_stops"]

#: A sample whose joint rates are all within this (rad/s) is at rest.
REST_SPEED = 1e-9


@dataclass(frozen=True, slots=True)
class Stop:
    """A stop of the reference: it is at rest from ``arrive`` to ``leave`` (s, the
    trajectory's clock; equal for a stop of one instant). ``final``: the end of the motion."""

    arrive: float
    leave: float
    final: bool


class Reference:
    """A sampled trajectory as a function of time.

    Parameters
    ----------
    t : shape (M,), s, strictly increasing (any origin: a replacement starts at its ``at``)
    q, qd, qdd : shape (M, 3), rad, rad/s, rad/s^2
    """

    def __init__(self, t: np.ndarray, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> None:
        t = np.asarray(t, dtype=float)
        if t.ndim != 1 or t.size < 1:
            raise InputError(f"t must have shape (M,) with M >= 1, got {t.shape}", field="t")
        arrays = []
        for name, a in (("q", q), ("qd", qd), ("qdd", qdd)):
            a = np.asarray(a, dtype=float)
            if a.shape != (t.size, 3):
                raise InputError(f"{name} must have shape ({t.size}, 3), got {a.shape}", field=name)
            if not np.all(np.isfinite(a)):
                raise InputError(f"{name} must be finite (no NaN or infinity)", field=name)
            arrays.append(a)
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise InputError("t must be finite and increase strictly", field="t")
        self.t = t
        self.q, self.qd, self.qdd = arrays
        self._coefficients = _quintic(t, *arrays) if t.size > 1 else None

    @property
    def start(self) -> float:
        """The first sample's time, s."""
        return float(self.t[0])

    @property
    def end(self) -> float:
        """The last sample's time, s."""
        return float(self.t[-1])

    def at(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, qd, qdd), each (K, 3), at ``times`` (K,), s: the samples' quintic interpolation
        inside [start, end], the first sample before it, the last posture at rest after it
        (at ``end`` itself: the last sample)."""
        times = np.atleast_1d(np.asarray(times, dtype=float))
        q = np.empty((times.size, 3))
        qd = np.zeros((times.size, 3))
        qdd = np.zeros((times.size, 3))
        after = times > self.end
        before = times <= self.start
        q[after] = self.q[-1]
        q[before & ~after], qd[before & ~after], qdd[before & ~after] = (
            self.q[0],
            self.qd[0],
            self.qdd[0],
        )
        inside = ~(after | before)
        if np.any(inside) and self._coefficients is not None:
            k = np.clip(
                np.searchsorted(self.t, times[inside], side="right") - 1, 0, self.t.size - 2
            )
            c = self._coefficients[k]  # (K, 6, 3)
            tau = (times[inside] - self.t[k])[:, None]
            q[inside] = c[:, 0] + tau * (
                c[:, 1] + tau * (c[:, 2] + tau * (c[:, 3] + tau * (c[:, 4] + tau * c[:, 5])))
            )
            qd[inside] = c[:, 1] + tau * (
                2 * c[:, 2] + tau * (3 * c[:, 3] + tau * (4 * c[:, 4] + tau * 5 * c[:, 5]))
            )
            qdd[inside] = 2 * c[:, 2] + tau * (
                6 * c[:, 3] + tau * (12 * c[:, 4] + tau * 20 * c[:, 5])
            )
        return q, qd, qdd


def _quintic(t: np.ndarray, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """Coefficients (M-1, 6, 3) of q(tau) = sum c_i tau^i on each interval (tau from its start):
    the quintic matching q, qd, qdd at both of its samples."""
    h = np.diff(t)[:, None]
    p0, p1, v0, v1, a0, a1 = q[:-1], q[1:], qd[:-1], qd[1:], qdd[:-1], qdd[1:]
    dp = p1 - p0
    c3 = (20 * dp - (8 * v1 + 12 * v0) * h - (3 * a0 - a1) * h**2) / (2 * h**3)
    c4 = (-30 * dp + (14 * v1 + 16 * v0) * h + (3 * a0 - 2 * a1) * h**2) / (2 * h**4)
    c5 = (12 * dp - 6 * (v1 + v0) * h - (a0 - a1) * h**2) / (2 * h**5)
    return np.stack([p0, v0, a0 / 2, c3, c4, c5], axis=1)


def find_stops(reference: Reference) -> list[Stop]:
    """The stops of a reference in time order: each run of samples at rest (every joint rate
    within :data:`REST_SPEED`) but the first sample's (the start is not a stop), and always
    the end (the last one, ``final``; its ``leave`` is the end, the hold after it being the
    simulation's)."""
    rest = np.all(np.abs(reference.qd) <= REST_SPEED, axis=1)
    stops: list[Stop] = []
    i, m = 0, rest.size
    while i < m:
        if not rest[i]:
            i += 1
            continue
        j = i
        while j + 1 < m and rest[j + 1]:
            j += 1
        if i > 0 and j < m - 1:
            stops.append(Stop(float(reference.t[i]), float(reference.t[j]), False))
        i = j + 1
    stops.append(Stop(reference.end, reference.end, True))
    return stops
