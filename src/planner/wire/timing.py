"""The timing vocabulary: timing options and joint limits of a plan, the timed trajectory, and
``POST /v1/timing``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from numpy.typing import ArrayLike
from pydantic import (
    Discriminator,
    Field,
    Tag,
    ValidationInfo,
    field_validator,
)

from planner.exceptions import InputError
from planner.timing.export import JOINT_NAMES, TrajectoryArrays, checked_arrays
from planner.wire.common import (
    _MAX_SAMPLES,
    GRAVITY_FIELD,
    MAX_OBSTACLES,
    Angles3,
    AssemblyModeLabel,
    DesignModel,
    Gravity,
    Integer,
    MarginsModel,
    Obstacle,
    Rates3,
    Vec3,
    WorkingModeLabel,
    _DesignField,
    _Request,
    _Response,
    located,
    triple_to_core,
)
from planner.wire.diagnostics import DiagnosticsModel, TimingErrorInfo

if TYPE_CHECKING:
    from planner.timing.limits import JointLimits
    from planner.timing.options import TimingOptions
    from planner.timing.trajectory import Trajectory
    from planner.wire.cartesian import CartesianTimingOptions

__all__ = [
    "MAX_TIMING_WAYPOINTS",
    "AnyTrajectory",
    "Limits",
    "Scaling",
    "StartRatesModel",
    "TimingOptionsModel",
    "TimingRequest",
    "TimingResponse",
    "TimingStatus",
    "TrajectoryFormat",
    "TrajectoryModel",
    "TrajectoryPoint",
    "TrajectoryPointsModel",
    "arrays_from_points",
    "joint_limits_to_core",
    "points_from_arrays",
    "timing_error",
    "timing_to_core",
    "trajectory_arrays",
    "trajectory_model",
    "trajectory_points",
]

#: ``timing.format``: parallel arrays (``t``, ``q``, ``qd``, ``qdd``) or a controller's points.
TrajectoryFormat = Literal["arrays", "points"]
#: A speed scaling factor in (0, 1] (MoveIt's ``max_*_scaling_factor``).
Scaling = Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=1.0)]
_FORMAT_DESCRIPTION = (
    "Shape of the trajectory: 'arrays' (default: t, q, qd, qdd as parallel arrays) or "
    "'points' (duration, joint_names theta1..theta3 and points with time_from_start, "
    "positions, velocities, accelerations: a controller's JointTrajectory)."
)


class TimingOptionsModel(_Request):
    """How the planned path is turned into a trajectory."""

    method: Literal["toppra", "ruckig", "none"] = "toppra"
    sample_rate_hz: Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=10_000.0)] = 100.0
    stop_at_transits: bool = Field(False, description="Come to rest at each mode transit.")
    max_deviation: Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=1.0)] | None = Field(
        None,
        description="Largest joint-space distance from a waypoint to its corner blend, rad "
        "(0: stop at every waypoint); absent: the timing default.",
    )
    format: TrajectoryFormat = Field("arrays", description=_FORMAT_DESCRIPTION)


class Limits(_Request):
    """Per-joint limits (rad/s, rad/s^2, rad/s^3); an absent velocity or acceleration takes
    the timing default (:meth:`planner.timing.JointLimits.default`: 2 rad/s, 8 rad/s^2). An
    absent ``jerk`` is not asked: ``toppra`` is then not jerk-limited and ``ruckig`` takes its
    default, 200 rad/s^3; a given one is honoured by both methods."""

    velocity: Rates3 | None = None
    acceleration: Rates3 | None = None
    jerk: Rates3 | None = Field(
        None,
        description="Jerk limits, rad/s^3 (optional): honoured by toppra (its profile "
        "moving-averaged per rest-to-rest section) and ruckig; absent: toppra is not "
        "jerk-limited, ruckig takes 200 rad/s^3.",
    )
    cartesian_speed: Annotated[float, Field(allow_inf_nan=False, ge=1e-6, le=1e3)] | None = Field(
        None, description="Bound on the speed of P, m/s (optional)."
    )
    torque: (
        Annotated[
            list[Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=1e6)]],
            Field(min_length=3, max_length=3),
        ]
        | None
    ) = Field(
        None,
        description="Actuator torque limits, N m, each > 0 (optional): the timing is "
        "time-optimal under |tau_j| <= torque[j] too, and the trajectory carries tau.",
    )
    velocity_scaling: Scaling = Field(
        1.0,
        description="Factor in (0, 1] multiplying the velocity limits (default 1: as given).",
    )
    acceleration_scaling: Scaling = Field(
        1.0,
        description="Factor in (0, 1] multiplying the acceleration limits (default 1: as given).",
    )


class TrajectoryModel(_Response):
    """The timed trajectory: M samples of t (s), q (rad), qd (rad/s), qdd (rad/s^2); for
    ruckig also the jerk (rad/s^3); P (m) and its speed (m/s); the largest deviation from the
    planned path in joint space (rad) and at P (m)."""

    duration: float
    t: Annotated[list[float], Field(max_length=_MAX_SAMPLES)]
    q: Annotated[list[Vec3], Field(max_length=_MAX_SAMPLES)]
    qd: Annotated[list[Vec3], Field(max_length=_MAX_SAMPLES)]
    qdd: Annotated[list[Vec3], Field(max_length=_MAX_SAMPLES)]
    jerk: Annotated[list[Vec3], Field(max_length=_MAX_SAMPLES)] | None = None
    p: Annotated[list[Vec3], Field(max_length=_MAX_SAMPLES)] | None = None
    p_speed: Annotated[list[float], Field(max_length=_MAX_SAMPLES)] | None = None
    method: Literal["toppra", "ruckig"] | None = None
    max_deviation_q: float | None = None
    max_deviation_p: float | None = None
    tau: Annotated[list[Vec3], Field(max_length=_MAX_SAMPLES)] | None = Field(
        None, description="Actuator torques, N m (with design.inertia or limits.torque)."
    )


class TrajectoryPoint(_Response):
    """One sample of a points trajectory: time from the start (s), and per joint (in the
    order of ``joint_names``) position (rad), velocity (rad/s) and acceleration (rad/s^2)."""

    time_from_start: float
    positions: Vec3
    velocities: Vec3
    accelerations: Vec3
    effort: Vec3 | None = Field(
        None, description="Actuator torques, N m (with design.inertia or limits.torque)."
    )


class TrajectoryPointsModel(_Response):
    """The timed trajectory as a controller takes it (``timing.format = "points"``, ROS 2's
    ``JointTrajectory`` shape): the same samples as the arrays form, one point each."""

    duration: float
    joint_names: Annotated[list[str], Field(min_length=3, max_length=3)] = Field(
        default_factory=lambda: ["theta1", "theta2", "theta3"]
    )
    points: Annotated[list[TrajectoryPoint], Field(min_length=1, max_length=_MAX_SAMPLES)]
    method: Literal["toppra", "ruckig"] | None = None
    max_deviation_q: float | None = None
    max_deviation_p: float | None = None


def _trajectory_kind(value: Any) -> str:
    if isinstance(value, dict):
        return "points" if "points" in value else "arrays"
    return "points" if isinstance(value, TrajectoryPointsModel) else "arrays"


#: A trajectory in either format (told apart by the ``points`` field).
AnyTrajectory = Annotated[
    Annotated[TrajectoryModel, Tag("arrays")] | Annotated[TrajectoryPointsModel, Tag("points")],
    Discriminator(_trajectory_kind),
]


# ---------------------------------------------------------------------------- timing
#: Hard cap on the waypoints of a path sent to ``POST /v1/timing``.
MAX_TIMING_WAYPOINTS = 10_000


class StartRatesModel(_Request):
    """The state a timed path starts in (its posture is the first waypoint)."""

    qd: Annotated[
        list[Annotated[float, Field(allow_inf_nan=False)]], Field(min_length=3, max_length=3)
    ] = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="Joint velocity, rad/s.")
    qdd: Annotated[
        list[Annotated[float, Field(allow_inf_nan=False)]], Field(min_length=3, max_length=3)
    ] = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="Joint acceleration, rad/s^2.")


class TimingRequest(_Request):
    """Body of ``POST /v1/timing``: time-parameterise a joint path (N x 3 waypoints, rad,
    joined by straight joint-space segments, literal values) from rest to rest, checked
    densely against the design's joint limits, the assembly mode and, when ``margins`` or
    ``obstacles`` are given, the planner's validity rules."""

    design: DesignModel = _DesignField
    waypoints: Annotated[list[Angles3], Field(min_length=2, max_length=MAX_TIMING_WAYPOINTS)] = (
        Field(description="N x 3 joint waypoints, rad, N >= 2.")
    )
    assembly_mode: AssemblyModeLabel = Field("+", description="Assembly mode of the path.")
    method: Literal["toppra", "ruckig"] = "toppra"
    sample_rate_hz: Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=10_000.0)] = 100.0
    format: TrajectoryFormat = Field("arrays", description=_FORMAT_DESCRIPTION)
    limits: Limits = Field(default_factory=Limits)
    gravity: Gravity = GRAVITY_FIELD
    max_deviation: Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=1.0)] | None = Field(
        None, description="Largest distance from a waypoint to its corner blend, rad."
    )
    stop_at: list[Annotated[Integer, Field(ge=0)]] = Field(
        default_factory=list,
        max_length=MAX_TIMING_WAYPOINTS,
        description="Waypoint indices where the trajectory comes to rest.",
    )
    margins: MarginsModel | None = Field(
        None, description="Validity margins of the dense re-check (the planner's rules)."
    )
    obstacles: list[Obstacle] = Field(default_factory=list, max_length=MAX_OBSTACLES)
    working_mode: WorkingModeLabel | None = Field(
        None,
        description="Working mode the validity rules hold the path to (absent: that of the "
        "first waypoint); used with margins or obstacles.",
    )
    start: StartRatesModel = Field(
        default_factory=StartRatesModel,
        description="A moving start at the first waypoint: `qd`, `qdd` (default zeros). The "
        "trajectory begins in exactly that state through a lead-in (docs/execution.md).",
    )

    @field_validator("stop_at")
    @classmethod
    def _stop_at_in_range(cls, value: list[int], info: ValidationInfo) -> list[int]:
        waypoints = info.data.get("waypoints")
        if waypoints is None:  # waypoints failed their own check: nothing to compare with
            return value
        n = len(waypoints)
        for i in value:
            if i >= n:
                raise ValueError(f"stop_at holds waypoint indices in [0, {n}), got {i}")
        return value


TimingStatus = Literal["solved", "invalid_path", "invalid_start", "infeasible", "timeout"]


class TimingResponse(_Response):
    """Answer of ``POST /v1/timing``. ``solved``: ``trajectory`` passed the dense re-check;
    ``invalid_path``: the path itself breaks a rule between its waypoints, or no repair kept
    the trajectory valid (``diagnostics.timing_error`` names the rule, time and posture);
    ``invalid_start``: a moving start whose quickest braking already breaks a rule;
    ``infeasible``: the solver found no profile; ``timeout``: the request's deadline passed."""

    status: TimingStatus
    message: str = ""
    trajectory: AnyTrajectory | None = None
    diagnostics: DiagnosticsModel = Field(default_factory=DiagnosticsModel)


# ---------------------------------------------------------------------------- conversions
def joint_limits_to_core(
    model: Limits, loc: tuple[str | int, ...] = ("body", "limits")
) -> JointLimits:
    """The request's ``limits`` as :class:`planner.timing.JointLimits` (absent fields: the
    library's defaults), scaled by ``velocity_scaling`` and ``acceleration_scaling``
    (:meth:`planner.timing.JointLimits.scaled`); a bad value raises ``LimitsError`` located at
    ``loc.<field>``."""
    from planner.timing import JointLimits

    default = JointLimits.default()
    jerk = model.jerk  # absent: not asked (ruckig takes its default, toppra none)
    with located(*loc):
        limits = JointLimits(
            velocity=triple_to_core(model.velocity or default.velocity),
            acceleration=triple_to_core(model.acceleration or default.acceleration),
            jerk=None if jerk is None else triple_to_core(jerk),
            torque=None if model.torque is None else triple_to_core(model.torque),
        )
        if model.velocity_scaling != 1.0 or model.acceleration_scaling != 1.0:
            limits = limits.scaled(model.velocity_scaling, model.acceleration_scaling)
        return limits


def timing_to_core(
    model: TimingOptionsModel | CartesianTimingOptions,
    limits: Limits,
    loc: tuple[str | int, ...] = ("body", "timing"),
) -> TimingOptions:
    """The request's ``timing`` (and ``limits.cartesian_speed``) as
    :class:`planner.timing.TimingOptions` (an absent ``max_deviation``: the timing default; a
    straight path's timing has no corner allowance nor transits: they follow from its
    tolerance); a bad value raises the library's error located at ``loc.<field>``."""
    from planner.timing.options import DEFAULT_MAX_DEVIATION
    from planner.timing.options import TimingOptions as CoreTiming

    deviation = getattr(model, "max_deviation", None)
    with located(*loc):
        return CoreTiming(
            method=model.method,
            sample_rate_hz=model.sample_rate_hz,
            max_deviation=(DEFAULT_MAX_DEVIATION if deviation is None else deviation),
            stop_at_transits=getattr(model, "stop_at_transits", False),
            max_cartesian_speed=limits.cartesian_speed,
        )


# ------------------------------------------------------------------ the points layout
def points_from_arrays(
    t: ArrayLike,
    q: ArrayLike,
    qd: ArrayLike,
    qdd: ArrayLike,
    *,
    duration: float | None = None,
    tau: ArrayLike | None = None,
) -> dict:
    """The points form (JSON-ready dict) of parallel arrays.

    Parameters
    ----------
    t : shape (M,), s
    q, qd, qdd : shape (M, 3), rad, rad/s, rad/s^2
    duration : float, s, optional (default ``t[-1]``)
    tau : shape (M, 3), N m, optional: each point's ``effort``

    Returns
    -------
    dict with ``duration``, ``joint_names`` (:data:`JOINT_NAMES`) and ``points`` (M dicts
    with ``time_from_start``, ``positions``, ``velocities``, ``accelerations``).
    """
    t, q, qd, qdd, _ = checked_arrays(t, q, qd, qdd)
    points = [
        {
            "time_from_start": ti,
            "positions": qi,
            "velocities": vi,
            "accelerations": ai,
        }
        for ti, qi, vi, ai in zip(t.tolist(), q.tolist(), qd.tolist(), qdd.tolist(), strict=True)
    ]
    if tau is not None:
        for point, effort in zip(points, np.asarray(tau, dtype=float).tolist(), strict=True):
            point["effort"] = effort
    return {
        "duration": float(t[-1] if duration is None else duration),
        "joint_names": list(JOINT_NAMES),
        "points": points,
    }


def arrays_from_points(points_form: Mapping) -> TrajectoryArrays:
    """Parallel arrays of a points form (the inverse of :func:`points_from_arrays`).

    Joints are reordered by ``joint_names`` when present (any order of theta1..theta3).

    Raises
    ------
    InputError
        A missing field, an unknown or missing joint name, or a point of the wrong length.
    """
    try:
        pts = points_form["points"]
    except (KeyError, TypeError) as exc:
        raise InputError("a points trajectory needs a 'points' list") from exc
    names = list(points_form.get("joint_names", JOINT_NAMES))
    if sorted(names) != sorted(JOINT_NAMES) or len(names) != 3:
        raise InputError(f"joint_names must be {list(JOINT_NAMES)} in some order, got {names}")
    order = [names.index(n) for n in JOINT_NAMES]
    if not isinstance(pts, Sequence) or len(pts) == 0:
        raise InputError("points must be a non-empty list")
    try:
        t = np.array([p["time_from_start"] for p in pts], dtype=float)
        q = np.array([p["positions"] for p in pts], dtype=float)[:, order]
        qd = np.array([p["velocities"] for p in pts], dtype=float)[:, order]
        qdd = np.array([p["accelerations"] for p in pts], dtype=float)[:, order]
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise InputError(
            "every point needs time_from_start and 3 positions, velocities, accelerations"
        ) from exc
    t, q, qd, qdd, _ = checked_arrays(t, q, qd, qdd)
    duration = float(points_form.get("duration", t[-1]))
    return TrajectoryArrays(t, q, qd, qdd, None, duration)


def trajectory_model(
    traj: Trajectory, format: TrajectoryFormat = "arrays"
) -> TrajectoryModel | TrajectoryPointsModel:
    """The wire form of a :class:`planner.timing.Trajectory`, in ``format`` (``"points"``:
    :func:`points_from_arrays`, the same samples)."""
    if format == "points":
        return trajectory_points(_arrays_model(traj))
    return _arrays_model(traj)


def _arrays_model(traj: Trajectory) -> TrajectoryModel:
    return TrajectoryModel(
        method=traj.method,
        duration=traj.duration,
        t=traj.t.tolist(),
        q=traj.q.tolist(),
        qd=traj.qd.tolist(),
        qdd=traj.qdd.tolist(),
        jerk=traj.jerk.tolist() if traj.jerk is not None else None,
        p=traj.p.tolist(),
        p_speed=traj.p_speed.tolist(),
        max_deviation_q=traj.max_deviation_q,
        max_deviation_p=traj.max_deviation_p,
        tau=_tau_list(traj),
    )


def _tau_list(traj: Trajectory) -> list[list[float]] | None:
    """The trajectory's torques as lists (None without them; a NaN, which a checked
    trajectory does not have, would not be JSON)."""
    tau = getattr(traj, "tau", None)
    if tau is None or not np.all(np.isfinite(tau)):
        return None
    return np.asarray(tau, dtype=float).tolist()


def timing_error(exc: Exception) -> TimingErrorInfo:
    """``diagnostics.timing_error`` of a failed timing: the error's type, and the rule, time
    and posture of a failed dense re-check."""
    q = getattr(exc, "q", None)
    return TimingErrorInfo(
        type=type(exc).__name__,
        rule=getattr(exc, "rule", None),
        time=getattr(exc, "time", None),
        q=list(q) if q is not None else None,
    )


def trajectory_points(model: TrajectoryModel | TrajectoryPointsModel) -> TrajectoryPointsModel:
    """The points form of a wire trajectory (the same floats, one point per sample, ``tau``
    as each point's ``effort``; the arrays' other per-sample extras ``jerk``, ``p``,
    ``p_speed`` have no place there). A points
    trajectory is returned as it is."""
    if isinstance(model, TrajectoryPointsModel):
        return model
    form = points_from_arrays(
        model.t, model.q, model.qd, model.qdd, duration=model.duration, tau=model.tau
    )
    return TrajectoryPointsModel(
        **form,
        method=model.method,
        max_deviation_q=model.max_deviation_q,
        max_deviation_p=model.max_deviation_p,
    )


def trajectory_arrays(model: TrajectoryModel | TrajectoryPointsModel) -> TrajectoryModel:
    """The arrays form of a wire trajectory (:func:`arrays_from_points`:
    the same floats, joints ordered by ``joint_names``). An arrays trajectory is returned as
    it is."""
    if isinstance(model, TrajectoryModel):
        return model
    a = arrays_from_points(model.model_dump(include={"duration", "joint_names", "points"}))
    efforts = [p.effort for p in model.points]
    order = [list(model.joint_names).index(n) for n in JOINT_NAMES]
    tau = None if any(e is None for e in efforts) else np.asarray(efforts)[:, order].tolist()
    return TrajectoryModel(
        duration=a.duration,
        t=a.t.tolist(),
        q=a.q.tolist(),
        qd=a.qd.tolist(),
        qdd=a.qdd.tolist(),
        tau=tau,
        method=model.method,
        max_deviation_q=model.max_deviation_q,
        max_deviation_p=model.max_deviation_p,
    )
