"""Sequences on the pick-and-place cycle (top corners passed as via states) and through a
working-mode change (the transits reported per leg, with their times).

Oracles independent of the sequence code: the trajectory evaluated on a fine grid of our own
(closest approach to each target, its order, strictly increasing output times, the velocity
limits), the all-stops cycle (toppra's straight rest-to-rest moves, time-optimal per leg),
and the working-mode signs of the forward kinematics on either side of each transit."""

from __future__ import annotations

import numpy as np
import pytest

from planner import Design, SequenceTarget, forward_batch, solve_sequence
from planner.planning import CartesianTarget, JointPosture
from planner.timing import JointLimits, TimingOptions

DESIGN = Design.default()
LIMITS = JointLimits.default()
#: The benchmark's Adept cycle on the default design (benchmarks/sequences.py): pick point,
#: up 20 mm, across 244 mm, and the start posture at the pick point in mode +++.
PICK = np.array([0.35, -0.15, -0.45])
UP, ACROSS = np.array([0.0, 0.0, 0.02]), np.array([0.0, 0.244, 0.0])
START = JointPosture([0.90975316, -0.10880946, 1.24575975])
TIMING = TimingOptions(method="toppra", sample_rate_hz=100)


def adept(stop: bool, blends=(0.0,) * 5) -> list[SequenceTarget]:
    points = [PICK + UP, PICK + UP + ACROSS, PICK + ACROSS, PICK + UP + ACROSS, PICK + UP]
    stops = [stop, stop, True, stop, stop]
    return [
        SequenceTarget(CartesianTarget(p, "+++"), stop=s, blend=b)
        for p, s, b in zip(points, stops, blends, strict=True)
    ]


@pytest.fixture(scope="module")
def cycles():
    stops = solve_sequence(DESIGN, START, adept(True), cycle=True, objective="fixed", timing=TIMING)
    assert stops.solved, stops.message
    lengths = [leg.plan.diagnostics.path_length for leg in stops.legs]
    blends = [0.0] * 5
    for i in (0, 1, 3, 4):  # 90 % of the rule's limit: half the shorter adjacent leg
        blends[i] = 0.9 * 0.5 * min(lengths[i], lengths[i + 1])
    passed = solve_sequence(
        DESIGN, START, adept(False, blends), cycle=True, objective="fixed", timing=TIMING
    )
    assert passed.solved, passed.message
    return stops, passed, blends


def test_passing_the_top_corners_saves_a_quarter_of_the_cycle(cycles):
    stops, passed, _ = cycles
    assert passed.cycle_time <= 0.75 * stops.cycle_time
    assert not passed.diagnostics.stopped_targets


def test_each_top_corner_is_passed_within_its_blend_in_order(cycles):
    _, passed, blends = cycles
    traj = passed.trajectory
    t = np.linspace(0.0, traj.duration, 40001)
    q, qd, _, _ = traj.at(t)
    assert np.all(np.abs(qd) <= LIMITS.velocity_array * (1 + 1e-6))
    assert np.all(np.diff(traj.t) > 0)
    w = np.asarray(passed.path.waypoints)
    t_prev = 0.0
    for leg in passed.legs[:5]:
        target = w[leg.waypoint_index]
        assert leg.start_time == pytest.approx(t_prev)
        after = t >= t_prev - 1e-9
        d = np.linalg.norm(q - target, axis=1)
        if leg.target_index == 2:  # the place: at rest, exactly
            assert leg.pass_distance <= 1e-9 and leg.pass_speed <= 1e-9
        else:  # passed within its blend, moving, at the leg's end_time
            assert leg.pass_distance <= blends[leg.target_index] * (1 + 1e-9)
            assert leg.pass_speed > 0.1
            k = int(np.argmin(np.abs(t - leg.end_time)))
            assert d[k] <= blends[leg.target_index] + 2e-3
        assert np.all(d[after & (t <= leg.end_time)] >= leg.pass_distance - 2e-3)
        t_prev = leg.end_time


def test_a_mode_change_reports_its_transits_per_leg_with_their_times():
    targets = [
        SequenceTarget(CartesianTarget(PICK + UP, "+-+")),
        SequenceTarget(CartesianTarget(PICK, "+++")),
    ]
    result = solve_sequence(DESIGN, START, targets, objective="fixed", timing=TIMING)
    assert result.solved, result.message
    curve = result.trajectory.curve
    seen = 0
    for leg in result.legs:
        transits = leg.plan.path.transits
        assert len(leg.transit_times) == len(transits)
        assert list(leg.transit_times) == sorted(leg.transit_times)
        for tr, t_cross in zip(transits, leg.transit_times, strict=True):
            seen += 1
            assert leg.start_time <= t_cross <= leg.end_time
            q = curve.evaluate(np.array([t_cross - 0.05, t_cross, t_cross + 0.05]))[0]
            assert np.linalg.norm(q[1] - np.asarray(tr.q)) <= TIMING.max_deviation
            signs = forward_batch(DESIGN, q[[0, 2]], "+").working_mode_signs
            flipped = {"axis": 0, "A": 1, "B": 2}[tr.flipped]
            assert signs[0, flipped] != signs[1, flipped]  # the named sign flips there
    assert seen >= 2  # there and back


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_passing_a_corner_exactly_is_never_slower_than_stopping_there(method):
    """Issue 36: passing a sharp corner exactly (blend 0) makes the path run straight through
    it at speed, which can cost more than braking to it; the sequence then rests there (the
    quicker of the two), lists it in stopped_targets and says why, so blend 0 is never
    slower than a stop. Since issue 39 an exact pass may also be a via state on the corner's
    own posture at a free velocity, which can beat the stop even on the sharp corner (toppra:
    1.3238 s against 1.3249 s); either way it is exact or a listed rest. On gentle corners
    passing stays quicker and is kept."""
    start = JointPosture([0.0, 2.0, 1.0])
    timing = TimingOptions(method=method)
    for sharp in (True, False):
        # out and nearly back (about 170 degrees), or on almost straight (about 18 degrees)
        corner = [0.6, 2.0, 1.0] if sharp else [0.3, 2.0, 1.0]
        after = [0.0, 2.1, 1.0] if sharp else [0.6, 2.1, 1.0]

        def targets(stop: bool, corner=corner, after=after) -> list[SequenceTarget]:
            return [
                SequenceTarget(JointPosture(corner), stop=stop, blend=0.0),
                SequenceTarget(JointPosture(after)),
            ]

        passing = solve_sequence(DESIGN, start, targets(False), cycle=True, timing=timing)
        stopping = solve_sequence(DESIGN, start, targets(True), cycle=True, timing=timing)
        assert passing.solved and stopping.solved
        assert passing.cycle_time <= stopping.cycle_time + 1e-9
        if sharp:  # at rest there (said so), or through it exactly as a via state
            if passing.diagnostics.stopped_targets == (0,):
                assert "quicker than passing exactly" in passing.message
                assert passing.cycle_time == pytest.approx(stopping.cycle_time, rel=1e-12)
            else:
                assert passing.legs[0].pass_distance <= 1e-6
                assert passing.legs[0].pass_speed > 0.0
        else:
            assert passing.diagnostics.stopped_targets == ()
            assert passing.cycle_time < stopping.cycle_time
