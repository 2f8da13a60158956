"""``POST /v1/cartesian``: straight tool paths (``docs/cartesian.md``). The request, its
timing options, the response (a plan response plus ``fraction``, the stopping point and
the deviation from the polyline) and the conversions to and from
:func:`planner.cartesian.plan.plan_cartesian`, once each way.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import Field

from planner.wire.common import (
    Point3,
    Vec3,
    WorkingModeLabel,
    _Request,
    _Response,
    located,
)
from planner.wire.diagnostics import DiagnosticsModel
from planner.wire.execution import lead_in_model
from planner.wire.motion import MotionRequest, finite, motion_problem
from planner.wire.plan import PathModel, PlanStatus, path_model
from planner.wire.timing import (
    _FORMAT_DESCRIPTION,
    AnyTrajectory,
    TrajectoryFormat,
    trajectory_model,
)

if TYPE_CHECKING:
    from planner.cartesian.result import CartesianResult
    from planner.motion.problem import MotionProblem

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


class CartesianRequest(MotionRequest):
    """Body of ``POST /v1/cartesian``: P moves on straight segments from the start's P through
    each waypoint in turn, in the start's working and assembly mode (never changed), within
    ``path_tolerance`` of the polyline along the timed trajectory. Only ``start`` and
    ``waypoints`` are required."""

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
    timing: CartesianTimingOptions = Field(default_factory=CartesianTimingOptions)


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
@dataclass(frozen=True, slots=True)
class CartesianInputs:
    """A Cartesian request as the library's objects (each field's errors located): the
    :class:`~planner.motion.MotionProblem` and what :class:`planner.cartesian.StraightMotion`
    takes besides."""

    problem: MotionProblem
    waypoints: np.ndarray
    path_tolerance: float


def cartesian_inputs(
    request: CartesianRequest, *, deadline: float | None = None, max_samples: int | None = None
) -> CartesianInputs:
    """The library objects of a Cartesian request (a bad value raises the library's error,
    located at its field): its problem (:func:`planner.wire.motion_problem`), its waypoints
    and tolerance. A polyline longer than :data:`MAX_POLYLINE_REACHES` reaches (L1 + L2),
    from the start's P, is an :class:`~planner.exceptions.InputError` at ``waypoints``."""
    from planner.exceptions import InputError
    from planner.kinematics import forward_batch

    problem = motion_problem(request, deadline=deadline, max_samples=max_samples)
    design, start = problem.design, problem.start
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
    return CartesianInputs(problem, waypoints, float(request.path_tolerance))


def cartesian_response(
    result: CartesianResult, *, format: TrajectoryFormat = "arrays"
) -> CartesianResponse:
    """The answer of one straight path, built once from a
    :class:`planner.cartesian.plan.CartesianResult`."""
    d = result.diagnostics
    timed = result.trajectory is not None
    diagnostics = CartesianDiagnosticsModel(
        planning_time_s=d.planning_time_s,
        timing_time_s=d.timing_time_s if timed else None,
        timing_repairs=getattr(result.trajectory, "repairs", None) if timed else None,
        max_torque_ratio=getattr(result.trajectory, "max_torque_ratio", None) if timed else None,
        path_length=finite(d.path_length),
        min_clearance=finite(d.min_clearance),
        max_kappa_A=finite(d.max_kappa_A),
        min_serial_margin=finite(d.min_serial_margin),
        planner="cartesian",
        max_path_deviation=finite(d.max_path_deviation),
        chord_bound=finite(d.chord_bound),
        blend_deviation_bound=finite(d.blend_deviation_bound),
        cartesian_length=finite(d.cartesian_length),
        lead_in=lead_in_model(result.trajectory),
    )
    stop = result.stop
    return CartesianResponse(
        status=result.status.value,
        message=result.message,
        fraction=float(result.fraction),
        path=path_model(result.path) if result.path is not None else None,
        trajectory=(
            trajectory_model(result.trajectory, format) if result.trajectory is not None else None
        ),
        diagnostics=diagnostics,
        stop=None
        if stop is None
        else CartesianStop(
            rule=stop.rule,
            value=finite(stop.value),
            p=np.asarray(stop.p, dtype=float).tolist(),
            fraction=float(stop.fraction),
        ),
        working_mode=result.working_mode or None,
    )
