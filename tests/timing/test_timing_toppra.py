"""toppra timing: limits at every sample, exact ends at rest, closed-form durations,
deviation within the blend, stops, and the Cartesian speed bound."""

from __future__ import annotations

import numpy as np
import pytest
from timing_factories import fine_times, random_walk, segment_distance_to_polyline

from planner import Design, Manipulator, forward_batch
from planner.timing import LIMIT_RTOL, JointLimits, time_path
from planner.timing.trajectory import p_velocity

DESIGN = Design.default()
LIMITS = JointLimits(velocity=(2.0, 1.5, 2.5), acceleration=(8.0, 6.0, 10.0))  # no jerk asked
TOL = 1 + LIMIT_RTOL


def assert_within_limits(qd, qdd, limits=LIMITS, tol=TOL):
    assert np.all(np.abs(qd) <= np.asarray(limits.velocity) * tol)
    assert np.all(np.abs(qdd) <= np.asarray(limits.acceleration) * tol)


@pytest.mark.parametrize("seed", range(4))
def test_limits_hold_at_every_sample_and_between(seed):
    w = random_walk(seed, n=7)
    traj = time_path(DESIGN, w, LIMITS, sample_rate_hz=250.0)
    assert traj.method == "toppra" and traj.jerk is None
    assert_within_limits(traj.qd, traj.qdd)
    # An independent fine grid, not the library's check times.
    q, qd, qdd, _ = traj.at(fine_times(traj.duration, 50001))
    assert_within_limits(qd, qdd)
    # q continuous: consecutive fine samples no farther apart than the speed allows.
    dt = traj.duration / 50000
    step = np.abs(np.diff(q, axis=0))
    assert np.all(step <= np.asarray(LIMITS.velocity) * dt * TOL + 1e-12)
    # qd is the time derivative of q (central differences on the fine grid).
    fd = (q[2:] - q[:-2]) / (2 * dt)
    assert np.median(np.abs(fd - qd[1:-1])) < 1e-6
    assert np.max(np.abs(fd - qd[1:-1])) < np.max(LIMITS.acceleration) * dt


@pytest.mark.parametrize("seed", range(3))
def test_starts_and_ends_exactly_at_rest(seed):
    w = random_walk(seed, n=5)
    traj = time_path(DESIGN, w, LIMITS)
    assert np.array_equal(traj.q[0], w[0]) and np.array_equal(traj.q[-1], w[-1])
    assert traj.t[0] == 0.0 and traj.t[-1] == traj.duration
    assert np.all(np.diff(traj.t) > 0) and np.all(np.diff(traj.t) <= 1 / 100.0 + 1e-12)
    assert np.all(traj.qd[[0, -1]] == 0.0)
    # The continuous curve itself starts and ends there (not only the forced samples).
    q, qd, _, _ = traj.at(np.array([0.0, traj.duration]))
    np.testing.assert_allclose(q, w[[0, -1]], atol=1e-12)
    np.testing.assert_allclose(qd, 0.0, atol=1e-9)


@pytest.mark.parametrize(
    ("delta", "shape"), [([1.2, -0.4, 0.3], "trapezoid"), ([0.2, 0.1, -0.05], "triangle")]
)
def test_straight_move_matches_closed_form_duration(delta, shape):
    # One segment, rest to rest: along direction u the path speed is bounded by
    # min_j v_j / |u_j| and the path acceleration by min_j a_j / |u_j|; the time-optimal
    # profile is a trapezoid (or a triangle when the cruise speed is not reached).
    q0 = np.array([0.1, 0.2, 0.3])
    w = np.stack([q0, q0 + delta])
    length = np.linalg.norm(delta)
    u = np.abs(np.asarray(delta)) / length
    v = np.min(np.asarray(LIMITS.velocity) / u)
    a = np.min(np.asarray(LIMITS.acceleration) / u)
    if length >= v**2 / a:
        expected = length / v + v / a
        assert shape == "trapezoid"
    else:
        expected = 2 * np.sqrt(length / a)
        assert shape == "triangle"
    traj = time_path(DESIGN, w, LIMITS)
    assert expected * (1 - 1e-6) <= traj.duration <= expected * 1.02
    assert traj.max_deviation_q == 0.0


@pytest.mark.parametrize("delta", [0.02, 0.1])
def test_deviation_stays_within_the_blend(delta):
    w = random_walk(5, n=8)
    traj = time_path(DESIGN, w, LIMITS, max_deviation=delta)
    q, _, _, _ = traj.at(fine_times(traj.duration, 2001))
    exact = segment_distance_to_polyline(w, q)
    assert exact.max() <= delta + 1e-3
    assert traj.max_deviation_q <= delta + 1e-9
    assert traj.max_deviation_q == pytest.approx(exact.max(), abs=3e-3)
    assert traj.max_deviation_p > 0


def test_blending_is_faster_than_stopping_and_zero_deviation_follows_the_polyline():
    w = random_walk(6, n=8)
    blended = time_path(DESIGN, w, LIMITS, max_deviation=0.05)
    exact = time_path(DESIGN, w, LIMITS, max_deviation=0.0)
    assert blended.duration < exact.duration
    q, qd, _, _ = exact.at(fine_times(exact.duration, 8001))
    assert segment_distance_to_polyline(w, q).max() < 1e-3
    assert exact.max_deviation_q == 0.0
    # It comes to rest at every interior vertex.
    for k in range(1, len(w) - 1):
        i = np.argmin(np.linalg.norm(q - w[k], axis=1))
        assert np.linalg.norm(q[i] - w[k]) < 1e-3
        assert np.linalg.norm(qd[i]) < 0.2


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_stop_at_brings_the_trajectory_to_rest_on_the_waypoint(method):
    w = random_walk(7, n=6)
    traj = time_path(DESIGN, w, LIMITS, method=method, stop_at=[2])
    t = fine_times(traj.duration, 20001)
    q, qd, _, _ = traj.at(t)
    i = np.argmin(np.linalg.norm(q - w[2], axis=1))
    assert np.linalg.norm(q[i] - w[2]) < 1e-4
    assert np.linalg.norm(qd[i]) < np.max(LIMITS.acceleration) * (t[1] - t[0]) * 2
    # ... and passes other vertices without stopping.
    j = np.argmin(np.linalg.norm(q - w[3], axis=1))
    assert np.linalg.norm(qd[j]) > 0.1
    # the stop instant is an output sample carrying the rest state, qd = qdd = 0 (issue 36:
    # toppra's acceleration jumps there, from braking to starting, on either side of it)
    k = int(np.argmin(np.linalg.norm(traj.q - w[2], axis=1)))
    assert np.linalg.norm(traj.q[k] - w[2]) < 1e-9
    assert np.all(traj.qd[k] == 0.0) and np.all(traj.qdd[k] == 0.0)
    eps = 1e-6
    _, _, before, _ = traj.at(np.array([traj.t[k] - eps]))
    _, _, after, _ = traj.at(np.array([traj.t[k] + eps]))
    if method == "toppra":
        assert np.linalg.norm(before) > 0.1 and np.linalg.norm(after) > 0.1


def test_p_velocity_agrees_with_the_jacobians():
    rng = np.random.default_rng(0)
    m = Manipulator(DESIGN)
    q = random_walk(8, n=20)
    qd = rng.normal(size=(20, 3))
    p, v, ok = p_velocity(DESIGN, q, qd, "+")
    for i in np.flatnonzero(ok):
        post = m.posture(q[i], "+")
        a, b = m.jacobians(post)
        np.testing.assert_allclose(p[i], post.p, atol=1e-12)
        np.testing.assert_allclose(v[i], np.linalg.solve(a, b @ qd[i]), atol=1e-7)


def test_cartesian_speed_bound_holds_and_binds():
    w = random_walk(9, n=6)
    free = time_path(DESIGN, w, LIMITS)
    vmax = 0.5 * float(free.p_speed.max())
    traj = time_path(DESIGN, w, LIMITS, max_cartesian_speed=vmax, sample_rate_hz=500.0)
    assert traj.p_speed.max() <= vmax * TOL
    assert traj.duration > free.duration
    assert_within_limits(traj.qd, traj.qdd)
    # Independent route: finite differences of P over time on the samples.
    dp = np.linalg.norm(np.diff(traj.p, axis=0), axis=1) / np.diff(traj.t)
    assert dp.max() <= vmax * 1.001
    assert dp.max() >= vmax * 0.95  # the bound is active somewhere


def test_single_point_path_has_zero_duration():
    w = np.array([[0.1, 0.2, 0.3], [0.1, 0.2, 0.3]])
    traj = time_path(DESIGN, w, LIMITS)
    assert traj.duration == 0.0 and traj.t.tolist() == [0.0]
    assert np.array_equal(traj.q[0], w[0]) and np.all(traj.qd == 0)


def test_p_follows_the_requested_assembly_mode():
    w = random_walk(12, n=4)
    plus = time_path(DESIGN, w, LIMITS, assembly_mode="+")
    minus = time_path(DESIGN, w, LIMITS, assembly_mode="-")
    np.testing.assert_allclose(minus.q, plus.q)  # timing does not depend on the branch
    np.testing.assert_allclose(minus.p, forward_batch(DESIGN, minus.q, "-").p, atol=1e-12)
    np.testing.assert_allclose(plus.p, forward_batch(DESIGN, plus.q, "+").p, atol=1e-12)
    assert np.abs(minus.p - plus.p).max() > 1e-3


def _profile_at_numpy(prof, x, forward):
    """PathProfile.at_time / at_path as numpy arrays (their form before they were compiled)."""
    if forward:
        t = np.clip(np.asarray(x, dtype=float), 0.0, prof.duration)
        i = np.clip(np.searchsorted(prof.time, t, side="right") - 1, 0, prof.sdd.shape[0] - 1)
        tau = t - prof.time[i]
        a = prof.sdd[i]
        s = prof.s[i] + prof.sd[i] * tau + 0.5 * a * tau**2
        return np.minimum(s, prof.s[i + 1]), prof.sd[i] + a * tau, a
    s = np.clip(np.asarray(x, dtype=float), prof.s[0], prof.s[-1])
    i = np.clip(np.searchsorted(prof.s, s, side="right") - 1, 0, prof.sdd.shape[0] - 1)
    a = prof.sdd[i]
    sd = np.sqrt(np.maximum(prof.sd[i] ** 2 + 2 * a * (s - prof.s[i]), 0.0))
    dt = 2 * (s - prof.s[i]) / np.maximum(sd + prof.sd[i], 1e-300)
    return prof.time[i] + dt, sd, a


def test_profile_reads_equal_their_numpy_form_bit_for_bit():
    """The compiled reads of a toppra profile (``PathProfile.at_time``, ``at_path``) give
    the numpy form's values bit for bit: at times and positions inside, on the grid points
    (rests included: the profile of a path with a stop), outside (clipped), NaN kept NaN,
    a 0-d input read as numpy scalars and a 2-d one in its shape."""
    w = random_walk(np.random.default_rng(4), 6)
    traj = time_path(Design.default(), w, JointLimits.default(), stop_at=[2])
    prof = traj.curve.profile
    rng = np.random.default_rng(9)
    t = np.concatenate(
        [rng.uniform(-0.1, prof.duration + 0.1, 2000), prof.time, [np.nan, 0.0, prof.duration]]
    )
    s = np.concatenate([rng.uniform(prof.s[0] - 0.1, prof.s[-1] + 0.1, 2000), prof.s, [np.nan]])
    for x, forward in ((t, True), (s, False)):
        got = prof.at_time(x) if forward else prof.at_path(x)
        ref = _profile_at_numpy(prof, x, forward)
        for g, r in zip(got, ref, strict=True):
            assert np.array_equal(g, r, equal_nan=True)
        one = prof.at_time(x[5]) if forward else prof.at_path(x[5])
        assert all(isinstance(v, np.float64) and v == r[5] for v, r in zip(one, ref, strict=True))
        square = prof.at_time(x[:6].reshape(2, 3)) if forward else prof.at_path(x[:6].reshape(2, 3))
        assert all(np.array_equal(v, r[:6].reshape(2, 3)) for v, r in zip(square, ref, strict=True))
    assert np.sum(prof.sd[1:-1] == 0.0) >= 1  # a rest inside the profile
