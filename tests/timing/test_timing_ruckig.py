"""Ruckig timing: jerk limits, continuity of q, qd, qdd, exact ends at rest, agreement with
Ruckig's own evaluation, straight rest-to-rest moves, and duration against toppra."""

from __future__ import annotations

import numpy as np
import pytest
from ruckig import InputParameter, Ruckig
from timing_factories import fine_times, random_walk, segment_distance_to_polyline

from planner import Design
from planner.exceptions import TimingInfeasibleError
from planner.timing import LIMIT_RTOL, JointLimits, ruckig_method, time_path
from planner.timing.path import BlendedPath
from planner.timing.ruckig_method import _MIDDLE, _solve_move, _through_marks
from planner.timing.toppra_method import min_blend_radius, solve_toppra
from planner.timing.trajectory import TimeScaledCurve

DESIGN = Design.default()
LIMITS = JointLimits(velocity=(2.0, 1.5, 2.5), acceleration=(8.0, 6.0, 10.0), jerk=(200.0,) * 3)
TOL = 1 + LIMIT_RTOL


@pytest.mark.parametrize("seed", range(3))
def test_limits_and_continuity(seed):
    w = random_walk(seed, n=6)
    traj = time_path(DESIGN, w, LIMITS, method="ruckig", sample_rate_hz=250.0)
    assert traj.jerk is not None
    t = fine_times(traj.duration, 40001)
    q, qd, qdd, jerk = traj.at(t)
    for x, lim in ((qd, LIMITS.velocity), (qdd, LIMITS.acceleration), (jerk, LIMITS.jerk)):
        assert np.all(np.abs(x) <= np.asarray(lim) * TOL)
    for x, lim in ((traj.qd, LIMITS.velocity), (traj.qdd, LIMITS.acceleration)):
        assert np.all(np.abs(x) <= np.asarray(lim) * TOL)
    # q, qd and qdd continuous: steps bounded by the next derivative's limit.
    dt = t[1] - t[0]
    for x, lim in ((q, LIMITS.velocity), (qd, LIMITS.acceleration), (qdd, LIMITS.jerk)):
        assert np.all(np.abs(np.diff(x, axis=0)) <= np.asarray(lim) * dt * TOL + 1e-9)
    # Both sides of every move boundary agree.
    bounds = traj.curve.start[1:-1]
    for eps in (1e-9,):
        a = traj.at(bounds - eps)
        b = traj.at(bounds + eps)
        for k, lim in enumerate((LIMITS.velocity, LIMITS.acceleration, LIMITS.jerk)):
            np.testing.assert_allclose(a[k], b[k], atol=np.max(lim) * 2 * eps + 1e-7)


@pytest.mark.parametrize("seed", range(2))
def test_starts_and_ends_exactly_at_rest(seed):
    w = random_walk(seed, n=5)
    traj = time_path(DESIGN, w, LIMITS, method="ruckig")
    assert np.array_equal(traj.q[0], w[0]) and np.array_equal(traj.q[-1], w[-1])
    q, qd, qdd, _ = traj.at(np.array([0.0, traj.duration]))
    np.testing.assert_allclose(q, w[[0, -1]], atol=1e-9)
    np.testing.assert_allclose(qd, 0.0, atol=1e-9)
    np.testing.assert_allclose(qdd, 0.0, atol=1e-9)


def test_vectorised_evaluation_matches_ruckig_at_time():
    w = random_walk(4, n=5)
    traj = time_path(DESIGN, w, LIMITS, method="ruckig")
    rng = np.random.default_rng(0)
    for move in traj.curve.moves:
        tau = np.sort(rng.uniform(0, move.duration, 10))
        ours = move.evaluate(tau)
        ref = move.source  # Ruckig's own trajectory object, evaluated by Ruckig
        assert not move.braking
        for i, x in enumerate(tau):
            pos, vel, acc = ref.at_time(float(x))
            np.testing.assert_allclose(ours[0][i], pos, atol=1e-9)
            np.testing.assert_allclose(ours[1][i], vel, atol=1e-9)
            np.testing.assert_allclose(ours[2][i], acc, atol=1e-9)


def test_rest_to_rest_moves_stay_on_the_segments():
    w = random_walk(2, n=6)
    traj = time_path(DESIGN, w, LIMITS, method="ruckig", max_deviation=0.0)
    q, _, _, _ = traj.at(fine_times(traj.duration, 3001))
    assert segment_distance_to_polyline(w, q).max() < 1e-3
    assert traj.max_deviation_q < 1e-9


def test_duration_relative_to_toppra():
    ratios, stop_ratios, devs = [], [], []
    for seed in range(4):
        w = random_walk(seed, n=10)
        top = time_path(DESIGN, w, LIMITS)
        ruck = time_path(DESIGN, w, LIMITS, method="ruckig")
        stop = time_path(DESIGN, w, LIMITS, method="ruckig", max_deviation=0.0)
        ratios.append(ruck.duration / top.duration)
        stop_ratios.append(stop.duration / top.duration)
        devs.append(ruck.max_deviation_q)
    # Jerk limits cost some time, through-waypoint states much less than resting at each.
    assert all(0.95 < r < 1.25 for r in ratios), ratios
    assert all(r < s for r, s in zip(ratios, stop_ratios, strict=True))
    assert max(devs) < 0.1


def test_ruckig_errors_become_timing_errors():
    otg, inp = Ruckig(3), InputParameter(3)
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [1.0] * 3, [1.0] * 3, [1.0] * 3
    zero = np.zeros(3)
    too_fast = (np.ones(3), np.array([5.0, 0.0, 0.0]), zero)  # beyond the velocity limit
    with pytest.raises(TimingInfeasibleError, match="ruckig"):
        _solve_move(otg, inp, (zero, zero, zero), too_fast, ())


def test_move_speed_bound_covers_the_sampled_speed_and_check_spacing():
    w = random_walk(3, n=6)
    traj = time_path(DESIGN, w, LIMITS, method="ruckig")
    curve = traj.curve
    for k, move in enumerate(curve.moves):
        tau = np.linspace(0, move.duration, 20001)
        qd = move.evaluate(tau)[1]
        bound = move.speed_bound(fallback=np.inf)
        assert np.linalg.norm(qd, axis=1).max() <= bound * (1 + 1e-9)
        # It is the norm of each joint's peak speed, found exactly (not just a safe bound).
        per_joint_peak = np.abs(qd).max(axis=0)
        assert bound == pytest.approx(np.linalg.norm(per_joint_peak), rel=1e-4, abs=1e-9), k
    t = curve.check_times(0.01)
    q = curve.evaluate(t)[0]
    assert np.max(np.linalg.norm(np.diff(q, axis=0), axis=1)) <= 0.01 + 1e-12


def test_cartesian_speed_bound_with_ruckig():
    w = random_walk(9, n=6)
    free = time_path(DESIGN, w, LIMITS, method="ruckig")
    vmax = 0.5 * float(free.p_speed.max())
    traj = time_path(
        DESIGN, w, LIMITS, method="ruckig", max_cartesian_speed=vmax, sample_rate_hz=500.0
    )
    assert traj.p_speed.max() <= vmax * TOL
    assert traj.duration > free.duration
    assert isinstance(traj.curve, TimeScaledCurve)  # the chain needed the uniform slow-down
    t = fine_times(traj.duration, 20001)
    _, qd, qdd, jerk = traj.at(t)
    for x, lim in ((qd, LIMITS.velocity), (qdd, LIMITS.acceleration), (jerk, LIMITS.jerk)):
        assert np.all(np.abs(x) <= np.asarray(lim) * TOL)
    # Independent route: finite differences of P over time on the output samples.
    dp = np.linalg.norm(np.diff(traj.p, axis=0), axis=1) / np.diff(traj.t)
    assert vmax * 0.95 <= dp.max() <= vmax * 1.001


@pytest.mark.parametrize("delta", [0.02, 0.05])
def test_deviation_is_held_to_max_deviation(delta):
    for seed in range(3):
        w = random_walk(10 + seed, n=8)
        traj = time_path(DESIGN, w, LIMITS, method="ruckig", max_deviation=delta)
        q, _, _, _ = traj.at(fine_times(traj.duration, 2001))
        assert segment_distance_to_polyline(w, q).max() <= delta + 1e-3
        assert 0.0 < traj.max_deviation_q <= delta * (1 + 1e-9)


def _benchmark_walks(n: int) -> list[np.ndarray]:
    """The seeded 20-waypoint walks of ``benchmarks/timing.py`` (same generator and seed)."""
    rng = np.random.default_rng(0)
    return [
        np.clip(np.cumsum(rng.uniform(-0.5, 0.5, size=(20, 3)), axis=0), -2.5, 2.5)
        for _ in range(n)
    ]


def test_curve_evaluation_matches_ruckig_move_by_move():
    """The chain's stacked phase tables against Ruckig's own evaluation of the active move."""
    w = random_walk(5, n=8)
    traj = time_path(DESIGN, w, LIMITS, method="ruckig")
    curve = traj.curve
    t = np.random.default_rng(1).uniform(0, curve.duration, 400)
    q, qd, qdd, _ = curve.evaluate(t)
    for i, x in enumerate(t):
        k = int(curve.move_index(np.array([x]))[0])
        pos, vel, acc = curve.moves[k].source.at_time(float(x - curve.start[k]))
        np.testing.assert_allclose(q[i], pos, atol=1e-9)
        np.testing.assert_allclose(qd[i], vel, atol=1e-9)
        np.testing.assert_allclose(qdd[i], acc, atol=1e-8)


def test_short_segment_between_blends_becomes_one_middle_state():
    """Benchmark path 79 has a segment toppra crosses in 0.018 s between two blends: with an
    exit and an entry there, Ruckig needed 0.50 s for it and the whole path took 1.24x
    toppra's duration; with one state at its middle, within 1.2x (and every limit and the
    deviation allowance hold, as the dense re-check of time_path guarantees)."""
    limits = JointLimits.default().with_ruckig_jerk()
    w = _benchmark_walks(80)[79]
    path = BlendedPath.from_waypoints(
        w, np.full(20, 0.05), np.zeros(20, bool), min_blend_radius(limits)
    )
    profile = solve_toppra(path, limits)
    t_merge = float(np.max(limits.acceleration_array / limits.jerk_array))
    tags = [m[1] for m in _through_marks(path, profile, t_merge)]
    assert _MIDDLE in tags
    assert _MIDDLE not in [m[1] for m in _through_marks(path, profile, 0.0)]
    top = time_path(DESIGN, w, limits)
    ruck = time_path(DESIGN, w, limits, method="ruckig")
    assert ruck.duration / top.duration <= 1.2
    q = ruck.at(fine_times(ruck.duration, 20001))[0]
    assert segment_distance_to_polyline(w, q).max() <= 0.05 + 1e-3


def test_patience_chooses_as_trying_every_factor(monkeypatch):
    """The greedy speed choice stopping after PATIENCE worse factors against trying all of
    them: the same chains (durations equal) on seeded benchmark paths."""
    limits = JointLimits.default()
    walks = _benchmark_walks(6)
    short = [time_path(DESIGN, w, limits, method="ruckig").duration for w in walks]
    monkeypatch.setattr(ruckig_method, "PATIENCE", len(ruckig_method.SPEED_FACTORS))
    full = [time_path(DESIGN, w, limits, method="ruckig").duration for w in walks]
    np.testing.assert_allclose(short, full, rtol=1e-3)


def test_moves_through_middle_states_stand_for_their_blends():
    """With a low jerk limit (a / j = 0.2 s) most segments between blends get a middle state,
    often several in a row. A move between two of them passes a blend: it must stand for it
    (its plan segments are checked for deviation), and only a rest-to-rest move may stand for
    none. Independently of the library's check, no posture strays farther from the polyline
    than the allowance plus half the check resolution (the dense re-check's guarantee)."""
    limits = JointLimits(velocity=(2.0,) * 3, acceleration=(8.0,) * 3, jerk=(40.0,) * 3)
    chained = 0
    for seed in range(4):
        w = random_walk(seed, n=8)
        traj = time_path(DESIGN, w, limits, method="ruckig")
        curve = traj.curve
        for k, move in enumerate(curve.moves):
            if not move.corners:
                ends = curve.evaluate(curve.start[k : k + 2] + np.array([1e-12, -1e-12]))[1]
                assert np.abs(ends).max() < 1e-6, k
        chained += sum(len(m.corners) >= 3 for m in curve.moves)
        q = traj.at(fine_times(traj.duration, 20001))[0]
        assert segment_distance_to_polyline(w, q).max() <= 0.05 + 0.005
    assert chained > 0  # middle states in a row were exercised
