"""``limits.jerk`` honoured by toppra (issue 39): each rest-to-rest section of its
time-optimal trajectory moving-averaged (``planner.timing.jerk_filter``).

Oracles independent of the filter's own jerk: finite differences of the trajectory's own
``qdd`` (at the output samples, and on a time grid of our own between them), finite
differences of ``q`` and ``qd`` against ``qd`` and ``qdd`` (the filter evaluates each from a
different formula), the velocity and acceleration limits on that grid, the rests on their
vertices, and the same path timed without a jerk (the unfiltered profile's jerk is far above
the limit, so these checks can fail)."""

from __future__ import annotations

import numpy as np
import pytest

from planner import Design, SequenceTarget, solve_sequence
from planner.cartesian import plan_cartesian
from planner.planning import JointPosture
from planner.timing import JointLimits, TimingOptions, time_path
from planner.timing.jerk_filter import WINDOW_FACTORS, JerkFilteredCurve

DESIGN = Design.default()
VEL, ACC, JERK = (2.0, 1.5, 2.5), (8.0, 6.0, 10.0), (150.0, 200.0, 250.0)
LIMITS = JointLimits(VEL, ACC, JERK)
#: Tolerance on every limit: the finite differences are averages of the exact jerk, which
#: the window holds 1e-3 inside the limit; 1e-6 is the dense re-check's own LIMIT_RTOL.
RTOL = 1e-6


def walk(seed: int, n: int = 7) -> np.ndarray:
    rng = np.random.default_rng(seed)
    steps = np.cumsum(rng.uniform(-0.5, 0.5, size=(n, 3)), axis=0)
    return np.clip(steps + np.array([0.0, 0.5, 1.0]), -2, 2)


def fd_jerk(t: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """|finite difference of qdd| per joint, max over the samples."""
    return np.max(np.abs(np.diff(qdd, axis=0) / np.diff(t)[:, None]), axis=0)


def assert_jerk_limited(traj, limits: JointLimits = LIMITS) -> None:
    jerk = np.asarray(limits.jerk)
    # the output samples (1 kHz) and a grid of our own, 40x finer, between them
    assert np.all(fd_jerk(traj.t, traj.qdd) <= jerk * (1 + RTOL))
    t = np.linspace(0.0, traj.duration, int(traj.duration * 40_000) + 2)
    q, qd, qdd, jk = traj.at(t)
    assert np.all(fd_jerk(t, qdd) <= jerk * (1 + RTOL))
    assert np.all(np.max(np.abs(jk), axis=0) <= jerk * (1 + RTOL))
    assert np.all(np.max(np.abs(qd), axis=0) <= np.asarray(limits.velocity) * (1 + RTOL))
    assert np.all(np.max(np.abs(qdd), axis=0) <= np.asarray(limits.acceleration) * (1 + RTOL))
    # q, qd, qdd one consistent motion (central differences, second order in the step)
    dt = t[1] - t[0]
    np.testing.assert_allclose((q[2:] - q[:-2]) / (2 * dt), qd[1:-1], atol=1e-6)
    np.testing.assert_allclose((qd[2:] - qd[:-2]) / (2 * dt), qdd[1:-1], atol=np.max(jerk) * dt)


@pytest.mark.parametrize("seed", [0, 1])
def test_toppra_with_a_jerk_limit_holds_it_and_costs_little(seed):
    w = walk(seed)
    free = time_path(DESIGN, w, JointLimits(VEL, ACC), sample_rate_hz=1000.0, stop_at=[3])
    traj = time_path(DESIGN, w, LIMITS, sample_rate_hz=1000.0, stop_at=[3])
    assert traj.method == "toppra" and traj.jerk is not None
    assert free.jerk is None
    # the unfiltered profile breaks the limit many times over: the check below can fail
    assert np.max(fd_jerk(free.t, free.qdd) / np.asarray(JERK)) > 10.0
    assert_jerk_limited(traj)
    # rests stay exact: the ends and the stop_at vertex, at rest
    assert np.array_equal(traj.q[0], w[0]) and np.array_equal(traj.q[-1], w[-1])
    k = int(np.argmin(np.linalg.norm(traj.q - w[3], axis=1)))
    assert np.linalg.norm(traj.q[k] - w[3]) < 1e-9 and np.all(traj.qd[k] == 0.0)
    _, qd_k, qdd_k, _ = traj.at(np.array([traj.t[k]]))
    assert np.all(np.abs(qd_k) < 1e-12) and np.all(np.abs(qdd_k) < 1e-12)
    # each of its two rest-to-rest sections costs at most the largest window
    window = max(WINDOW_FACTORS) * max(a / j for a, j in zip(ACC, JERK, strict=True))
    if traj.repairs == 0:
        assert traj.duration <= free.duration + 2 * window + 1e-9
    assert traj.duration >= free.duration  # toppra's is the time-optimal one
    assert traj.max_deviation_q <= 0.05 + 1e-9


def test_a_straight_rest_to_rest_move_takes_toppras_time_plus_one_ramp():
    """A trapezoid's acceleration jumps by a at most, so the window is a/j: the move takes
    the time-optimal trapezoid's time plus a/j, the jerk-limited optimum (a 7-phase S-curve
    when the cruise is long enough): an independent closed form."""
    w = np.array([[0.0, 0.5, 1.0], [1.5, 0.5, 1.0]])  # theta1 only: a 1.5 rad trapezoid
    lim = JointLimits((2.0, 2.0, 2.0), (8.0, 8.0, 8.0), (200.0, 200.0, 200.0))
    traj = time_path(DESIGN, w, lim, sample_rate_hz=1000.0)
    free = time_path(DESIGN, w, JointLimits(lim.velocity, lim.acceleration))
    trapezoid = 1.5 / 2.0 + 2.0 / 8.0
    assert free.duration == pytest.approx(trapezoid, rel=2e-3)  # toppra's fit: 1e-3 inside
    assert traj.duration == pytest.approx(free.duration + 8.0 / 200.0, rel=1e-9)
    assert isinstance(traj.curve, JerkFilteredCurve)
    assert_jerk_limited(traj, lim)


def test_via_chains_and_a_straight_path_hold_the_jerk():
    """A section timed as a chain through via states (second-order Ruckig moves without a
    jerk) is built jerk-limited instead; a straight tool path too."""
    w = np.array([[0.0, 0.5, 1.0], [0.4, 0.9, 1.2], [0.8, 0.6, 1.5], [1.0, 0.9, 1.3]])
    traj = time_path(DESIGN, w, LIMITS, sample_rate_hz=1000.0, via_at=[1, 2], max_deviation=0.05)
    assert_jerk_limited(traj)
    start = JointPosture([0.0, 2.0, 1.0])
    res = plan_cartesian(
        DESIGN, start, np.array([[0.05, 0.3, 0.0]]), timing="toppra", limits=LIMITS
    )
    assert res.trajectory is not None, res.timing_error  # (of the part it reaches)
    assert_jerk_limited(res.trajectory)


def test_a_sequence_passing_a_corner_exactly_holds_the_jerk():
    start = JointPosture([0.0, 2.0, 1.0])
    targets = [
        SequenceTarget(JointPosture([0.3, 2.0, 1.0]), stop=False, blend=0.0),
        SequenceTarget(JointPosture([0.6, 2.1, 1.0])),
    ]
    timing = TimingOptions(method="toppra", sample_rate_hz=1000.0)
    res = solve_sequence(DESIGN, start, targets, cycle=True, timing=timing, limits=LIMITS)
    assert res.solved, res.message
    assert_jerk_limited(res.trajectory)
    free = solve_sequence(
        DESIGN, start, targets, cycle=True, timing=timing, limits=JointLimits(VEL, ACC)
    )
    assert res.cycle_time >= free.cycle_time - 1e-9
