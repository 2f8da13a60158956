"""Pass-through corners as free via states (:mod:`planner.timing.vias`): the trajectory passes
within each ball, keeps every limit (checked on a fine grid and against finite differences of
its own positions), is never slower than the blended path and never faster than the
per-joint time-optimal bound; a chain that fails the re-check gives way to the blended path."""

from __future__ import annotations

import math

import numpy as np
import pytest
from timing_factories import fine_times

from planner import Design, forward_batch
from planner.timing import LIMIT_RTOL, JointLimits, time_path
from planner.timing.vias import SplicedCurve

DESIGN = Design.default()
LIMITS = JointLimits.default()
TOL = 1 + LIMIT_RTOL
#: The default design's Adept cycle, first half (pick, up 20 mm, across 244 mm, place), in
#: joint space: the vertical legs are about 0.1 rad, the across one 0.87 rad (joint 3).
ADEPT = np.array(
    [
        [0.90975316, -0.10880946, 1.24575975],
        [0.88760000, -0.18998000, 1.19424000],
        [0.88760000, -0.13820000, 0.32524000],
        [0.90975000, -0.06145000, 0.39151000],
    ]
)
BLENDS = np.array([0.0, 0.0444, 0.0467, 0.0])


def rest_to_rest(d: float, v: float, a: float) -> float:
    """Least time of one joint moving ``d`` from rest to rest (trapezoid or triangle)."""
    return d / v + v / a if d > v * v / a else 2.0 * math.sqrt(d / a)


def first_half_bound(w: np.ndarray, blends: np.ndarray, lim: JointLimits) -> float:
    """A lower bound of any motion from rest at w[0] to rest at w[3] passing within
    blends[2] of w[2], by joint 3 alone: it must come within blends[2] of w[2][2] (below
    w[3][2], so it turns there, at rest) and then climb back to w[3][2]."""
    v, a = lim.velocity[2], lim.acceleration[2]
    low = w[2, 2] + blends[2]
    return rest_to_rest(w[0, 2] - low, v, a) + rest_to_rest(w[3, 2] - low, v, a)


# toppra's gain over its own arcs: 10 % on the grid of before issue 36, 8.3 % since the arcs
# themselves are timed on a finer grid (0.8878 -> 0.8692 s, 2.1 % shorter; the vias 0.796 s)
@pytest.mark.parametrize(("method", "gain"), [("toppra", 0.07), ("ruckig", 0.03)])
def test_vias_pass_within_each_ball_within_the_limits(method, gain):
    arcs = time_path(DESIGN, ADEPT, LIMITS, method=method, max_deviation=BLENDS)
    traj = time_path(DESIGN, ADEPT, LIMITS, method=method, max_deviation=BLENDS, via_at=[1, 2])
    assert isinstance(traj.curve, SplicedCurve)
    # faster than the arcs, and still no faster than the per-joint bound
    assert traj.duration < (1.0 - gain) * arcs.duration
    assert traj.duration >= first_half_bound(ADEPT, BLENDS, LIMITS)
    t = fine_times(traj.duration, 20001)
    q, qd, qdd, _ = traj.at(t)
    # within each ball, in order (the lift's corner first)
    d1 = np.linalg.norm(q - ADEPT[1], axis=1)
    d2 = np.linalg.norm(q - ADEPT[2], axis=1)
    assert d1.min() <= BLENDS[1] and d2.min() <= BLENDS[2]
    assert t[np.argmin(d1)] < t[np.argmin(d2)]
    # the limits on the fine grid, and qd, qdd the derivatives of q (finite differences)
    assert np.all(np.abs(qd) <= LIMITS.velocity_array * TOL)
    assert np.all(np.abs(qdd) <= LIMITS.acceleration_array * TOL)
    dt = t[1] - t[0]
    fd = np.diff(q, axis=0) / dt
    mid = 0.5 * (qd[1:] + qd[:-1])
    assert np.max(np.abs(fd - mid)) <= LIMITS.acceleration_array.max() * dt
    # ends exact and at rest; output times strictly increasing
    assert np.allclose(traj.q[0], ADEPT[0]) and np.allclose(traj.q[-1], ADEPT[-1])
    assert np.all(traj.qd[[0, -1]] == 0.0)
    assert np.all(np.diff(traj.t) > 0)


def test_a_chain_only_where_every_interior_waypoint_is_a_via():
    arcs = time_path(DESIGN, ADEPT, LIMITS, max_deviation=BLENDS)
    one = time_path(DESIGN, ADEPT, LIMITS, max_deviation=BLENDS, via_at=[1])
    assert not isinstance(one.curve, SplicedCurve)
    assert one.duration == pytest.approx(arcs.duration, rel=1e-12)


def test_a_chain_that_fails_the_re_check_gives_way_to_the_blended_path():
    arcs = time_path(DESIGN, ADEPT, LIMITS, max_deviation=BLENDS)
    traj = time_path(DESIGN, ADEPT, LIMITS, max_deviation=BLENDS, via_at=[1, 2])
    # a small joint-space ball on the chain's own motion, away from the arcs' motion
    q_via = traj.at(fine_times(traj.duration, 4001))[0]
    q_arc = arcs.at(fine_times(arcs.duration, 4001))[0]
    far = np.min(np.linalg.norm(q_via[:, None] - q_arc[None], axis=2), axis=1)
    centre = q_via[int(np.argmax(far))]
    radius = 0.5 * float(far.max())
    assert radius > 0.003

    def check(q: np.ndarray) -> np.ndarray:
        return np.linalg.norm(q - centre, axis=1) > radius

    assert np.all(check(q_arc))
    kept = time_path(DESIGN, ADEPT, LIMITS, max_deviation=BLENDS, via_at=[1, 2], check_states=check)
    assert kept.repairs >= 1
    assert kept.duration == pytest.approx(arcs.duration, rel=1e-9)
    assert np.all(check(kept.at(fine_times(kept.duration, 4001))[0]))


def test_a_chain_keeps_the_cartesian_speed_bound():
    """A chain slowed uniformly for the bound (ruckig: still faster than its arcs; toppra's
    own profile under the bound beats a uniformly slowed chain, and is kept)."""
    method = "ruckig"
    free = time_path(DESIGN, ADEPT, LIMITS, method=method, max_deviation=BLENDS, via_at=[1, 2])
    bound = 0.5 * float(np.max(free.p_speed))
    traj = time_path(
        DESIGN,
        ADEPT,
        LIMITS,
        method=method,
        max_deviation=BLENDS,
        via_at=[1, 2],
        max_cartesian_speed=bound,
    )
    q, qd, _, _ = traj.at(fine_times(traj.duration, 20001))
    # P's speed recomputed here by central differences of the forward kinematics
    h = 1e-6
    v_p = np.zeros((q.shape[0], 3))
    for j in range(3):
        e = np.zeros(3)
        e[j] = h
        dp = (forward_batch(DESIGN, q + e, "+").p - forward_batch(DESIGN, q - e, "+").p) / (2 * h)
        v_p += dp * qd[:, j : j + 1]
    speed = v_p
    assert isinstance(traj.curve, SplicedCurve)
    assert np.max(np.linalg.norm(speed, axis=1)) <= bound * (1 + 1e-5)
    assert traj.duration > free.duration
