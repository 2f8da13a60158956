"""Execution in the core: the running trajectory's reading, a moving start's lead-in, a stop.

Checked against independent routes: a quintic polynomial reproduced exactly by the reading
and its derivatives against finite differences; every trajectory's first sample against the
asked state (1e-9); limits by finite differences of the samples (the change of q over a step
is bounded by the velocity limit, of qd by the acceleration limit, of qdd by the jerk limit);
the distance to the planned segment by a brute-force projection; a start driven into a
forbidden box by a checker built here.
"""

from __future__ import annotations

import numpy as np
import numpy.polynomial.polynomial as P
import pytest
from timing_factories import box_checker

from planner import Design
from planner.exceptions import InputError, LimitsError
from planner.motion import MotionProblem, run
from planner.planning import JointPosture
from planner.solver import GoalMotion
from planner.timing import JointLimits, TimingOptions, time_path
from planner.timing.braking import stop_trajectory
from planner.timing.lead_in import StartState, braking_failure, with_moving_start
from planner.timing.running import RunningTrajectory

DESIGN = Design.default()
LIMITS = JointLimits.default()
PATH = np.array([[0.0, 2.0, 1.0], [0.4, 2.2, 1.1], [0.6, 1.8, 1.3]])
RTOL = 1e-6


def fd_within(t, q, qd, qdd, limits: JointLimits, *, jerk: bool) -> None:
    """Limits by finite differences of the samples (mean value theorem)."""
    dt = np.diff(t)[:, None]
    slack = 1 + RTOL
    assert np.all(np.abs(np.diff(q, axis=0)) <= limits.velocity_array * dt * slack + 1e-12)
    assert np.all(np.abs(np.diff(qd, axis=0)) <= limits.acceleration_array * dt * slack + 1e-12)
    assert np.all(np.abs(qd) <= limits.velocity_array * slack)
    assert np.all(np.abs(qdd) <= limits.acceleration_array * slack)
    if jerk:
        jerk_max = limits.with_ruckig_jerk().jerk_array  # ruckig's jerk: asked or its default
        assert np.all(np.abs(np.diff(qdd, axis=0)) <= jerk_max * dt * slack + 1e-9)


# ---------------------------------------------------------------------------- the reading
def test_the_reading_reproduces_a_quintic_and_its_derivatives():
    rng = np.random.default_rng(3)
    c = rng.normal(size=(6, 3))

    def poly(t, d):  # the d-th derivative of the quintic, per joint
        return np.stack([P.polyval(t, P.polyder(c[:, j], d)) for j in range(3)], axis=1)

    t = np.sort(rng.uniform(0, 2, 9))
    running = RunningTrajectory.of(t, poly(t, 0), poly(t, 1), poly(t, 2))
    x = np.linspace(t[0], t[-1], 301)
    q, qd, qdd, jerk = running.evaluate(x)
    for got, d in ((q, 0), (qd, 1), (qdd, 2), (jerk, 3)):
        np.testing.assert_allclose(got, poly(x, d), atol=1e-8 * (1 + np.abs(poly(x, d)).max()))
    at = float(t[4])  # a sample time: that sample, bit for bit
    assert all(
        np.array_equal(a, b[4])
        for a, b in zip(running.state_at(at), (running.q, running.qd, running.qdd), strict=True)
    )
    one = running.state_at(float(x[77]))
    assert all(np.allclose(a, b[77], atol=1e-12) for a, b in zip(one, (q, qd, qdd), strict=True))


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"t": [0.0, 0.0, 1.0]}, "trajectory.t"),
        ({"q": [[0.0, 0.0, 0.0]] * 2}, "trajectory.q"),
        ({"qd": [[0.0, np.nan, 0.0]] * 3}, "trajectory.qd"),
        ({"t": [0.0]}, "trajectory.t"),
    ],
)
def test_a_malformed_running_trajectory_names_its_field(change, field):
    arrays = {
        "t": [0.0, 0.5, 1.0],
        "q": [[0.0] * 3] * 3,
        "qd": [[0.0] * 3] * 3,
        "qdd": [[0.0] * 3] * 3,
    }
    arrays.update(change)
    with pytest.raises(InputError) as err:
        RunningTrajectory.of(**arrays)
    assert err.value.field == field


# ---------------------------------------------------------------------------- moving starts
@pytest.mark.parametrize("method", ["toppra", "ruckig"])
@pytest.mark.parametrize(
    "qd, qdd",
    [
        ((1.0, -0.5, 0.3), (2.0, 1.0, -1.0)),  # off the path
        (tuple((PATH[1] - PATH[0]) * 3.0), (0.0, 0.0, 0.0)),  # along the first segment
    ],
)
def test_a_moving_start_begins_in_its_state_and_keeps_the_limits(method, qd, qdd):
    rest = time_path(DESIGN, PATH, LIMITS, method=method, sample_rate_hz=500)
    state = StartState.of(PATH[0], qd, qdd)
    traj = with_moving_start(
        rest,
        state,
        design=DESIGN,
        assembly_mode="+",
        limits=LIMITS,
        check_states=None,
        resolution=0.01,
        sample_rate_hz=500,
        first_segment=PATH[:2],
        near=0.05,
    )
    np.testing.assert_allclose(traj.q[0], state.q, atol=1e-9, rtol=0)
    np.testing.assert_allclose(traj.qd[0], state.qd, atol=1e-9, rtol=0)
    np.testing.assert_allclose(traj.qdd[0], state.qdd, atol=1e-9, rtol=0)
    np.testing.assert_array_equal(traj.q[-1], PATH[-1])
    assert not np.any(traj.qd[-1]) and not np.any(traj.qdd[-1])
    fd_within(traj.t, traj.q, traj.qd, traj.qdd, LIMITS, jerk=method == "ruckig")
    lead = traj.curve.lead_in
    assert lead.kind == "direct" and 0 < lead.joins_at <= rest.duration
    # after the lead-in the trajectory is the rest-to-rest one, shifted in time
    later = traj.t[traj.t > lead.duration + 1e-9]
    q_late = traj.curve.evaluate(later)[0]
    q_rest = rest.curve.evaluate(later - lead.duration + lead.joins_at)[0]
    np.testing.assert_allclose(q_late, q_rest, atol=1e-12)


def _off_segment(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    d = b - a
    u = np.clip((q - a) @ d / (d @ d), 0.0, 1.0)
    return float(np.max(np.linalg.norm(q - (a + u[:, None] * d), axis=1)))


def test_a_start_along_the_path_stays_on_the_planned_segment():
    straight = PATH[:2]
    rest = time_path(DESIGN, straight, LIMITS, method="ruckig", sample_rate_hz=500)
    state = StartState.of(straight[0], (straight[1] - straight[0]) * 2.0)
    traj = with_moving_start(
        rest,
        state,
        design=DESIGN,
        assembly_mode="+",
        limits=LIMITS,
        check_states=None,
        resolution=0.01,
        sample_rate_hz=500,
        first_segment=straight,
    )
    assert _off_segment(traj.q, *straight) < 1e-9
    assert traj.duration < rest.duration  # it started moving: sooner than from rest


def test_a_start_beyond_the_limits_is_refused_at_its_field():
    with pytest.raises(LimitsError) as err:
        MotionProblem.of(DESIGN, JointPosture(PATH[0]), start_qd=(2.5, 0.0, 0.0))
    assert err.value.field == "start.qd"
    with pytest.raises(LimitsError) as err:  # jerk-limited: 1.9 + 8^2 / 400 > 2
        MotionProblem.of(
            DESIGN,
            JointPosture(PATH[0]),
            timing=TimingOptions(method="ruckig"),
            start_qd=(1.9, 0, 0),
            start_qdd=(8.0, 0, 0),
        )
    assert err.value.field == "start.qdd"
    with pytest.raises(InputError, match="timed answer"):
        MotionProblem.of(
            DESIGN, JointPosture(PATH[0]), timing=TimingOptions(method="none"), start_qd=(1, 0, 0)
        )


def test_a_start_that_cannot_brake_inside_the_valid_set_is_invalid_start():
    state = StartState.of(PATH[0], (2.0, 0.0, 0.0))  # braking takes 2^2 / (2 * 8) = 0.25 rad
    wall = box_checker(np.array([0.1, -9.0, -9.0]), np.array([9.0, 9.0, 9.0]))
    why = braking_failure(DESIGN, state, "+", LIMITS, wall, 0.01, jerk_limited=False)
    assert why is not None and "validity" in why
    far = box_checker(np.array([0.3, -9.0, -9.0]), np.array([9.0, 9.0, 9.0]))
    assert braking_failure(DESIGN, state, "+", LIMITS, far, 0.01, jerk_limited=False) is None


def test_the_pipeline_answers_invalid_start_for_a_start_rushing_at_a_joint_limit():
    design = Design(L0=DESIGN.L0, L1=DESIGN.L1, L2=DESIGN.L2, joint_max=(0.1, 3.1, 3.1))
    problem = MotionProblem.of(design, JointPosture(PATH[0]), start_qd=(2.0, 0.0, 0.0))
    solution = run(problem, GoalMotion(JointPosture([0.05, 2.1, 1.05])))
    assert solution.plan.status.value == "invalid_start"
    assert "joint_limits" in solution.plan.message


# ---------------------------------------------------------------------------- stops
def _running(method: str, scaling: float = 1.0) -> RunningTrajectory:
    limits = JointLimits(
        velocity=tuple(LIMITS.velocity_array * scaling),
        acceleration=tuple(LIMITS.acceleration_array * scaling),
        # ruckig runs under its jerk (asked, or the default); toppra's has none asked
        jerk=tuple(LIMITS.with_ruckig_jerk().jerk_array * scaling) if method == "ruckig" else None,
    )
    traj = time_path(DESIGN, PATH, limits, method=method, sample_rate_hz=1000)
    return RunningTrajectory.of(traj.t, traj.q, traj.qd, traj.qdd)


@pytest.mark.parametrize(("method", "scaling"), [("ruckig", 0.5), ("ruckig", 1.0), ("toppra", 1.0)])
def test_a_stop_starts_in_the_running_state_and_comes_to_rest_within_the_limits(method, scaling):
    running = _running(method, scaling)
    along = 0
    for at in np.linspace(0.05, running.end - 0.05, 7):
        stop = stop_trajectory(
            running,
            float(at),
            design=DESIGN,
            assembly_mode="+",
            limits=LIMITS,
            path_rules=None,
            brake_rules=None,
            jerk_limited=method == "ruckig",
            sample_rate_hz=1000,
        )
        assert stop.status == "solved", stop.message
        q0, qd0, qdd0 = running.state_at(float(at))
        assert stop.t[0] == at
        for got, want in ((stop.q[0], q0), (stop.qd[0], qd0), (stop.qdd[0], qdd0)):
            np.testing.assert_allclose(got, want, atol=1e-9, rtol=0)
        assert not np.any(stop.qd[-1]) and not np.any(stop.qdd[-1])
        fd_within(stop.t, stop.q, stop.qd, stop.qdd, LIMITS, jerk=method == "ruckig")
        if stop.along_path:
            along += 1  # its postures are the running path's own
            sigma = np.linspace(at, at + 2 * stop.stop_time, 1001)
            path = running.evaluate(np.minimum(sigma, running.end))[0]
            gap = np.min(np.linalg.norm(stop.q[::10, None, :] - path[None], axis=2), axis=1)
            assert gap.max() < 2e-3
    if scaling < 1.0:  # room below the limits: the stop keeps to the path
        assert along >= 4


def test_a_stop_that_no_braking_keeps_valid_is_invalid_start():
    running = _running("ruckig")
    at = 0.3
    q0 = running.state_at(at)[0]
    wall = box_checker(q0 - 1e-3, q0 + 1e-3)  # valid only within a hair of the posture
    stop = stop_trajectory(
        running,
        at,
        design=DESIGN,
        assembly_mode="+",
        limits=LIMITS,
        path_rules=wall,
        brake_rules=wall,
    )
    assert stop.status == "invalid_start" and "validity" in stop.message
