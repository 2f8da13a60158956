"""``POST /v1/simulate``: a trajectory (or a plan or sequence request, planned first) run on
the simulated robot (:mod:`planner.simulation`), and its answer (``docs/simulation.md``).

The robot is the request's ``design`` (with its ``inertia``), ``gravity``, ``assembly_mode`` and
``limits.torque`` (the actuators saturate there; absent: no saturation). With ``request`` the
robot is that request's (its design, gravity, limits and start's assembly mode): the
top-level fields of the robot must then be absent (a 422 at the one given), so that nothing
is accepted and silently overridden.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import Discriminator, Field, Tag

from planner.exceptions import InputError
from planner.wire.common import (
    GRAVITY_FIELD,
    Angles3,
    AssemblyModeLabel,
    DesignModel,
    Gravity,
    Vec3,
    _DesignField,
    _Request,
    _Response,
    design_to_core,
    inertia_to_core,
    located,
)
from planner.wire.plan import PlanRequest
from planner.wire.sequence import SequenceRequest
from planner.wire.timing import TrajectoryModel, TrajectoryPointsModel, trajectory_arrays

if TYPE_CHECKING:
    from planner.design import Design
    from planner.dynamics import Inertia
    from planner.simulation import Controller, Reference, Simulation

__all__ = [
    "BAG_MEDIA_TYPE",
    "MAX_SIMULATE_TRAJECTORY_SAMPLES",
    "ControllerModel",
    "SimulateLimits",
    "SimulateRequest",
    "SimulateResponse",
    "SimulatedTrajectory",
    "SimulationRobot",
    "StopModel",
    "TrackingModel",
    "controller_to_core",
    "reference_to_core",
    "simulation_bag",
    "simulation_response",
    "simulation_robot",
]

#: Media type of a ROS 2 bag answer (MCAP has no registered type).
BAG_MEDIA_TYPE = "application/octet-stream"

#: Most samples of a trajectory sent to ``POST /v1/simulate``.
MAX_SIMULATE_TRAJECTORY_SAMPLES = 100_000

_Gain = Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=1e9)]
_Gains = Annotated[list[_Gain], Field(min_length=3, max_length=3)]
_Time = Annotated[float, Field(allow_inf_nan=False, ge=-1e7, le=1e7)]
_Rate = Annotated[float, Field(allow_inf_nan=False, ge=-1e6, le=1e6)]
_Rates = Annotated[list[_Rate], Field(min_length=3, max_length=3)]
_Torque = Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=1e6)]
_N = MAX_SIMULATE_TRAJECTORY_SAMPLES


class ControllerModel(_Request):
    """The controller: ``computed_torque`` (the product's inverse dynamics as the
    feed-forward plus ``M(q_ref) (kp e + kd e_dot)``; kp 1/s^2, kd 1/s; default 2500, 100)
    or ``pd`` (``kp e + kd e_dot`` alone; kp N m/rad, kd N m s/rad; default 2500 and 100
    times the mass matrix's diagonal at the first posture)."""

    kind: Literal["computed_torque", "pd"] = "computed_torque"
    kp: _Gains | None = Field(None, description="Proportional gains, 3, >= 0.")
    kd: _Gains | None = Field(None, description="Derivative gains, 3, >= 0.")


class SimulatedTrajectory(_Request):
    """The trajectory to run: M samples of t (s, strictly increasing, any origin), q (rad),
    qd (rad/s), qdd (rad/s^2), read between samples by quintic interpolation and held at
    its last posture after its end. A plan's answer trajectory in the arrays form gives
    these four fields."""

    t: Annotated[list[_Time], Field(min_length=1, max_length=_N)]
    q: Annotated[list[Angles3], Field(min_length=1, max_length=_N)]
    qd: Annotated[list[_Rates], Field(min_length=1, max_length=_N)]
    qdd: Annotated[list[_Rates], Field(min_length=1, max_length=_N)]


class SimulateLimits(_Request):
    """The actuators' limits of the simulated robot."""

    torque: Annotated[list[_Torque], Field(min_length=3, max_length=3)] | None = Field(
        None, description="N m, each > 0: every applied torque is clipped to +-torque[j]."
    )


def _motion_kind(value: Any) -> str:
    if isinstance(value, dict):
        return "sequence" if "targets" in value else "plan"
    return "sequence" if isinstance(value, SequenceRequest) else "plan"


#: A plan or a sequence request (told apart by ``targets``).
MotionToSimulate = Annotated[
    Annotated[PlanRequest, Tag("plan")] | Annotated[SequenceRequest, Tag("sequence")],
    Discriminator(_motion_kind),
]

#: The fields of the robot, given at the top or taken from ``request``.
_ROBOT_FIELDS = ("design", "gravity", "assembly_mode", "limits")


class SimulateRequest(_Request):
    """Body of ``POST /v1/simulate``: exactly one of ``trajectory`` and ``request``."""

    design: DesignModel = _DesignField
    gravity: Gravity = GRAVITY_FIELD
    assembly_mode: AssemblyModeLabel = Field("+", description="The trajectory's, '+' or '-'.")
    trajectory: SimulatedTrajectory | None = None
    request: MotionToSimulate | None = Field(
        None,
        description="A plan or sequence request, planned first (its timing.sample_rate_hz "
        "defaults to rate_hz); its robot is the simulated one.",
    )
    controller: ControllerModel = Field(default_factory=ControllerModel)
    rate_hz: Annotated[float, Field(allow_inf_nan=False, ge=10.0, le=10_000.0)] = Field(
        1000.0, description="Control rate, Hz (the torque is held between two instants)."
    )
    limits: SimulateLimits = Field(default_factory=SimulateLimits)
    settle_tolerance_mm: Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=1000.0)] = Field(
        0.1, description="P within this of the reference counts as settled, mm."
    )
    hold_s: Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=10.0)] = Field(
        1.0, description="Longest hold at the last posture after the motion, s."
    )


class TrackingModel(_Response):
    """The tracking error over every recorded sample."""

    p_max_mm: float
    p_rms_mm: float
    q_max: Vec3 = Field(description="Per joint, the largest |q_ref - q|, rad.")


class StopModel(_Response):
    """A stop of the reference: at rest from ``arrive`` to ``leave`` (s)."""

    arrive: float
    leave: float
    final: bool


class SimulateResponse(_Response):
    """Answer of ``POST /v1/simulate``: the realised samples at ``rate_hz`` and the
    measures of the run (definitions: ``docs/simulation.md``)."""

    t: list[float] = Field(description="Control instants, s (the trajectory's clock).")
    q: list[Vec3] = Field(description="Realised actuated joints, rad.")
    qd: list[Vec3] = Field(description="Realised joint rates, rad/s.")
    tau: list[Vec3] = Field(description="Applied torques (after saturation), N m.")
    p: list[Vec3] = Field(description="Realised P, m (MuJoCo's).")
    p_error_mm: list[float] = Field(description="|P realised - P reference| per sample, mm.")
    tracking: TrackingModel
    planned_duration: float = Field(description="The trajectory's duration, s.")
    realised_duration: float | None = Field(
        description="Planned duration plus the final stop's settle time, s; null: not settled."
    )
    settle_times: list[float | None] = Field(
        description="Per stop (the last one the end), s from arrival; null: not settled."
    )
    stops: list[StopModel]
    engine: str = Field(description="'mujoco x.y.z'.")
    controller: str
    rate_hz: float
    physics_timestep: float = Field(description="MuJoCo's integration step (RK4), s.")
    saturated_samples: int = Field(description="Control instants where a torque was clipped.")
    assembly_kept: bool = Field(description="The loop stayed in its assembly mode throughout.")
    trajectory: TrajectoryModel | None = Field(
        None, description="With `request`: the planned trajectory that was simulated."
    )


class SimulationRobot:
    """The simulated robot of a request, as the library's objects."""

    __slots__ = ("assembly_mode", "design", "gravity", "inertia", "torque_limits")

    def __init__(
        self,
        design: Design,
        inertia: Inertia | None,
        gravity: list[float],
        assembly_mode: str,
        torque_limits: list[float] | None,
    ) -> None:
        self.design = design
        self.inertia = inertia
        self.gravity = gravity
        self.assembly_mode = assembly_mode
        self.torque_limits = torque_limits


def simulation_robot(request: SimulateRequest) -> SimulationRobot:
    """The robot of a simulate request (the inner request's with ``request``; a top-level
    robot field given beside it is an InputError at that field)."""
    inner = request.request
    if inner is None:
        return SimulationRobot(
            design_to_core(request.design),
            inertia_to_core(request.design),
            list(request.gravity),
            request.assembly_mode,
            request.limits.torque,
        )
    for name in _ROBOT_FIELDS:
        if name in request.model_fields_set:
            with located("body", name):
                raise InputError(
                    f"{name} is the request's with `request`: give it there, not at the top"
                )
    return SimulationRobot(
        design_to_core(inner.design),
        inertia_to_core(inner.design),
        list(inner.gravity),
        inner.start.assembly_mode,
        inner.limits.torque,
    )


def reference_to_core(
    trajectory: SimulatedTrajectory | TrajectoryModel | TrajectoryPointsModel,
    loc: tuple[str | int, ...] = ("body", "trajectory"),
) -> Reference:
    """The library's :class:`~planner.simulation.Reference` of a trajectory, its errors
    located under ``loc``."""
    from planner.simulation import Reference

    if isinstance(trajectory, TrajectoryPointsModel):
        trajectory = trajectory_arrays(trajectory)
    with located(*loc):
        return Reference(
            np.asarray(trajectory.t, dtype=float),
            np.asarray(trajectory.q, dtype=float),
            np.asarray(trajectory.qd, dtype=float),
            np.asarray(trajectory.qdd, dtype=float),
        )


def controller_to_core(model: ControllerModel) -> Controller:
    """The library's :class:`~planner.simulation.Controller`."""
    from planner.simulation import Controller

    with located("body", "controller"):
        return Controller(
            model.kind,
            None if model.kp is None else (model.kp[0], model.kp[1], model.kp[2]),
            None if model.kd is None else (model.kd[0], model.kd[1], model.kd[2]),
        )


def simulation_response(
    sim: Simulation, trajectory: TrajectoryModel | None = None
) -> SimulateResponse:
    """The wire answer of a :class:`~planner.simulation.Simulation`."""
    return SimulateResponse(
        t=sim.t.tolist(),
        q=sim.q.tolist(),
        qd=sim.qd.tolist(),
        tau=sim.tau.tolist(),
        p=sim.p.tolist(),
        p_error_mm=sim.p_error_mm.tolist(),
        tracking=TrackingModel(
            p_max_mm=sim.tracking.p_max_mm,
            p_rms_mm=sim.tracking.p_rms_mm,
            q_max=list(sim.tracking.q_max),
        ),
        planned_duration=sim.planned_duration,
        realised_duration=sim.realised_duration,
        settle_times=list(sim.settle_times),
        stops=[StopModel(arrive=s.arrive, leave=s.leave, final=s.final) for s in sim.stops],
        engine=sim.engine,
        controller=sim.controller,
        rate_hz=sim.rate_hz,
        physics_timestep=sim.physics_timestep,
        saturated_samples=sim.saturated,
        assembly_kept=sim.assembly_kept,
        trajectory=trajectory,
    )


def simulation_bag(request: SimulateRequest, response: SimulateResponse) -> bytes:
    """The ROS 2 bag (MCAP bytes, :func:`planner.simulation.bag.write_bag`) of a simulate
    answer: the trajectory it followed (the request's, or with ``request`` the planned one)
    and the realised run."""
    import io

    from planner.simulation.bag import RunArrays, write_bag
    from planner.timing.export import TrajectoryArrays

    source = response.trajectory if response.trajectory is not None else request.trajectory
    if source is None:
        raise InputError("a simulation answer without the trajectory it followed")
    t, q, qd, qdd = (np.asarray(getattr(source, k), dtype=float) for k in ("t", "q", "qd", "qdd"))
    run = RunArrays(
        t=np.asarray(response.t, dtype=float),
        q=np.asarray(response.q, dtype=float),
        qd=np.asarray(response.qd, dtype=float),
        tau=np.asarray(response.tau, dtype=float),
        p_error_mm=np.asarray(response.p_error_mm, dtype=float),
    )
    buffer = io.BytesIO()
    write_bag(buffer, trajectory=TrajectoryArrays(t, q, qd, qdd), simulation=run)
    return buffer.getvalue()
