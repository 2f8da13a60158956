"""A trajectory and a simulation as a ROS 2 bag (MCAP), read back with the same library's
reader (mcap_ros2, which decodes the CDR by the schema written in the file): every value
back as written, the schemas ROS 2's own message names."""

from __future__ import annotations

import io

import numpy as np
from mcap.reader import make_reader
from simulation_factories import move_reference

from planner import Design
from planner.simulation import simulate
from planner.simulation.bag import (
    BAG_JOINT_NAMES,
    TOPIC_JOINT_STATES,
    TOPIC_P_ERROR,
    TOPIC_PLANNED_STATES,
    TOPIC_TRAJECTORY,
    read_bag,
    write_bag,
)
from planner.timing.export import TrajectoryArrays


def test_a_simulation_and_its_trajectory_read_back_from_the_bag(tmp_path) -> None:
    ref = move_reference(duration=0.1)
    sim = simulate(Design.default(), ref, hold_s=0.0)
    start = 1_700_000_000 * 10**9  # a wall-clock epoch, as a recorded bag has
    path = tmp_path / "run.mcap"
    write_bag(path, trajectory=ref, simulation=sim, start_ns=start)
    back = read_bag(path, start_ns=start)
    assert back.joint_names == list(BAG_JOINT_NAMES)
    traj = back.trajectory
    assert traj is not None and traj["tau"] is None
    for key in ("q", "qd", "qdd"):
        np.testing.assert_array_equal(traj[key], getattr(ref, key))
    np.testing.assert_allclose(traj["t"], ref.t, atol=1e-9)  # ns stamps
    planned, realised = back.planned, back.realised
    assert planned is not None and realised is not None and back.p_error_mm is not None
    np.testing.assert_array_equal(planned["q"], ref.q)
    np.testing.assert_array_equal(realised["q"], sim.q)
    np.testing.assert_array_equal(realised["qd"], sim.qd)
    np.testing.assert_array_equal(realised["tau"], sim.tau)
    np.testing.assert_allclose(realised["t"], sim.t, atol=1e-9)
    np.testing.assert_array_equal(back.p_error_mm["data"], sim.p_error_mm)
    # the file's schemas and channels: ROS 2's names, CDR encoding, the ros2 profile
    with path.open("rb") as f:
        summary = make_reader(f).get_summary()
        header = make_reader(open(path, "rb")).get_header()
    assert header.profile == "ros2"
    schemas = {s.name for s in summary.schemas.values()}
    assert schemas == {
        "trajectory_msgs/msg/JointTrajectory",
        "sensor_msgs/msg/JointState",
        "std_msgs/msg/Float64",
    }
    channels = {c.topic: c.message_encoding for c in summary.channels.values()}
    assert channels == dict.fromkeys(
        (TOPIC_TRAJECTORY, TOPIC_PLANNED_STATES, TOPIC_JOINT_STATES, TOPIC_P_ERROR), "cdr"
    )
    counts = summary.statistics.channel_message_counts
    by_topic = {summary.channels[c].topic: n for c, n in counts.items()}
    assert by_topic[TOPIC_TRAJECTORY] == 1 and by_topic[TOPIC_JOINT_STATES] == sim.t.size


def test_a_trajectory_with_torques_alone_to_a_stream() -> None:
    """A trajectory with torques (the efforts of its points), written to a byte stream."""
    rng = np.random.default_rng(2)
    t = np.array([0.5, 0.75, 1.0])
    arrays = TrajectoryArrays(
        t,
        rng.normal(size=(3, 3)),
        rng.normal(size=(3, 3)),
        rng.normal(size=(3, 3)),
        tau=rng.normal(size=(3, 3)),
    )
    buf = io.BytesIO()
    write_bag(buf, trajectory=arrays)
    back = read_bag(io.BytesIO(buf.getvalue()))
    assert back.realised is None and back.p_error_mm is None and back.trajectory is not None
    np.testing.assert_array_equal(back.trajectory["tau"], arrays.tau)
    np.testing.assert_allclose(back.trajectory["t"], t, atol=1e-9)
    assert back.planned is not None
    np.testing.assert_array_equal(back.planned["tau"], arrays.tau)
