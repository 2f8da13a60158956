"""``POST /v1/sequence``: a start, an ordered list of targets (each a stop or passed through
within a blend), optionally back to the start; one trajectory through all of them, its legs
with their time spans, and the cycle time (names: CONVENTIONS "Wire, third part")."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import Field, model_validator

from planner.constants import MAX_SEQUENCE_TARGETS
from planner.wire.common import (
    Goal,
    _Request,
    _Response,
    located,
)
from planner.wire.diagnostics import DiagnosticsModel
from planner.wire.execution import ReplaceModel, fill_start_from_replace, lead_in_model
from planner.wire.motion import MotionRequest, PlannerOptions, finite, goal_to_core, motion_problem
from planner.wire.plan import (
    PathModel,
    PlanStatus,
    path_model,
)
from planner.wire.timing import (
    AnyTrajectory,
    TimingOptionsModel,
    TrajectoryFormat,
    timing_error,
    trajectory_model,
)

if TYPE_CHECKING:
    from planner.motion.problem import MotionProblem
    from planner.sequence.problem import SequenceResult, SequenceTarget

__all__ = [
    "MAX_SEQUENCE_TARGETS",
    "BlendModel",
    "LegModel",
    "Objective",
    "SequenceDiagnosticsModel",
    "SequenceInputs",
    "SequenceRequest",
    "SequenceResponse",
    "SequenceTargetModel",
    "sequence_inputs",
    "sequence_response",
]

#: Longest ``dwell`` on a moving target, s (a part tracked longer leaves the workspace).
MAX_DWELL_S = 60.0
#: ``"time"`` (default): each Cartesian "any" target's working mode chosen for the shortest
#: cycle; ``"fixed"``: each as given ("any" = the single plan's rule).
Objective = Literal["time", "fixed"]


class SequenceTargetModel(_Request):
    """One target of a sequence."""

    goal: Goal = Field(description="A joint posture or a Cartesian target.")
    stop: bool = Field(True, description="At rest there (default); false: passed at speed.")
    blend: Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=math.pi)] = Field(
        0.0,
        description="When passing through: the largest joint-space distance (rad) of the "
        "trajectory from the target's posture; 0 (default): exactly through it. A blend "
        "larger than half the shorter adjacent leg shrinks to that (diagnostics.blends).",
    )
    blend_radius: Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=10.0)] | None = Field(
        None,
        description="When passing through: the largest distance (m) of the tool point P from "
        "the target's point (MoveIt Pilz's blend_radius); instead of blend, not with it. "
        "Shrinks to fit as blend does.",
    )
    dwell: Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=MAX_DWELL_S)] = Field(
        0.0,
        description="A moving target's (goal with velocity): how long the tool moves with the "
        "part once it has met it, s (the gripper closes); 0 for any other target.",
    )


class SequenceRequest(MotionRequest):
    """Body of ``POST /v1/sequence``. Only ``start`` and ``targets`` are required."""

    targets: list[SequenceTargetModel] = Field(
        min_length=1,
        max_length=MAX_SEQUENCE_TARGETS,
        description=f"In order, 1 to {MAX_SEQUENCE_TARGETS} (the service may allow fewer: "
        "PLANNER_MAX_SEQUENCE_TARGETS).",
    )
    cycle: bool = Field(False, description="Return to the start at the end.")
    objective: Objective = Field(
        "time",
        description="'time' (default): choose each Cartesian 'any' target's working mode for "
        "the shortest whole trajectory; 'fixed': each target as given.",
    )
    planner: PlannerOptions = Field(
        default_factory=PlannerOptions, description="Search options of every leg."
    )
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


class LegModel(_Response):
    """One leg: the plan to target ``target_index`` (``len(targets)``: a cycle's return)."""

    target_index: int = Field(ge=0)
    status: PlanStatus = Field(description="The leg's plan status.")
    path: PathModel | None = Field(None, description="The leg's path as planned.")
    working_mode: str = Field("", description="Working mode at arrival ('' if not planned).")
    start_time: float | None = Field(None, description="Leaves the previous target, s.")
    end_time: float | None = Field(
        None, description="Reaches the target (at rest for a stop; closest approach else), s."
    )
    pass_distance: float | None = Field(
        None, description="Joint-space distance from the target's posture at end_time, rad."
    )
    pass_speed: float | None = Field(None, description="Joint speed at end_time, rad/s.")
    transit_times: list[float] = Field(
        default_factory=list,
        description="When the trajectory crosses each working-mode transit of the leg "
        "(path.transits, in order; /v1/plan's shape), s; empty when not timed.",
    )
    meet_time: float | None = Field(
        None, description="A moving target's: when the tool meets the part, s (else null)."
    )
    meet_point: list[float] | None = Field(
        None, description="A moving target's: where the tool meets the part, m (else null)."
    )


class BlendModel(_Response):
    """One passed target's blend: as asked and as used, in the unit it was asked in ("m":
    blend_radius, "rad": blend)."""

    target_index: int = Field(ge=0)
    asked: float
    used: float
    unit: Literal["m", "rad"]


class SequenceDiagnosticsModel(DiagnosticsModel):
    """The plan diagnostics over the whole sequence (extremes over every leg), and the mode
    search's."""

    modes: list[str] = Field(
        default_factory=list, description="Working mode at each target ('' for a joint goal)."
    )
    runner_up_modes: list[str] | None = Field(
        None, description="The second best assignment of the mode search (objective 'time')."
    )
    runner_up_cycle_time: float | None = Field(None, description="Its cycle time, s.")
    assignments_evaluated: int = Field(
        0, ge=0, description="Mode assignments planned and timed by the search."
    )
    optimality_gap_s: float | None = Field(
        None,
        description="What the mode search proves: no other assignment of working modes, "
        "planned and timed, is more than this much shorter, s (0: the choice is proven the "
        "best; null when it proves none, e.g. without timing).",
    )
    stopped_targets: list[int] = Field(
        default_factory=list,
        description="Pass-through targets where the timing had to come to rest.",
    )
    blends: list[BlendModel] = Field(
        default_factory=list,
        description="Each passed target's blend, asked and used (after shrinking to fit).",
    )


class SequenceResponse(_Response):
    """Answer of ``POST /v1/sequence``: ``solved`` only when every leg is."""

    status: PlanStatus
    message: str = ""
    legs: list[LegModel] = Field(default_factory=list)
    trajectory: AnyTrajectory | None = None
    cycle_time: float | None = Field(None, description="Duration of the trajectory, s.")
    diagnostics: SequenceDiagnosticsModel = Field(default_factory=SequenceDiagnosticsModel)


# ---------------------------------------------------------------------------- conversions
@dataclass(frozen=True, slots=True)
class SequenceInputs:
    """A sequence request as the library's objects: the
    :class:`~planner.motion.MotionProblem` and what :func:`planner.sequence.plan_sequence`
    takes besides."""

    problem: MotionProblem
    targets: list[SequenceTarget]
    cycle: bool
    objective: str


def sequence_inputs(
    request: SequenceRequest, *, deadline: float | None = None, max_samples: int | None = None
) -> SequenceInputs:
    """The library objects of a sequence request (a bad value raises the library's error,
    located at its field): its problem (:func:`planner.wire.motion_problem`) and targets. A
    target's goal takes no ``tolerance`` nor ``prefer``: a sequence reaches each target
    exactly, and chooses the modes by its ``objective``."""
    from planner.sequence.problem import SequenceTarget

    problem = motion_problem(request, deadline=deadline, max_samples=max_samples)
    targets = []
    for i, t in enumerate(request.targets):
        g = t.goal
        loc = ("body", "targets", i, "goal")
        if g.tolerance != 0.0:
            _refuse((*loc, "tolerance"), "a sequence target takes no tolerance (0)")
        if getattr(g, "prefer", "shortest") != "shortest":
            _refuse((*loc, "prefer"), "a sequence chooses the modes by its objective")
        goal = _moving_goal(g, loc) if getattr(g, "velocity", None) is not None else None
        if goal is None:
            goal = goal_to_core(g, loc)
        with located("body", "targets", i):
            if t.blend_radius is not None and "blend" in t.model_fields_set:
                _refuse(
                    ("body", "targets", i, "blend_radius"),
                    "give blend (rad) or blend_radius (m), not both",
                )
            targets.append(SequenceTarget(goal, t.stop, t.blend, t.blend_radius, t.dwell))
    return SequenceInputs(problem, targets, request.cycle, request.objective)


def _moving_goal(model: Any, loc: tuple) -> Any:
    """A goal with a ``velocity``: the library's :class:`~planner.sequence.problem.
    MovingTarget` (a belt faster than its bound: 422 at ``goal.velocity``)."""
    from planner.sequence.problem import MovingTarget

    with located(*loc):
        return MovingTarget(
            np.array(model.p),
            model.working_mode,
            np.array(model.velocity),
            0.0 if model.t0 is None else model.t0,
        )


def _refuse(loc: tuple, message: str) -> None:
    from planner.exceptions import InputError

    with located(*loc):
        raise InputError(message)


def _extreme(values: list[float], fn) -> float | None:
    kept = [v for v in values if v is not None and np.isfinite(v)]
    return finite(fn(kept)) if kept else None


def sequence_response(
    result: SequenceResult, *, format: TrajectoryFormat = "arrays"
) -> SequenceResponse:
    """The answer of a :class:`planner.sequence.SequenceResult`, built once: its legs (each
    leg's path as planned), the one trajectory in ``format``, the cycle time, the plans'
    extremes over every leg and the mode search's diagnostics (a timing failure: ``no_path``
    with ``diagnostics.timing_error``, or ``timeout``)."""
    legs = [
        LegModel(
            target_index=leg.target_index,
            status=leg.plan.status.value,
            path=path_model(leg.plan.path) if leg.plan.path is not None else None,
            working_mode=leg.working_mode,
            start_time=finite(leg.start_time),
            end_time=finite(leg.end_time),
            pass_distance=finite(leg.pass_distance),
            pass_speed=finite(leg.pass_speed),
            transit_times=[float(t) for t in leg.transit_times],
            meet_time=finite(leg.meet_time),
            meet_point=None if leg.meet_point is None else [float(x) for x in leg.meet_point],
        )
        for leg in result.legs
    ]
    d = result.diagnostics
    plans = [leg.plan.diagnostics for leg in result.legs]
    traj = result.trajectory
    extra: dict[str, Any] = {}
    if result.timing_error is not None:
        from planner.exceptions import TimingDeadlineError

        if not isinstance(result.timing_error, TimingDeadlineError):
            extra["timing_error"] = timing_error(result.timing_error)
    elif traj is not None:
        extra["timing_time_s"] = d.timing_time_s
        extra["timing_repairs"] = traj.repairs
        extra["max_torque_ratio"] = getattr(traj, "max_torque_ratio", None)
        extra["lead_in"] = lead_in_model(traj)
    runner = d.runner_up
    diagnostics = SequenceDiagnosticsModel(
        planning_time_s=d.planning_time_s,
        path_length=_extreme([p.path_length for p in plans], sum),
        min_clearance=_extreme([p.min_clearance for p in plans], min),
        max_kappa_A=_extreme([p.max_kappa_A for p in plans], max),
        min_serial_margin=_extreme([p.min_serial_margin for p in plans], min),
        planner=",".join(sorted({p.planner for p in plans if p.planner})) or None,
        modes=list(d.modes),
        runner_up_modes=list(runner[0]) if runner is not None else None,
        runner_up_cycle_time=finite(runner[1]) if runner is not None else None,
        assignments_evaluated=d.estimates,
        optimality_gap_s=finite(d.extra.get("gap_s")) if "gap_s" in d.extra else None,
        stopped_targets=list(d.stopped_targets),
        blends=[
            BlendModel(target_index=b.target_index, asked=b.asked, used=b.used, unit=b.unit)
            for b in d.blends
        ],
        **extra,
    )
    return SequenceResponse(
        status=result.status.value,
        message=result.message,
        legs=legs,
        trajectory=trajectory_model(traj, format) if traj is not None else None,
        cycle_time=finite(result.cycle_time),
        diagnostics=diagnostics,
    )
