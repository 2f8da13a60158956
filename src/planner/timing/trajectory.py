"""The timed result: a curve that can be evaluated at any time, and its sampled form.

Two curves implement the same small interface (``duration``, ``evaluate(t)``,
``check_times(resolution)``): :class:`ToppraCurve` (a path velocity profile on the blended path)
and ``RuckigCurve`` (a chain of jerk-limited state-to-state moves, in
:mod:`planner.timing.ruckig_method`). :class:`Trajectory` holds the samples at the requested
rate plus the measured quality: deviation from the planned polyline in joint space and at P.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from planner.design import Design
from planner.exceptions import InputError
from planner.kinematics import forward_velocity
from planner.timing.path import BlendedPath
from planner.timing.toppra_method import PathProfile

__all__ = [
    "Curve",
    "RestCurve",
    "TimeScaledCurve",
    "ToppraCurve",
    "Trajectory",
    "check_sample_count",
    "p_velocity",
    "sample_times",
]

#: Points checked inside every toppra grid interval besides its ends.
SUBSAMPLES = 5
#: Most postures in one dense re-check (each costs ~100 bytes per array evaluated).
MAX_CHECK_SAMPLES = 5_000_000


def check_sample_count(n: int) -> None:
    """Refuse a dense re-check of more than ``MAX_CHECK_SAMPLES`` postures (memory)."""
    if n > MAX_CHECK_SAMPLES:
        raise InputError(
            f"check_resolution is too fine for this path: {n} postures to check, more than "
            f"{MAX_CHECK_SAMPLES}"
        )


class Curve(Protocol):
    """A timed joint trajectory q(t) on [0, duration]."""

    @property
    def duration(self) -> float: ...

    def evaluate(
        self, t: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """(q, qd, qdd, jerk or None) at times t (M,), shapes (M, 3)."""
        ...

    def rest_times(self) -> np.ndarray:
        """Times strictly inside (0, duration) where the motion is at rest (its stops), s:
        output samples include them, so a client sees every rest posture."""
        ...

    def check_times(self, resolution: float) -> np.ndarray:
        """Times, increasing, at which consecutive postures are at most ``resolution`` apart
        in joint space (Euclidean, rad), plus every instant where the acceleration jumps."""
        ...

    def plan_segments(self, t: np.ndarray) -> np.ndarray:
        """Shape (M, 2), int: first and last planned segment each posture stands for, or
        (-1, -1) where it lies on the planned polyline by construction (no deviation)."""
        ...


@dataclass(frozen=True, eq=False)
class ToppraCurve:
    """q(t) = path(s(t)) for a toppra profile on a blended path (jerk is not defined)."""

    path: BlendedPath
    profile: PathProfile

    @property
    def duration(self) -> float:
        return self.profile.duration

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, None]:
        s, sd, sdd = self.profile.at_time(t)
        return self._at(s, sd, sdd)

    def rest_times(self) -> np.ndarray:
        """Times strictly inside the motion where it comes to rest (the stops), s."""
        inner = self.profile.sd[1:-1] == 0.0
        return self.profile.time[1:-1][inner]

    def _at(
        self, s: np.ndarray, sd: np.ndarray, sdd: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, None]:
        q, d1, d2 = self.path.evaluate_all(s)
        return q, d1 * sd[:, None], d1 * sdd[:, None] + d2 * (sd**2)[:, None], None

    def check_path_positions(self, resolution: float, *, ordered: bool = True) -> np.ndarray:
        """Path positions ``resolution`` apart along s (s is the joint-space arc length, so
        consecutive checked postures are at most ``resolution`` apart whatever the timing),
        plus ``SUBSAMPLES`` points inside every grid interval (toppra certifies the limits at
        grid points only) and both sides of every grid point (the acceleration jumps there).
        Sorted and unique, or with ``ordered=False`` the same set unsorted, with repeats (for
        a largest value over them, which needs no sort)."""
        prof = self.profile
        s_geo = self.geometric_positions(resolution)
        check_sample_count(s_geo.shape[0] + prof.s.shape[0] * (SUBSAMPLES + 3))
        ds = np.diff(prof.s)
        frac = np.concatenate(
            [[1e-9], np.arange(1, SUBSAMPLES + 1) / (SUBSAMPLES + 1), [1.0 - 1e-9]]
        )
        s_sub = (prof.s[:-1, None] + ds[:, None] * frac[None, :]).ravel()
        every = np.concatenate([s_geo, s_sub, prof.s])
        return np.unique(every) if ordered else every

    def geometric_positions(self, resolution: float) -> np.ndarray:
        """Path positions evenly ``resolution`` apart at most along s, both ends included:
        the part of :meth:`check_path_positions` that bounds the joint-space gap between
        checked postures (s is the joint-space arc length)."""
        n = max(2, int(np.ceil(self.path.length / resolution)) + 1)
        return np.linspace(self.profile.s[0], self.profile.s[-1], n)

    def validity_times(self, resolution: float) -> np.ndarray:
        """Times of :meth:`geometric_positions`, sorted and unique (each one of
        :meth:`check_times`, to the bit: the profile is read position by position): where
        the dense re-check tests the path's validity rules (with the output samples). The
        rules of a posture depend on the posture alone, and these are at most
        ``resolution`` apart; the other check times (inside every grid interval and on
        both sides of its ends) are there for the limits, which toppra certifies at the
        grid points only."""
        t, _, _ = self.profile.at_path(self.geometric_positions(resolution))
        return np.unique(np.clip(t, 0.0, self.profile.duration))

    def check_times(self, resolution: float, positions: np.ndarray | None = None) -> np.ndarray:
        """Times of :meth:`check_path_positions` (``positions`` when the caller has them
        already: the time-scale fit measured the same ones), sorted and unique (so the
        positions need not be: the same times either way)."""
        if positions is None:
            positions = self.check_path_positions(resolution, ordered=False)
        s = positions
        t, _, _ = self.profile.at_path(s)
        return np.unique(np.clip(t, 0.0, self.profile.duration))

    def plan_segments(self, t: np.ndarray) -> np.ndarray:
        """On the blend of vertex k: segments k-1 and k; on a straight piece: (-1, -1)."""
        s, _, _ = self.profile.at_time(t)
        k = self.path.arc_corner_at(s)
        return np.where(k[:, None] >= 0, np.stack([k - 1, k], axis=1), -1)


def sample_times(duration: float, rate_hz: float) -> np.ndarray:
    """0, 1/rate, 2/rate, ... and the end time exactly (the last step may be shorter), s."""
    n = int(np.floor(duration * rate_hz + 1e-9))
    t = np.arange(n + 1) / rate_hz
    t = t[t < duration - 1e-12]
    return np.append(t, duration)


def p_velocity(
    design: Design, q: np.ndarray, qd: np.ndarray, assembly_mode: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Point P and its velocity dP/dt = J(q) qd for postures q (M, 3) and rates qd (M, 3).

    :func:`planner.kinematics.forward_velocity`: the loop closure differentiated in one
    compiled pass (it was a central difference of :func:`planner.forward_batch` along qd,
    three direct kinematics per posture; the two agree to the difference's own error, 2e-10
    relative, ``tests/core/test_kinematics.py``).

    Returns
    -------
    p : shape (M, 3), m
    v : shape (M, 3), m/s (NaN where a posture does not assemble)
    ok : shape (M,), bool -- the posture assembles in ``assembly_mode`` (and CD is not
        stretched, where the velocity is unbounded).
    """
    return forward_velocity(
        design, np.asarray(q, dtype=float), np.asarray(qd, dtype=float), assembly_mode
    )


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A timed trajectory sampled at a fixed rate, with its measured quality.

    Attributes
    ----------
    method : "toppra" | "ruckig"
    duration : float, s
    t : shape (M,), s -- 0, 1/rate, ..., duration (the last step may be shorter).
    q, qd, qdd : shape (M, 3) -- rad, rad/s, rad/s^2.
    jerk : shape (M, 3), rad/s^3, or None (toppra: acceleration is piecewise constant).
    p : shape (M, 3), m -- point P.
    p_speed : shape (M,), m/s -- |dP/dt|.
    max_deviation_q : float, rad
        Largest joint-space distance from the timed trajectory to the planned polyline, over
        the dense check samples. Each posture is measured against the planned segments it
        stands for (the two segments of its corner), not against any far part of the plan
        that happens to pass nearby, so this is an upper bound of the distance to the plan.
    max_deviation_p : float, m
        Largest distance between P of a timed posture and P of its nearest planned posture
        (the closest point of those segments in joint space), over the same samples.
    repairs : int
        Repair rounds taken (0: the first trajectory passed the dense re-check).
    checked_samples : int
        Postures in the dense re-check of the returned trajectory.
    computation_time_s : float
    curve : the continuous trajectory (``evaluate(t)`` at any time).
    tau : shape (M, 3), N m, or None -- actuator torques of the samples (with an inertial
        model or torque limits: :mod:`planner.timing.torque`).
    max_torque_ratio : float or None -- largest |tau_j| / torque limit over the dense
        re-check (with torque limits; <= 1 when they hold).
    """

    method: str
    duration: float
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    jerk: np.ndarray | None
    p: np.ndarray
    p_speed: np.ndarray
    max_deviation_q: float
    max_deviation_p: float
    repairs: int
    checked_samples: int
    computation_time_s: float
    curve: Curve
    tau: np.ndarray | None = None
    max_torque_ratio: float | None = None

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """(q, qd, qdd, jerk or None) at any times t (M,) in [0, duration]."""
        return self.curve.evaluate(np.atleast_1d(np.asarray(t, dtype=float)))


@dataclass(frozen=True, eq=False)
class TimeScaledCurve:
    """``base`` slowed uniformly in time by ``c`` (0 < c <= 1): q(t) = base.q(c t), so
    velocities scale by c, accelerations by c^2 and jerks by c^3, all within the base's limits;
    the speed of P scales by c. The same postures are visited, so validity is unchanged."""

    base: Curve
    c: float

    @property
    def duration(self) -> float:
        return self.base.duration / self.c

    def evaluate(
        self, t: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        q, qd, qdd, jerk = self.base.evaluate(np.asarray(t, dtype=float) * self.c)
        c = self.c
        return q, qd * c, qdd * c**2, None if jerk is None else jerk * c**3

    def check_times(self, resolution: float) -> np.ndarray:
        return self.base.check_times(resolution) / self.c

    def rest_times(self) -> np.ndarray:
        return self.base.rest_times() / self.c

    def plan_segments(self, t: np.ndarray) -> np.ndarray:
        return self.base.plan_segments(np.asarray(t, dtype=float) * self.c)


@dataclass(frozen=True, eq=False)
class RestCurve:
    """A path of zero length: the robot stays at ``q`` (duration 0)."""

    q: np.ndarray

    @property
    def duration(self) -> float:
        return 0.0

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, None]:
        m = np.atleast_1d(t).shape[0]
        zeros = np.zeros((m, 3))
        return np.broadcast_to(self.q, (m, 3)).copy(), zeros, zeros.copy(), None

    def check_times(self, resolution: float) -> np.ndarray:
        return np.zeros(1)

    def rest_times(self) -> np.ndarray:
        return np.empty(0)

    def plan_segments(self, t: np.ndarray) -> np.ndarray:
        return np.full((np.shape(t)[0], 2), -1)
