"""``POST /v1/plan`` and ``/v1/plan/batch``: planner options, the request, the path, its
diagnostics and the response.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    Field,
    PrivateAttr,
    field_validator,
)
from pydantic_core import PydanticCustomError

from planner.design import Design
from planner.wire.common import (
    _MAX_SAMPLES,
    GRAVITY_FIELD,
    MAX_BATCH_REQUESTS,
    MAX_OBSTACLES,
    AssemblyModeLabel,
    DesignModel,
    DiagnosticsModel,
    Goal,
    Gravity,
    Integer,
    JointPostureModel,
    MarginsModel,
    Obstacle,
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
from planner.wire.scenes import SceneName, scene_obstacles
from planner.wire.timing import (
    AnyTrajectory,
    Limits,
    TimingOptionsModel,
    TrajectoryFormat,
    joint_limits_to_core,
    timing_error,
    timing_to_core,
    trajectory_model,
)

__all__ = [
    "PathModel",
    "PlanBatchRequest",
    "PlanBatchResponse",
    "PlanInputs",
    "PlanRequest",
    "PlanResponse",
    "PlanStatus",
    "PlannerOptions",
    "SegmentModel",
    "TransitKind",
    "TransitModel",
    "path_model",
    "plan_inputs",
    "plan_response",
    "planner_options_to_core",
]


class PlannerOptions(_Request):
    """Search options of a plan."""

    name: str = Field(
        "rrtconnect",
        pattern=r"^[A-Za-z][A-Za-z0-9_]{0,31}$",
        description="Planner (case-insensitive): rrtconnect (default), rrt, rrtstar, prmstar, "
        "bitstar, aorrtc, lbkpiece.",
    )
    time_budget_s: Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=600.0)] = Field(
        1.0, description="Search budget, s (at most the service's request budget)."
    )
    seed: Annotated[Integer, Field(ge=1, le=2**31 - 1)] | None = Field(
        None,
        description="Seed of the planner's random numbers, >= 1 (reproducible results); "
        "absent: the planner's default seed.",
    )
    simplify: bool = Field(True, description="Shorten and smooth the path (OMPL simplifier).")
    stop_at_transits: bool = Field(
        False,
        description="Come to rest at each working-mode transit (the timed trajectory stops "
        "on the serial-singularity posture); default: pass it at speed.",
    )

    @field_validator("name")
    @classmethod
    def _lower(cls, value: str) -> str:
        return value.lower()


# ---------------------------------------------------------------------------- plan
class PlanRequest(_Request):
    """Body of ``POST /v1/plan``. Only ``start`` and ``goal`` are required."""

    design: DesignModel = _DesignField
    start: JointPostureModel
    goal: Goal
    obstacles: list[Obstacle] = Field(default_factory=list, max_length=MAX_OBSTACLES)
    scene: SceneName | None = Field(
        None,
        description="A stored scene's name (PUT /v1/scenes/{name}): its obstacles join "
        "`obstacles`, its design is the robot when `design` is absent; unknown: 422.",
    )
    #: the named scene's library obstacles, set by the service (:func:`with_scene`)
    _scene_obstacles: tuple[Any, ...] | None = PrivateAttr(None)
    margins: MarginsModel = Field(default_factory=MarginsModel)
    planner: PlannerOptions = Field(default_factory=PlannerOptions)
    timing: TimingOptionsModel = Field(default_factory=TimingOptionsModel)
    limits: Limits = Field(default_factory=Limits)
    gravity: Gravity = GRAVITY_FIELD


PlanStatus = Literal["solved", "no_path", "unreachable", "invalid_start", "invalid_goal", "timeout"]
TransitKind = Literal[
    "P_on_axis", "leg_A_stretched", "leg_A_folded", "leg_B_stretched", "leg_B_folded"
]


class SegmentModel(_Response):
    """A run of waypoints in one working and assembly mode; indices inclusive."""

    working_mode: WorkingModeLabel
    assembly_mode: AssemblyModeLabel
    start_index: int = Field(ge=0)
    end_index: int = Field(ge=0)


class TransitModel(_Response):
    """A serial-singularity posture where exactly one working-mode sign flips."""

    index: int = Field(ge=0)
    q: Vec3
    kind: TransitKind
    flipped: Literal["axis", "A", "B"]


class PathModel(_Response):
    """The planned joint path: waypoints (N x 3, rad), its segments and transits."""

    waypoints: Annotated[list[Vec3], Field(max_length=_MAX_SAMPLES)]
    segments: list[SegmentModel] = Field(default_factory=list)
    transits: list[TransitModel] = Field(default_factory=list)


class PlanResponse(_Response):
    """Answer of ``POST /v1/plan``: a finished search is a 200 with one of the statuses."""

    status: PlanStatus
    message: str = ""
    path: PathModel | None = None
    trajectory: AnyTrajectory | None = None
    diagnostics: DiagnosticsModel = Field(default_factory=DiagnosticsModel)


class PlanBatchRequest(_Request):
    """Body of ``POST /v1/plan/batch``."""

    requests: list[PlanRequest] = Field(min_length=1, max_length=MAX_BATCH_REQUESTS)

    @field_validator("requests", mode="before")
    @classmethod
    def _count_first(cls, value: Any) -> Any:
        # the count is checked on the raw list, before its items are validated one by one
        if isinstance(value, list) and len(value) > MAX_BATCH_REQUESTS:
            raise PydanticCustomError(
                "too_long",
                "at most {limit} requests per batch, got {count}",
                {"limit": MAX_BATCH_REQUESTS, "count": len(value)},
            )
        return value


class PlanBatchResponse(_Response):
    """Answer of ``POST /v1/plan/batch``: one response per request, in the same order."""

    results: list[PlanResponse]


# ---------------------------------------------------------------------------- conversions
@dataclass(frozen=True)
class PlanInputs:
    """A plan request as the library's objects, converted once (each field's errors located
    at its place in the body): the arguments of :func:`planner.solve` (those of
    :func:`planner.planning.plan`, the goal options ``prefer`` and ``tolerance``, the
    :class:`planner.timing.TimingOptions` and :class:`planner.timing.JointLimits`)."""

    design: Design
    start: Any
    goal: Any
    obstacles: list[Any]
    margins: Any
    options: Any
    timing: Any
    limits: Any
    prefer: str = "shortest"
    tolerance: float = 0.0
    inertia: Any = None
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)

    def solve_kwargs(self) -> dict[str, Any]:
        """The keyword arguments of :func:`planner.solve` after ``design, start, goal``."""
        return {
            "obstacles": self.obstacles,
            "margins": self.margins,
            "options": self.options,
            "timing": self.timing,
            "limits": self.limits,
            "prefer": self.prefer,
            "tolerance": self.tolerance,
            "inertia": self.inertia,
            "gravity": self.gravity,
        }


def plan_inputs(request: PlanRequest) -> PlanInputs:
    """The library objects of a plan request: design, start, goal, obstacles, margins and
    :class:`planner.planning.PlanOptions` (a bad value raises the library's error, located)."""
    from planner.planning.problem import CartesianTarget as CoreTarget
    from planner.planning.problem import JointPosture as CorePosture

    design = design_to_core(request.design)
    with located("body", "start"):
        start = CorePosture(np.array(request.start.q), request.start.assembly_mode)
    with located("body", "goal"):
        g = request.goal
        goal = (
            CorePosture(np.array(g.q), g.assembly_mode)
            if isinstance(g, JointPostureModel)
            else CoreTarget(np.array(g.p), g.working_mode)
        )
    obstacles = scene_obstacles(request)
    margins = margins_to_core(request.margins)
    options = planner_options_to_core(request.planner)
    timing = timing_to_core(request.timing, request.limits)
    limits = joint_limits_to_core(request.limits)
    prefer = getattr(request.goal, "prefer", "shortest")
    inertia = inertia_to_core(request.design)
    return PlanInputs(
        design,
        start,
        goal,
        obstacles,
        margins,
        options,
        timing,
        limits,
        prefer,
        request.goal.tolerance,
        inertia,
        tuple(request.gravity),  # type: ignore[arg-type]
    )


def planner_options_to_core(
    model: PlannerOptions, loc: tuple[str | int, ...] = ("body", "planner")
) -> Any:
    """The :class:`planner.planning.PlanOptions` of a request's ``planner`` field (a plan's,
    or every leg's of a sequence)."""
    from planner.planning.problem import PlanOptions

    with located(*loc):
        return PlanOptions(
            **model.model_dump(
                exclude_none=True,
                include={"name", "time_budget_s", "seed", "simplify", "stop_at_transits"},
            )
        )


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def path_model(path: Any) -> PathModel:
    """The wire form of a :class:`planner.planning.PlanPath`."""
    return PathModel(
        waypoints=np.asarray(path.waypoints, dtype=float).tolist(),
        segments=[
            SegmentModel(
                working_mode=s.working_mode,
                assembly_mode=s.assembly_mode,
                start_index=s.start_index,
                end_index=s.end_index,
            )
            for s in path.segments
        ],
        transits=[
            TransitModel(index=t.index, q=list(t.q), kind=t.kind, flipped=t.flipped)
            for t in path.transits
        ],
    )


def plan_response(
    result: Any,
    *,
    trajectory: Any = None,
    timing_failure: Exception | None = None,
    format: TrajectoryFormat = "arrays",
) -> PlanResponse:
    """The answer of one plan, built once: the :class:`planner.planning.PlanResult`, and the
    :class:`planner.timing.Trajectory` of its path (or the
    :class:`~planner.exceptions.TimingError` that stopped the timing: a passed deadline is
    status ``timeout``, any other timing failure ``no_path`` with the path kept and
    ``diagnostics.timing_error`` naming the failed rule), the trajectory in ``format``.
    ``result`` may be a :class:`planner.Solution` (:func:`planner.solve`'s answer), which
    carries all three."""
    from planner.exceptions import TimingDeadlineError

    if hasattr(result, "plan"):  # a Solution: the plan, its trajectory or timing error
        result, trajectory, timing_failure = result.plan, result.trajectory, result.timing_error

    d = result.diagnostics
    status, message = result.status.value, result.message
    timing: dict[str, Any] = {}
    if isinstance(timing_failure, TimingDeadlineError):
        status = "timeout"
        message = f"the path was found but timing ran out of time: {timing_failure}"
    elif timing_failure is not None:  # no profile, or the dense re-check failed after repairs
        status = "no_path"
        message = f"the path was found but could not be timed: {timing_failure}"
        timing["timing_error"] = timing_error(timing_failure)
    elif trajectory is not None:
        timing["timing_time_s"] = trajectory.computation_time_s
        timing["timing_repairs"] = trajectory.repairs
        timing["max_torque_ratio"] = getattr(trajectory, "max_torque_ratio", None)
    diagnostics = DiagnosticsModel(
        planning_time_s=d.planning_time_s,
        path_length=_finite(d.path_length),
        min_clearance=_finite(d.min_clearance),
        max_kappa_A=_finite(d.max_kappa_A),
        min_serial_margin=_finite(d.min_serial_margin),
        planner=d.planner,
        proven_infeasible=d.proven_infeasible and status == "no_path",
        **timing,
    )
    return PlanResponse(
        status=status,
        message=message,
        path=path_model(result.path) if result.path is not None else None,
        trajectory=trajectory_model(trajectory, format) if trajectory is not None else None,
        diagnostics=diagnostics,
    )
