"""Picking from a moving belt (:class:`planner.sequence.problem.MovingTarget`).

Oracles independent of the belt code: the tool point of the trajectory's own samples by the
forward kinematics (on the part within 0.1 mm over the whole dwell; its velocity by
differences of those samples equal to the belt's), the velocity and acceleration limits on
the samples, a validity checker built here; and for the interception, brute force over a
fine grid (1 ms) of meeting times whose costs come from this test's own route: the
part's postures by the inverse kinematics, their joint rates by the Jacobian of the forward
kinematics (qd = J^-1 v, not differences in time), and Ruckig's time-optimal moves solved
here directly."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ruckig import InputParameter, Result, Ruckig
from ruckig import Trajectory as RuckigTrajectory

from planner import Design, SequenceTarget, solve_sequence
from planner.exceptions import InputError
from planner.kinematics import WORKING_MODES, forward_batch, inverse_batch
from planner.planning import CartesianTarget, JointPosture, PlanStatus
from planner.sequence.problem import MAX_BELT_SPEED, MovingTarget
from planner.timing import JointLimits, TimingOptions
from planner.validity import Margins, ValidityChecker

DESIGN = Design.default()
LIMITS = JointLimits.default()
BIN = np.array([-0.2, 0.25, -0.45])
MODE = "+-+"
START = JointPosture(inverse_batch(DESIGN, BIN).q[0, WORKING_MODES.index(MODE)], "+")


def pick(part: MovingTarget, dwell: float, **kw):
    targets = [SequenceTarget(part, dwell=dwell), SequenceTarget(CartesianTarget(BIN))]
    return solve_sequence(DESIGN, START, targets, **kw)


def test_the_tool_tracks_the_part_within_0_1_mm_over_the_dwell():
    part = MovingTarget([-0.7, 0.0, -0.45], "any", [0.5, 0.0, 0.0], 0.0)
    dwell = 0.25
    r = pick(part, dwell, timing=TimingOptions(sample_rate_hz=1000))
    assert r.solved, r.message
    tr, leg = r.trajectory, r.legs[0]
    assert leg.meet_time == pytest.approx(leg.end_time)
    assert np.allclose(leg.meet_point, part.at(leg.meet_time)[0], atol=1e-12)
    span = (tr.t >= leg.meet_time - 1e-12) & (tr.t <= leg.meet_time + dwell + 1e-12)
    assert span.sum() >= 240
    p = forward_batch(DESIGN, tr.q[span], "+").p  # the samples' own P, not tr.p
    err = np.linalg.norm(p - part.at(tr.t[span]), axis=1)
    assert err.max() < 1e-4
    # the tool moves with the part: P's velocity by differences of the samples
    t = tr.t[span]
    v = np.diff(p, axis=0) / np.diff(t)[:, None]
    assert np.allclose(v, part.velocity, atol=1e-6)
    # the approach arrives with the part's velocity: the samples just before the meeting
    before = (tr.t < leg.meet_time) & (tr.t > leg.meet_time - 0.004)
    p_before = forward_batch(DESIGN, tr.q[before], "+").p
    v_in = (p[0] - p_before[-1]) / (t[0] - tr.t[before][-1])
    assert np.linalg.norm(v_in - part.velocity) < 0.01
    # every sample: times increasing, within the limits, valid in its mode, rest at the end
    assert np.all(np.diff(tr.t) > 0)
    assert np.all(np.abs(tr.qd) <= np.array(LIMITS.velocity) * (1 + 1e-6))
    assert np.all(np.abs(tr.qdd) <= np.array(LIMITS.acceleration) * (1 + 1e-6))
    checker = ValidityChecker(DESIGN, Margins(), (), "+", leg.working_mode)
    assert checker.is_valid(tr.q).all()
    assert np.allclose(tr.q[-1], r.legs[1].plan.path.waypoints[-1])
    assert np.allclose(forward_batch(DESIGN, tr.q[-1], "+").p[0], BIN, atol=1e-9)
    assert np.all(tr.qd[-1] == 0)
    assert "met the part" in r.message


def test_the_meeting_and_the_end_of_the_dwell_are_samples():
    """At 100 Hz (the samples 5 mm of belt apart) the trajectory still has a sample at
    meet_time, where P (the forward kinematics of that sample's q) is meet_point, and one at
    the end of the dwell, on the part."""
    part = MovingTarget([-0.75, 0.0, -0.45], "any", [0.5, 0.0, 0.0], 0.0)
    dwell = 0.1
    r = pick(part, dwell, timing=TimingOptions(sample_rate_hz=100))
    assert r.solved, r.message
    tr, leg = r.trajectory, r.legs[0]
    assert np.all(np.diff(tr.t) > 1e-9)
    for when in (leg.meet_time, leg.meet_time + dwell):
        k = int(np.argmin(np.abs(tr.t - when)))
        assert abs(tr.t[k] - when) <= 1e-9
        p = forward_batch(DESIGN, tr.q[k], "+").p[0]
        assert np.linalg.norm(p - part.at(when)[0]) < 1e-6
    k = int(np.argmin(np.abs(tr.t - leg.meet_time)))
    assert np.linalg.norm(forward_batch(DESIGN, tr.q[k], "+").p[0] - leg.meet_point) < 1e-6


# ---------------------------------------------------------------------------- brute force
def _rates(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """qd = J^-1 v at postures q (M, 3), J = dP/dq by central differences of the forward
    kinematics."""
    h, m = 1e-6, q.shape[0]
    e = np.eye(3) * h
    pp = forward_batch(
        DESIGN, np.concatenate([q + e[j] for j in range(3)] + [q - e[j] for j in range(3)]), "+"
    ).p
    jac = np.stack(
        [(pp[j * m : (j + 1) * m] - pp[(3 + j) * m : (4 + j) * m]) / (2 * h) for j in range(3)],
        axis=2,
    )
    return np.linalg.solve(jac, np.broadcast_to(v, (m, 3))[..., None])[..., 0]


def _move_time(otg, inp, a, b) -> float:
    inp.current_position, inp.current_velocity = list(a[0]), list(a[1])
    inp.target_position, inp.target_velocity = list(b[0]), list(b[1])
    inp.current_acceleration = inp.target_acceleration = [0.0] * 3
    traj = RuckigTrajectory(3)
    result = otg.calculate(inp, traj)
    return float(traj.duration) if result in (Result.Working, Result.Finished) else math.inf


def brute_force(part: MovingTarget, dwell: float, mode: str, step: float = 1e-3) -> float:
    """The least time the tool comes to rest at the bin, over meeting times every ``step``:
    approach from rest at the start (t >= its least time), track, depart to rest at the bin
    in ``mode``, each move time-optimal (second order)."""
    slot = WORKING_MODES.index(mode)
    checker = ValidityChecker(DESIGN, Margins(), (), "+", mode)
    otg, inp = Ruckig(3), InputParameter(3)
    inp.max_velocity = list(LIMITS.velocity)
    inp.max_acceleration = list(LIMITS.acceleration)
    inp.max_jerk = [math.inf] * 3
    q_bin = inverse_batch(DESIGN, BIN).q[0, slot]
    ts = np.arange(0.0, 6.0, 0.005)
    ik = inverse_batch(DESIGN, part.at(ts))
    ok = ik.ok[:, slot].copy()
    q = np.full((ts.shape[0], 3), np.nan)
    q[ok] = np.unwrap(ik.q[ok, slot], axis=0)
    q = q + 2 * np.pi * np.round((START.q - q[np.argmax(ok)]) / (2 * np.pi))
    ok[ok] &= checker.is_valid(q[ok])
    qd = np.full_like(q, np.nan)
    qd[ok] = _rates(q[ok], part.velocity)
    qdd = np.gradient(np.nan_to_num(qd), ts, axis=0)
    ok &= np.all(np.abs(qd) <= LIMITS.velocity, axis=1)
    ok &= np.all(np.abs(qdd) <= LIMITS.acceleration, axis=1)
    grid = np.arange(0.0, 6.0 - dwell, step)
    states = []
    for s in (grid, grid + dwell):
        ref = np.stack([np.interp(s, ts, q[:, j]) for j in range(3)], axis=1)
        raw = inverse_batch(DESIGN, part.at(s)).q[:, slot]
        qs = raw + 2 * np.pi * np.round((ref - raw) / (2 * np.pi))
        good = np.all(np.isfinite(qs), axis=1)
        qds = np.full_like(qs, np.nan)
        qds[good] = _rates(qs[good], part.velocity)
        states.append((qs, qds))
    best, rest = math.inf, np.zeros(3)
    lo = np.searchsorted(ts, grid - 0.005)
    hi = np.searchsorted(ts, grid + dwell + 0.005, side="right")
    bad = np.concatenate([[0], np.cumsum(~ok)])
    for k, t in enumerate(grid):
        if bad[hi[k]] - bad[lo[k]] > 0:
            continue
        meet = (states[0][0][k], states[0][1][k])
        if _move_time(otg, inp, (START.q, rest), meet) > t:
            continue
        leave = (states[1][0][k], states[1][1][k])
        best = min(best, t + dwell + _move_time(otg, inp, leave, (q_bin, rest)))
    return best


def _case(seed: int) -> tuple[MovingTarget, float]:
    rng = np.random.default_rng(seed)
    speed = rng.uniform(0.1, 1.0)
    y, z = rng.uniform(-0.1, 0.1), rng.uniform(-0.5, -0.4)
    part = MovingTarget([-0.75, y, z], MODE, [speed, 0.0, 0.0], rng.uniform(0.0, 0.5))
    return part, float(rng.uniform(0.1, 0.3))


@pytest.mark.parametrize("seed", range(4))
def test_the_meeting_time_is_within_2_percent_of_brute_force(seed):
    """4 seeded cases here (the cost of the suite); benchmarks/conveyor.py runs 50."""
    part, dwell = _case(seed)
    r = pick(part, dwell)
    bf = brute_force(part, dwell, MODE)
    if not math.isfinite(bf):
        assert r.status is PlanStatus.UNREACHABLE
        return
    assert r.solved, r.message
    at_bin = r.legs[1].end_time
    assert at_bin <= bf * 1.02
    assert at_bin >= bf - 0.002  # not better than the grid allows (its step, and a little)
    assert r.trajectory.duration == pytest.approx(at_bin)


def test_the_mode_choice_is_never_slower_than_a_fixed_mode():
    part = MovingTarget([-0.7, 0.0, -0.45], "any", [0.5, 0.0, 0.0], 0.0)
    chosen = pick(part, 0.2)
    assert chosen.solved, chosen.message
    for mode in ("+++", MODE):
        fixed = pick(MovingTarget(part.p, mode, part.velocity, part.t0), 0.2)
        if fixed.solved:
            assert chosen.cycle_time <= fixed.cycle_time + 1e-9


# ---------------------------------------------------------------------------- bad input
def test_a_part_never_reachable_is_unreachable_naming_the_target():
    far = MovingTarget([3.0, 3.0, 3.0], "any", [0.0, 0.5, 0.0], 0.0)
    r = pick(far, 0.1)
    assert r.status is PlanStatus.UNREACHABLE
    assert r.message.startswith("target 0:") and "never enters" in r.message


def test_a_part_gone_before_the_start_names_its_window():
    gone = MovingTarget([-0.7, 0.0, -0.45], "any", [0.5, 0.0, 0.0], -10.0)
    r = pick(gone, 0.1)
    assert r.status is PlanStatus.UNREACHABLE
    assert r.message.startswith("target 0:") and "before the sequence starts" in r.message
    assert " from " in r.message and " to " in r.message


def test_a_part_leaving_before_any_meeting_names_its_window():
    # reachable until about 0.2 s: the robot at the bin cannot get there in time
    late = MovingTarget([-0.7, 0.0, -0.45], "+-+", [0.5, 0.0, 0.0], -2.3)
    r = pick(late, 0.1)
    assert r.status is PlanStatus.UNREACHABLE
    assert r.message.startswith("target 0:") and "no meeting is possible" in r.message


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda: MovingTarget([0, 0, -0.4], "any", [MAX_BELT_SPEED + 0.1, 0, 0]), "velocity"),
        (lambda: MovingTarget([0, 0, -0.4], "any", [0, 0, 0], math.nan), "t0"),
        (lambda: SequenceTarget(MovingTarget([0, 0, -0.4]), dwell=-0.1), "dwell"),
        (lambda: SequenceTarget(CartesianTarget(BIN), dwell=0.1), "dwell"),
        (lambda: SequenceTarget(MovingTarget([0, 0, -0.4]), blend=0.1), "blend"),
    ],
)
def test_bad_moving_targets_are_refused_by_field(make, field):
    with pytest.raises(InputError) as exc:
        make()
    assert exc.value.field_path[-1] == field


def test_two_moving_targets_in_a_row_and_no_timing_are_refused():
    part = MovingTarget([-0.7, 0.0, -0.45], "any", [0.5, 0.0, 0.0], 0.0)
    two = [SequenceTarget(part, dwell=0.1), SequenceTarget(part, dwell=0.1)]
    with pytest.raises(InputError) as exc:
        solve_sequence(DESIGN, START, two)
    assert exc.value.field_path == ("targets", 1, "goal")
    with pytest.raises(InputError) as exc:
        pick(part, 0.1, timing=TimingOptions(method="none"))
    assert exc.value.field_path == ("timing", "method")


def test_a_static_target_after_a_pick_keeps_its_index_in_the_message():
    part = MovingTarget([-0.7, 0.0, -0.45], "any", [0.5, 0.0, 0.0], 0.0)
    targets = [
        SequenceTarget(part, dwell=0.1),
        SequenceTarget(CartesianTarget(BIN)),
        SequenceTarget(CartesianTarget([3.0, 3.0, 3.0])),
    ]
    r = solve_sequence(DESIGN, START, targets)
    assert r.status is PlanStatus.UNREACHABLE
    assert r.message.startswith("target 2:")
    assert [leg.target_index for leg in r.legs] == [0, 1, 2]
    assert r.legs[0].meet_time > 0 and r.legs[1].end_time > r.legs[0].meet_time
