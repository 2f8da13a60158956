"""Speed scaling against closed-form trapezoid durations; the points form and CSV files."""

from __future__ import annotations

import io

import numpy as np
import pytest

from planner import Design, InputError
from planner.exceptions import LimitsError
from planner.timing import JointLimits, time_path
from planner.timing.export import CSV_UNITS, read_csv, write_csv
from planner.wire.timing import arrays_from_points, points_from_arrays, trajectory_model

DESIGN = Design.default()
# theta1 alone turns by 3 rad: the loop (theta2, theta3) does not move, so it assembles all along
PATH = np.array([[-1.5, 2.0, 1.0], [1.5, 2.0, 1.0]])


def trapezoid(distance: float, v: float, a: float) -> float:
    """Rest-to-rest duration of the time-optimal move under |qd| <= v, |qdd| <= a."""
    if distance >= v * v / a:
        return distance / v + v / a
    return 2 * np.sqrt(distance / a)


@pytest.mark.parametrize(("vs", "acs"), [(1.0, 1.0), (0.5, 1.0), (0.5, 0.25), (0.3, 0.5)])
def test_scaling_factors_match_trapezoid_durations(vs, acs):
    base = JointLimits.default()
    lim = base.scaled(vs, acs)
    assert lim.velocity == tuple(v * vs for v in base.velocity)
    assert lim.acceleration == tuple(a * acs for a in base.acceleration)
    traj = time_path(DESIGN, PATH, lim, method="toppra")
    expected = trapezoid(3.0, 2.0 * vs, 8.0 * acs)
    assert traj.duration == pytest.approx(expected, rel=2e-3)


def test_half_velocity_doubles_a_move_at_the_velocity_limit():
    base = JointLimits.default()
    t_full = time_path(DESIGN, PATH, base).duration
    # velocity x0.5 with acceleration x0.25 is time scaling by 2: exactly twice as long
    t_half = time_path(DESIGN, PATH, base.scaled(0.5, 0.25)).duration
    assert t_half == pytest.approx(2 * t_full, rel=2e-3)
    # velocity x0.5 alone: the cruise (most of the move) doubles, the ramps halve
    t_v = time_path(DESIGN, PATH, base.scaled(0.5, 1.0)).duration
    assert t_v == pytest.approx(3.0 / 1.0 + 1.0 / 8.0, rel=2e-3)
    assert 1.7 < t_v / t_full < 2.0


@pytest.mark.parametrize(
    ("args", "field"),
    [((0.0,), "velocity_scaling"), ((1.5,), "velocity_scaling"), ((float("nan"),), "velocity_scaling"),
     ((0.5, 0.0), "acceleration_scaling"), ((0.5, 2.0), "acceleration_scaling"),
     (("x",), "velocity_scaling"), ((True,), "velocity_scaling")],
)  # fmt: skip
def test_scaling_errors_name_the_field(args, field):
    with pytest.raises(LimitsError, match=rf"limits\.{field}"):
        JointLimits.default().scaled(*args)


def _trajectory():
    w = np.array([[0.0, 2.0, 1.0], [0.4, 2.2, 1.1], [0.6, 1.9, 1.3]])
    return time_path(DESIGN, w, JointLimits.default(), method="ruckig")


def test_points_and_arrays_carry_the_same_samples():
    traj = _trajectory()
    pts = trajectory_model(traj, "points").model_dump()
    assert pts["joint_names"] == ["theta1", "theta2", "theta3"]
    assert pts["duration"] == traj.duration
    assert len(pts["points"]) == len(traj.t)
    for i in (0, len(traj.t) // 2, len(traj.t) - 1):
        p = pts["points"][i]
        assert p["time_from_start"] == traj.t[i]
        assert p["positions"] == traj.q[i].tolist()
        assert p["velocities"] == traj.qd[i].tolist()
        assert p["accelerations"] == traj.qdd[i].tolist()
    back = arrays_from_points(pts)
    for name in ("t", "q", "qd", "qdd"):
        assert np.array_equal(getattr(back, name), getattr(traj, name))
    assert back.duration == traj.duration


def test_points_with_reordered_joint_names():
    t = np.array([0.0, 0.5])
    q = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    pts = points_from_arrays(t, q, q * 0, q * 0)
    pts["joint_names"] = ["theta3", "theta1", "theta2"]
    for p in pts["points"]:
        p["positions"] = [p["positions"][2], p["positions"][0], p["positions"][1]]
    assert np.array_equal(arrays_from_points(pts).q, q)
    with pytest.raises(InputError, match="joint_names"):
        arrays_from_points({"joint_names": ["a", "b", "c"], "points": pts["points"]})
    with pytest.raises(InputError, match="t must increase"):
        points_from_arrays(np.array([0.0, 0.0]), q, q, q)


def test_csv_round_trip_is_exact(tmp_path):
    traj = _trajectory()
    path = tmp_path / "traj.csv"
    write_csv(path, traj.t, traj.q, traj.qd, traj.qdd, traj.jerk)
    lines = path.read_text().splitlines()
    assert lines[0] == CSV_UNITS and "rad/s^2" in lines[0]
    assert lines[1].startswith("t,theta1,theta2,theta3,")
    back = read_csv(path)
    for name in ("t", "q", "qd", "qdd", "jerk"):
        assert np.array_equal(getattr(back, name), getattr(traj, name))
    buf = io.StringIO()
    write_csv(buf, traj.t, traj.q, traj.qd, traj.qdd)
    buf.seek(0)
    assert read_csv(buf).jerk is None
    with pytest.raises(InputError, match="lacks the columns"):
        read_csv(io.StringIO("t,theta1\n0,1\n"))
