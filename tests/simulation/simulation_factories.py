"""Trajectories for the simulation tests: rest-to-rest quintic moves (closed form), sampled."""

from __future__ import annotations

import numpy as np

from planner.simulation import Reference

Q0 = np.array([0.0, 2.0, 1.0])
Q1 = np.array([0.4, 2.3, 0.8])


def quintic_move(
    q0: np.ndarray = Q0, q1: np.ndarray = Q1, duration: float = 0.3, rate_hz: float = 1000.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t, q, qd, qdd) of the minimum-jerk move q0 -> q1 from rest to rest, sampled."""
    t = np.linspace(0.0, duration, round(duration * rate_hz) + 1)
    s = t / duration
    b = 10 * s**3 - 15 * s**4 + 6 * s**5
    bd = (30 * s**2 - 60 * s**3 + 30 * s**4) / duration
    bdd = (60 * s - 180 * s**2 + 120 * s**3) / duration**2
    d = q1 - q0
    return t, q0 + np.outer(b, d), np.outer(bd, d), np.outer(bdd, d)


def move_reference(**kwargs) -> Reference:
    return Reference(*quintic_move(**kwargs))


def there_and_back(dwell: float = 0.1, rate_hz: float = 1000.0) -> Reference:
    """Q0 -> Q1, a dwell at rest, Q1 -> Q0: one intermediate stop and the final one."""
    t1, q1, qd1, qdd1 = quintic_move(Q0, Q1, rate_hz=rate_hz)
    n = round(dwell * rate_hz)
    tw = t1[-1] + np.arange(1, n + 1) / rate_hz
    t2, q2, qd2, qdd2 = quintic_move(Q1, Q0, rate_hz=rate_hz)
    z = np.zeros((n, 3))
    return Reference(
        np.concatenate([t1, tw, tw[-1] + t2[1:]]),
        np.concatenate([q1, np.tile(Q1, (n, 1)), q2[1:]]),
        np.concatenate([qd1, z, qd2[1:]]),
        np.concatenate([qdd1, z, qdd2[1:]]),
    )
