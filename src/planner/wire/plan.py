"""``POST /v1/plan`` and ``/v1/plan/batch``: planner options, the request, the path, its
diagnostics and the response.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from planner.wire.common import (
    _MAX_SAMPLES,
    MAX_BATCH_REQUESTS,
    AssemblyModeLabel,
    Goal,
    Vec3,
    WorkingModeLabel,
    _Request,
    _Response,
)
from planner.wire.diagnostics import DiagnosticsModel
from planner.wire.execution import lead_in_model

if TYPE_CHECKING:
    from planner.exceptions import TimingError
    from planner.motion.problem import MotionProblem
    from planner.planning.problem import CartesianTarget, JointPosture
    from planner.planning.result import PlanPath, PlanResult
    from planner.solver import Solution
    from planner.timing.trajectory import Trajectory
from planner.wire.execution import ReplaceModel, fill_start_from_replace
from planner.wire.motion import MotionRequest, PlannerOptions, finite, goal_to_core, motion_problem
from planner.wire.timing import (
    AnyTrajectory,
    TimingOptionsModel,
    TrajectoryFormat,
    timing_error,
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
    "SegmentModel",
    "TransitKind",
    "TransitModel",
    "path_model",
    "plan_inputs",
    "plan_response",
    "solution_response",
]


# ---------------------------------------------------------------------------- plan
class PlanRequest(MotionRequest):
    """Body of ``POST /v1/plan``. Only ``start`` and ``goal`` are required."""

    goal: Goal
    planner: PlannerOptions = Field(default_factory=PlannerOptions)
    timing: TimingOptionsModel = Field(default_factory=TimingOptionsModel)
    replace: ReplaceModel | None = Field(
        None,
        description="Replace a running trajectory mid-motion: the answer starts from its state "
        "at `at` (then `start` may be omitted) and its times are on its clock (docs/execution.md).",
    )

    @model_validator(mode="before")
    @classmethod
    def _start_from_replace(cls, data: Any) -> Any:
        return fill_start_from_replace(data)


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
@dataclass(frozen=True, slots=True)
class PlanInputs:
    """A plan request as the library's objects, converted once (each field's errors located
    at its place in the body): the :class:`~planner.motion.MotionProblem` and the goal with
    its options, what :class:`planner.solver.GoalMotion` takes."""

    problem: MotionProblem
    goal: JointPosture | CartesianTarget
    prefer: str = "shortest"
    tolerance: float = 0.0


def plan_inputs(
    request: PlanRequest, *, deadline: float | None = None, max_samples: int | None = None
) -> PlanInputs:
    """The library objects of a plan request (a bad value raises the library's error,
    located): its problem (:func:`planner.wire.motion_problem`, with the answer's
    ``deadline`` and sample bound ``max_samples``) and its goal."""
    problem = motion_problem(request, deadline=deadline, max_samples=max_samples)
    goal = goal_to_core(request.goal, ("body", "goal"))
    prefer = getattr(request.goal, "prefer", "shortest")
    return PlanInputs(problem, goal, prefer, request.goal.tolerance)


def path_model(path: PlanPath) -> PathModel:
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
    result: PlanResult,
    *,
    trajectory: Trajectory | None = None,
    timing_failure: TimingError | None = None,
    format: TrajectoryFormat = "arrays",
) -> PlanResponse:
    """The answer of one plan, built once: the :class:`planner.planning.PlanResult`, and the
    :class:`planner.timing.Trajectory` of its path (or the
    :class:`~planner.exceptions.TimingError` that stopped the timing: a passed deadline is
    status ``timeout``, any other timing failure ``no_path`` with the path kept and
    ``diagnostics.timing_error`` naming the failed rule), the trajectory in ``format``; a
    :class:`planner.Solution` hands over its three parts (:func:`solution_response`)."""
    from planner.exceptions import TimingDeadlineError

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
        timing["lead_in"] = lead_in_model(trajectory)
    diagnostics = DiagnosticsModel(
        planning_time_s=d.planning_time_s,
        path_length=finite(d.path_length),
        min_clearance=finite(d.min_clearance),
        max_kappa_A=finite(d.max_kappa_A),
        min_serial_margin=finite(d.min_serial_margin),
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


def solution_response(solution: Solution, *, format: TrajectoryFormat = "arrays") -> PlanResponse:
    """The answer of a :class:`planner.Solution` (:func:`planner.solve`'s, or
    :class:`planner.solver.GoalMotion`'s through the pipeline): :func:`plan_response` of its
    plan, trajectory and timing error."""
    return plan_response(
        solution.plan,
        trajectory=solution.trajectory,
        timing_failure=solution.timing_error,
        format=format,
    )
