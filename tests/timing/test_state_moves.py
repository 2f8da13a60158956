"""Moves between joint states (:mod:`planner.timing.state_moves`), held to Ruckig's own
sampling (``at_time``): the position extrema of a move, and the curve ending exactly in the
state asked, at the least duration."""

from __future__ import annotations

import numpy as np
import pytest

from planner.timing import JointLimits
from planner.timing.state_moves import StateMover, position_extrema


@pytest.mark.parametrize("jerk", [False, True])
def test_position_extrema_match_the_sampled_move(jerk):
    """Second-order moves too, where Ruckig's own ``position_extrema`` is wrong."""
    rng = np.random.default_rng(3)
    mover = StateMover(JointLimits.default(), jerk=jerk)
    checked = 0
    for _ in range(20):
        a = (rng.uniform(-2, 2, 3), rng.uniform(-1.5, 1.5, 3), np.zeros(3))
        b = (rng.uniform(-2, 2, 3), rng.uniform(-1.5, 1.5, 3), np.zeros(3))
        traj = mover._solve(a, b)
        ext = position_extrema(traj)
        if ext is None:
            continue
        t = np.linspace(0.0, traj.duration, 1500)
        q = np.array([traj.at_time(float(x))[0] for x in t])
        assert np.allclose(q.min(axis=0), ext[0], atol=1e-5)
        assert np.allclose(q.max(axis=0), ext[1], atol=1e-5)
        checked += 1
    assert checked >= 15


def test_a_move_ends_in_the_state_asked():
    mover = StateMover(JointLimits.default(), jerk=True)
    a = (np.array([0.1, 0.5, -0.3]), np.zeros(3), np.zeros(3))
    b = (np.array([0.8, 0.2, 0.4]), np.array([0.5, -0.3, 0.2]), np.array([1.0, 0.0, -1.0]))
    curve = mover.curve(a, b)
    q, qd, qdd, _ = curve.evaluate(np.array([0.0, curve.duration]))
    assert np.allclose(q[0], a[0]) and np.allclose(qd[0], 0)
    assert np.allclose(q[1], b[0], atol=1e-9) and np.allclose(qd[1], b[1], atol=1e-9)
    assert np.allclose(qdd[1], b[2], atol=1e-6)
    assert mover.duration(a, b) == pytest.approx(curve.duration)
    bounds = (np.full(3, -0.2), np.full(3, 0.6))  # joint 1 ends at 0.8: outside
    assert mover.duration(a, b, bounds) == np.inf
