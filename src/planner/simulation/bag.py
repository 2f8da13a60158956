"""Trajectories and simulations as a ROS 2 bag: one MCAP file (profile ``ros2``, CDR
messages), readable by ``ros2 bag`` (storage ``mcap``) and Foxglove, written without ROS by
``mcap-ros2-support`` (``docs/simulation.md``).

Topics (joint names ``theta1``, ``theta2``, ``theta3``; times in the trajectory's clock, in ns
from ``start_ns``):

- ``/planned/joint_trajectory`` (``trajectory_msgs/msg/JointTrajectory``): one message, the
  whole trajectory as a ``FollowJointTrajectory`` goal carries it (``points[i]``:
  ``positions``, ``velocities``, ``accelerations``, ``effort`` when the trajectory has
  torques, ``time_from_start`` from its first sample), stamped at its first sample.
- ``/planned/joint_states`` (``sensor_msgs/msg/JointState``): the same samples one by one
  (``position``, ``velocity``, ``effort``), for plotting beside the realised ones.
- With a simulation: ``/joint_states`` (``sensor_msgs/msg/JointState``): the realised samples
  (``position`` q, ``velocity`` qd, ``effort`` the applied tau), what the robot's
  ``joint_state_broadcaster`` would publish; ``/tracking/p_error_mm``
  (``std_msgs/msg/Float64``): the distance of P to the reference's, mm.

The message definitions are ROS 2's own (``.msg`` text with their dependencies, as rosbag2
writes them), spelled out below.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import IO, Any, Protocol

import numpy as np

__all__ = [
    "BAG_JOINT_NAMES",
    "TOPIC_JOINT_STATES",
    "TOPIC_PLANNED_STATES",
    "TOPIC_P_ERROR",
    "TOPIC_TRAJECTORY",
    "BagContents",
    "RecordedRun",
    "RunArrays",
    "SampledTrajectory",
    "read_bag",
    "write_bag",
]

#: The joints' names in every message, in the order of q.
BAG_JOINT_NAMES = ("theta1", "theta2", "theta3")
TOPIC_TRAJECTORY = "/planned/joint_trajectory"
TOPIC_PLANNED_STATES = "/planned/joint_states"
TOPIC_JOINT_STATES = "/joint_states"
TOPIC_P_ERROR = "/tracking/p_error_mm"

_SEP = "=" * 80 + "\n"
_TIME = "int32 sec\nuint32 nanosec\n"
_HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n"
_JOINT_TRAJECTORY = (
    "std_msgs/Header header\nstring[] joint_names\nJointTrajectoryPoint[] points\n"
    f"{_SEP}MSG: std_msgs/Header\n{_HEADER}"
    f"{_SEP}MSG: builtin_interfaces/Time\n{_TIME}"
    f"{_SEP}MSG: trajectory_msgs/JointTrajectoryPoint\n"
    "float64[] positions\nfloat64[] velocities\nfloat64[] accelerations\nfloat64[] effort\n"
    "builtin_interfaces/Duration time_from_start\n"
    f"{_SEP}MSG: builtin_interfaces/Duration\n{_TIME}"
)
_JOINT_STATE = (
    "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\n"
    "float64[] effort\n"
    f"{_SEP}MSG: std_msgs/Header\n{_HEADER}"
    f"{_SEP}MSG: builtin_interfaces/Time\n{_TIME}"
)
_FLOAT64 = "float64 data\n"


class SampledTrajectory(Protocol):
    """What a bag takes of a trajectory: ``t`` (M,), s; ``q``, ``qd``, ``qdd`` (M, 3); and
    ``tau`` (M, 3) or None (the library's :class:`~planner.timing.Trajectory`, a
    :class:`~planner.timing.export.TrajectoryArrays`, a :class:`~planner.simulation.Reference`
    all have them; a missing ``tau`` counts as None)."""

    @property
    def t(self) -> np.ndarray: ...
    @property
    def q(self) -> np.ndarray: ...
    @property
    def qd(self) -> np.ndarray: ...
    @property
    def qdd(self) -> np.ndarray: ...


class RecordedRun(Protocol):
    """What a bag takes of a simulated run: ``t`` (K,), s; ``q``, ``qd``, ``tau`` (K, 3);
    ``p_error_mm`` (K,) (a :class:`~planner.simulation.Simulation` has them)."""

    @property
    def t(self) -> np.ndarray: ...
    @property
    def q(self) -> np.ndarray: ...
    @property
    def qd(self) -> np.ndarray: ...
    @property
    def tau(self) -> np.ndarray: ...
    @property
    def p_error_mm(self) -> np.ndarray: ...


@dataclass(frozen=True, eq=False)
class RunArrays:
    """A recorded run as plain arrays (a :class:`RecordedRun` for a run read from elsewhere,
    e.g. a service's answer): ``t`` (K,), s; ``q``, ``qd``, ``tau`` (K, 3); ``p_error_mm``
    (K,)."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray
    p_error_mm: np.ndarray


def _stamp(ns: int) -> dict[str, int]:
    if ns < 0:
        raise ValueError(f"a bag's times must be >= 0 ns (raise start_ns), got {ns}")
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def _ns(seconds: float, start_ns: int) -> int:
    return start_ns + round(seconds * 1e9)


def write_bag(
    target: str | os.PathLike[str] | IO[bytes],
    *,
    trajectory: SampledTrajectory | None = None,
    simulation: RecordedRun | None = None,
    start_ns: int = 0,
    frame_id: str = "base",
) -> None:
    """Write a trajectory and/or a simulation as one ROS 2 bag (MCAP) at ``target`` (a path
    or a binary stream). ``start_ns``: the bag time of the trajectory's t = 0."""
    if trajectory is None and simulation is None:
        raise ValueError("give a trajectory, a simulation or both")
    if isinstance(target, str | os.PathLike):
        with open(target, "wb") as stream:
            _write(stream, trajectory, simulation, start_ns, frame_id)
    else:
        _write(target, trajectory, simulation, start_ns, frame_id)


def _write(
    stream: IO[bytes],
    trajectory: SampledTrajectory | None,
    simulation: RecordedRun | None,
    start_ns: int,
    frame_id: str,
) -> None:
    from mcap_ros2.writer import Writer

    names = list(BAG_JOINT_NAMES)
    with Writer(stream) as writer:
        states = writer.register_msgdef("sensor_msgs/msg/JointState", _JOINT_STATE)
        if trajectory is not None:
            t = np.asarray(trajectory.t, dtype=float)
            tau = getattr(trajectory, "tau", None)
            rows = [np.asarray(a, dtype=float) for a in (trajectory.q, trajectory.qd)]
            effort = None if tau is None else np.asarray(tau, dtype=float)
            schema = writer.register_msgdef(
                "trajectory_msgs/msg/JointTrajectory", _JOINT_TRAJECTORY
            )
            first = _ns(float(t[0]), start_ns)
            points = [
                {
                    "positions": rows[0][i].tolist(),
                    "velocities": rows[1][i].tolist(),
                    "accelerations": np.asarray(trajectory.qdd[i], dtype=float).tolist(),
                    "effort": [] if effort is None else effort[i].tolist(),
                    "time_from_start": _stamp(_ns(float(t[i] - t[0]), 0)),
                }
                for i in range(t.size)
            ]
            message = {
                "header": {"stamp": _stamp(first), "frame_id": frame_id},
                "joint_names": names,
                "points": points,
            }
            writer.write_message(TOPIC_TRAJECTORY, schema, message, first, first)
            _write_states(
                writer, states, TOPIC_PLANNED_STATES, t, rows[0], rows[1], effort, start_ns
            )
        if simulation is not None:
            sim = simulation
            _write_states(
                writer, states, TOPIC_JOINT_STATES, sim.t, sim.q, sim.qd, sim.tau, start_ns
            )
            scalar = writer.register_msgdef("std_msgs/msg/Float64", _FLOAT64)
            for i, (ti, e) in enumerate(zip(sim.t, sim.p_error_mm, strict=True)):
                ns = _ns(float(ti), start_ns)
                writer.write_message(TOPIC_P_ERROR, scalar, {"data": float(e)}, ns, ns, i)


def _write_states(
    writer: Any,
    schema: Any,
    topic: str,
    t: np.ndarray,
    q: np.ndarray,
    qd: np.ndarray,
    tau: np.ndarray | None,
    start_ns: int,
) -> None:
    names = list(BAG_JOINT_NAMES)
    for i in range(len(t)):
        ns = _ns(float(t[i]), start_ns)
        message = {
            "header": {"stamp": _stamp(ns), "frame_id": ""},
            "name": names,
            "position": np.asarray(q[i], dtype=float).tolist(),
            "velocity": np.asarray(qd[i], dtype=float).tolist(),
            "effort": [] if tau is None else np.asarray(tau[i], dtype=float).tolist(),
        }
        writer.write_message(topic, schema, message, ns, ns, i)


@dataclass(frozen=True, eq=False)
class BagContents:
    """A bag read back: per topic, the arrays its messages carry (None: topic absent).

    ``trajectory``: ``{"t", "q", "qd", "qdd", "tau"}`` of the JointTrajectory (t from its
    header's stamp plus each point's time_from_start, s; ``tau`` None without efforts);
    ``planned``, ``realised``: ``{"t", "q", "qd", "tau"}`` of the JointState topics;
    ``p_error_mm``: ``{"t", "data"}``; ``joint_names``: the trajectory's."""

    trajectory: dict[str, Any] | None
    planned: dict[str, Any] | None
    realised: dict[str, Any] | None
    p_error_mm: dict[str, Any] | None
    joint_names: Sequence[str] | None


def read_bag(source: str | os.PathLike[str] | IO[bytes], start_ns: int = 0) -> BagContents:
    """The arrays of a bag written by :func:`write_bag` (times in s from ``start_ns``)."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    def seconds(stamp: Any) -> float:
        return (stamp.sec * 1_000_000_000 + stamp.nanosec - start_ns) / 1e9

    trajectory = None
    names = None
    states: dict[str, list[Any]] = {TOPIC_PLANNED_STATES: [], TOPIC_JOINT_STATES: []}
    errors: list[tuple[float, float]] = []
    if isinstance(source, str | os.PathLike):
        with open(source, "rb") as stream:
            return read_bag(stream, start_ns)
    reader = make_reader(source, decoder_factories=[DecoderFactory()])
    for _, channel, record, msg in reader.iter_decoded_messages(log_time_order=True):
        topic = channel.topic
        if topic == TOPIC_TRAJECTORY:
            t0 = seconds(msg.header.stamp)
            pts = msg.points
            names = list(msg.joint_names)
            efforts = [list(p.effort) for p in pts]
            trajectory = {
                "t": np.array(
                    [t0 + p.time_from_start.sec + p.time_from_start.nanosec / 1e9 for p in pts]
                ),
                "q": np.array([list(p.positions) for p in pts]),
                "qd": np.array([list(p.velocities) for p in pts]),
                "qdd": np.array([list(p.accelerations) for p in pts]),
                "tau": np.array(efforts) if all(efforts) else None,
            }
        elif topic in states:
            states[topic].append(msg)
        elif topic == TOPIC_P_ERROR:
            errors.append(((record.log_time - start_ns) / 1e9, msg.data))

    def arrays(msgs: list[Any]) -> dict[str, Any] | None:
        if not msgs:
            return None
        tau = [list(s.effort) for s in msgs]
        return {
            "t": np.array([seconds(s.header.stamp) for s in msgs]),
            "q": np.array([list(s.position) for s in msgs]),
            "qd": np.array([list(s.velocity) for s in msgs]),
            "tau": np.array(tau) if all(tau) else None,
        }

    return BagContents(
        trajectory=trajectory,
        planned=arrays(states[TOPIC_PLANNED_STATES]),
        realised=arrays(states[TOPIC_JOINT_STATES]),
        p_error_mm=(
            {"t": np.array([e[0] for e in errors]), "data": np.array([e[1] for e in errors])}
            if errors
            else None
        ),
        joint_names=names,
    )
