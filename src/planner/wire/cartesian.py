"""``POST /v1/cartesian``: straight tool paths (``docs/cartesian.md``). The request, its
timing options, the response (a plan response plus ``fraction``, the stopping point and
the deviation from the polyline) and the conversions to and from
:func:`planner.cartesian.plan.plan_cartesian`, once each way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, PrivateAttr

from planner.design import Design
from planner.wire.common import (
    GRAVITY_FIELD,
    MAX_OBSTACLES,
    DesignModel,
    DiagnosticsModel,
    Gravity,
    JointPostureModel,
    MarginsModel,
    Obstacle,
    Point3,
    Vec3,
    WorkingModeLabel,
    _DesignField,
    _Request,
    _Response,
    design_to_core,
    inertia_to_core,
    located,
    margins_to_core,
)
from planner.wire.plan import PathModel, PlanStatus, path_model
from planner.wire.scenes import SceneName, scene_obstacles
from planner.wire.timing import (
    _FORMAT_DESCRIPTION,
    AnyTrajectory,
    Limits,
    TrajectoryFormat,
    joint_limits_to_core,
    trajectory_model,
)

__all__ = [
    "MAX_CARTESIAN_WAYPOINTS",
    "MAX_POLYLINE_REACHES",
    "CartesianDiagnosticsModel",
    "CartesianInputs",
    "CartesianRequest",
    "CartesianResponse",
    "CartesianStop",
    "CartesianTimingOptions",
    "cartesian_inputs",
    "cartesian_response",
]

#: Hard cap on the waypoints of one Cartesian request.
MAX_CARTESIAN_WAYPOINTS = 1_000
#: Bounds of ``path_tolerance``, m: below 10 um the certified refinement needs pieces of a
#: few nanometres; above 0.1 m "straight" means little.
MIN_PATH_TOLERANCE = 1e-5
MAX_PATH_TOLERANCE = 0.1
#: Longest polyline accepted, in units of the reach L1 + L2: P never leaves the ball of that
#: radius about A, so a longer one is a mistake, and its probes (one every 2 mm, planned
#: before the stop is known) would cost seconds per kilometre.
MAX_POLYLINE_REACHES = 100.0


class CartesianTimingOptions(_Request):
    """How a straight tool path is timed. The corner blends are not an option here: they
    follow from ``path_tolerance`` (what the chords leave of it)."""

    method: Literal["toppra", "ruckig", "none"] = Field(
        "toppra",
        description="toppra (default; with limits.cartesian_speed P moves at that constant "
        "speed wherever the joint limits allow), ruckig (jerk-limited) or none.",
    )
    sample_rate_hz: Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=10_000.0)] = 100.0
    format: TrajectoryFormat = Field("arrays", description=_FORMAT_DESCRIPTION)


class CartesianRequest(_Request):
    """Body of ``POST /v1/cartesian``: P moves on straight segments from the start's P through
    each waypoint in turn, in the start's working and assembly mode (never changed), within
    ``path_tolerance`` of the polyline along the timed trajectory. Only ``start`` and
    ``waypoints`` are required."""

    design: DesignModel = _DesignField
    start: JointPostureModel
    waypoints: Annotated[list[Point3], Field(min_length=1, max_length=MAX_CARTESIAN_WAYPOINTS)] = (
        Field(description="Points P goes through in order, m (at least one).")
    )
    path_tolerance: Annotated[
        float, Field(allow_inf_nan=False, ge=MIN_PATH_TOLERANCE, le=MAX_PATH_TOLERANCE)
    ] = Field(
        1e-3,
        description="Largest distance of P from the polyline along the trajectory, m, in "
        "[1e-5, 0.1]; default 1 mm.",
    )
    obstacles: list[Obstacle] = Field(default_factory=list, max_length=MAX_OBSTACLES)
    scene: SceneName | None = Field(
        None,
        description="A stored scene's name (PUT /v1/scenes/{name}): its obstacles join "
        "`obstacles`, its design is the robot when `design` is absent; unknown: 422.",
    )
    #: the named scene's library obstacles, set by the service (:func:`with_scene`)
    _scene_obstacles: tuple[Any, ...] | None = PrivateAttr(None)
    margins: MarginsModel = Field(default_factory=MarginsModel)
    timing: CartesianTimingOptions = Field(default_factory=CartesianTimingOptions)
    limits: Limits = Field(default_factory=Limits)
    gravity: Gravity = GRAVITY_FIELD


class CartesianStop(_Response):
    """Where and why a straight path stops short."""

    rule: str = Field(
        description="joint_limits, assembly, kappa_max, working_mode, serial_min, clearance "
        "(the validity rules), workspace (the working mode does not reach the point) or "
        "path_tolerance."
    )
    value: float | None = Field(
        None, description="The measured value breaking the rule (null: none applies)."
    )
    p: Vec3 = Field(description="The last valid point of P on the polyline, m.")
    fraction: float = Field(ge=0.0, le=1.0, description="Share of the polyline achieved.")


class CartesianDiagnosticsModel(DiagnosticsModel):
    """A plan's diagnostics plus the measures of a straight path."""

    max_path_deviation: float | None = Field(
        None,
        description="Largest distance of P from the polyline, m: measured over the timed "
        "trajectory's dense check times (1e-3 rad apart), else along the joint path.",
    )
    chord_bound: float | None = Field(
        None, description="Certified bound on P's deviation along the joint path, m."
    )
    blend_deviation_bound: float | None = Field(
        None, description="Certified bound on the extra deviation of the corner blends, m."
    )
    cartesian_length: float | None = Field(None, description="Length of the polyline achieved, m.")


class CartesianResponse(_Response):
    """Answer of ``POST /v1/cartesian``: the fields of a plan response plus ``fraction``;
    ``status`` is ``solved`` exactly when ``fraction`` = 1, else ``no_path`` (the path up to
    the last valid point, ``message`` naming the rule, the measured value and the point) or
    ``invalid_start`` (fraction 0)."""

    status: PlanStatus
    message: str = ""
    fraction: float = Field(ge=0.0, le=1.0, description="Share of the polyline's length achieved.")
    path: PathModel | None = None
    trajectory: AnyTrajectory | None = None
    diagnostics: CartesianDiagnosticsModel = Field(default_factory=CartesianDiagnosticsModel)
    stop: CartesianStop | None = Field(None, description="Where and why the path stopped short.")
    working_mode: WorkingModeLabel | None = Field(
        None, description="The start's working mode, kept along the path."
    )


# ---------------------------------------------------------------------------- conversions
@dataclass(frozen=True)
class CartesianInputs:
    """A Cartesian request as the library's objects (each field's errors located): the
    arguments of :func:`planner.cartesian.plan.plan_cartesian`."""

    design: Design
    start: Any
    waypoints: np.ndarray
    obstacles: list[Any]
    margins: Any
    limits: Any
    options: dict[str, Any]


def cartesian_inputs(request: CartesianRequest) -> CartesianInputs:
    """The library objects of a Cartesian request (a bad value raises the library's error,
    located at its field). A polyline longer than :data:`MAX_POLYLINE_REACHES` reaches
    (L1 + L2), from the start's P, is an :class:`~planner.exceptions.InputError` at
    ``waypoints``."""
    from planner.exceptions import InputError
    from planner.kinematics import forward_batch
    from planner.planning.problem import JointPosture as CorePosture

    design = design_to_core(request.design)
    with located("body", "start"):
        start = CorePosture(np.array(request.start.q), request.start.assembly_mode)
    waypoints = np.asarray(request.waypoints, dtype=float)
    fb = forward_batch(design, start.q, start.assembly_mode)
    if fb.ok[0]:
        vertices = np.vstack([fb.p[0][None], waypoints])
        length = float(np.sum(np.linalg.norm(np.diff(vertices, axis=0), axis=1)))
        cap = MAX_POLYLINE_REACHES * (design.L1 + design.L2)
        if length > cap:
            with located("body"):
                raise InputError(
                    f"waypoints: the polyline from the start's P is {length:.6g} m long, more "
                    f"than {MAX_POLYLINE_REACHES:g} (L1 + L2) = {cap:.6g} m (P never leaves "
                    "the ball of radius L1 + L2 about A)",
                    field="waypoints",
                )
    obstacles = scene_obstacles(request)
    margins = margins_to_core(request.margins)
    limits = joint_limits_to_core(request.limits)
    options = {
        "path_tolerance": request.path_tolerance,
        "timing": request.timing.method,
        "sample_rate_hz": request.timing.sample_rate_hz,
        "cartesian_speed": request.limits.cartesian_speed,
        "inertia": inertia_to_core(request.design),
        "gravity": tuple(request.gravity),
    }
    return CartesianInputs(design, start, waypoints, obstacles, margins, limits, options)


def _finite(x: float) -> float | None:
    return float(x) if x is not None and math.isfinite(x) else None


def cartesian_response(result: Any, *, format: TrajectoryFormat = "arrays") -> CartesianResponse:
    """The answer of one straight path, built once from a
    :class:`planner.cartesian.plan.CartesianResult`."""
    d = result.diagnostics
    timed = result.trajectory is not None
    diagnostics = CartesianDiagnosticsModel(
        planning_time_s=d.planning_time_s,
        timing_time_s=d.timing_time_s if timed else None,
        timing_repairs=getattr(result.trajectory, "repairs", None) if timed else None,
        max_torque_ratio=getattr(result.trajectory, "max_torque_ratio", None) if timed else None,
        path_length=_finite(d.path_length),
        min_clearance=_finite(d.min_clearance),
        max_kappa_A=_finite(d.max_kappa_A),
        min_serial_margin=_finite(d.min_serial_margin),
        planner="cartesian",
        max_path_deviation=_finite(d.max_path_deviation),
        chord_bound=_finite(d.chord_bound),
        blend_deviation_bound=_finite(d.blend_deviation_bound),
        cartesian_length=_finite(d.cartesian_length),
    )
    stop = result.stop
    return CartesianResponse(
        status=result.status.value,
        message=result.message,
        fraction=float(result.fraction),
        path=path_model(result.path) if result.path is not None else None,
        trajectory=trajectory_model(result.trajectory, format) if timed else None,
        diagnostics=diagnostics,
        stop=None
        if stop is None
        else CartesianStop(
            rule=stop.rule,
            value=_finite(stop.value),
            p=np.asarray(stop.p, dtype=float).tolist(),
            fraction=float(stop.fraction),
        ),
        working_mode=result.working_mode or None,
    )
