"""What every motion request shares, and its one conversion into the library's
:class:`planner.motion.MotionProblem`.

``POST /v1/plan``, ``/v1/sequence`` and ``/v1/cartesian`` all describe a robot, a start, a
scene, margins, limits and gravity: :class:`MotionRequest` holds those fields once (each
request model adds its own: a goal, targets, waypoints, and its ``planner`` and ``timing``),
and :func:`motion_problem` converts them once, every error located at its field. The
start, a goal and a number that may be infinite are converted here too
(:func:`posture_to_core`, :func:`goal_to_core`, :func:`finite`), the one way for every model.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Annotated, Any

from pydantic import Field, PrivateAttr, field_validator

from planner.constants import PLANNERS, PlannerName
from planner.wire.common import (
    GRAVITY_FIELD,
    MAX_OBSTACLES,
    CartesianTargetModel,
    DesignModel,
    Gravity,
    Integer,
    JointPostureModel,
    MarginsModel,
    Obstacle,
    _DesignField,
    _Request,
    design_to_core,
    inertia_to_core,
    located,
    margins_to_core,
    triple_to_core,
)
from planner.wire.execution import StartPostureModel
from planner.wire.scenes import SceneName, scene_obstacles
from planner.wire.timing import Limits, joint_limits_to_core, timing_to_core

if TYPE_CHECKING:
    from planner.motion.problem import MotionProblem
    from planner.planning.problem import CartesianTarget, JointPosture, PlanOptions
    from planner.wire.cartesian import CartesianRequest
    from planner.wire.plan import PlanRequest
    from planner.wire.sequence import SequenceRequest

__all__ = [
    "MotionRequest",
    "PlannerOptions",
    "finite",
    "goal_to_core",
    "motion_problem",
    "planner_options_to_core",
    "posture_to_core",
]

Location = tuple[str | int, ...]


class PlannerOptions(_Request):
    """Search options of a plan."""

    name: PlannerName = Field(
        "rrtconnect",
        description="Planner (case-insensitive): " + ", ".join(PLANNERS) + "; default rrtconnect.",
    )
    time_budget_s: Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=600.0)] = Field(
        1.0, description="Search budget, s (at most the service's request budget)."
    )
    seed: Annotated[Integer, Field(ge=1, le=2**31 - 1)] | None = Field(
        None,
        description="Seed of the planner's random numbers, >= 1 (reproducible results); "
        "absent: the planner's default seed.",
    )
    simplify: bool = Field(
        True, description="Shorten the path (shortcuts; every motion certified)."
    )
    stop_at_transits: bool = Field(
        False,
        description="Come to rest at each working-mode transit (the timed trajectory stops "
        "on the serial-singularity posture); default: pass it at speed.",
    )

    @field_validator("name", mode="before")
    @classmethod
    def _lower(cls, value: Any) -> Any:
        return value.lower() if isinstance(value, str) else value


class MotionRequest(_Request):
    """The fields of every motion request (a plan, a sequence, a straight path)."""

    design: DesignModel = _DesignField
    start: StartPostureModel
    obstacles: list[Obstacle] = Field(default_factory=list, max_length=MAX_OBSTACLES)
    scene: SceneName | None = Field(
        None,
        description="A stored scene's name (PUT /v1/scenes/{name}): its obstacles join "
        "`obstacles`, its design is the robot when `design` is absent; unknown: 422.",
    )
    #: the named scene's library obstacles, set by the service (:func:`with_scene`)
    _scene_obstacles: tuple[Any, ...] | None = PrivateAttr(None)
    margins: MarginsModel = Field(default_factory=MarginsModel)
    limits: Limits = Field(default_factory=Limits)
    gravity: Gravity = GRAVITY_FIELD


def finite(x: float | None) -> float | None:
    """``x`` as a float, or None when it is None, infinite or NaN (JSON has no infinities):
    how an answer reports a measure that does not exist (no obstacle: no clearance)."""
    return float(x) if x is not None and math.isfinite(x) else None


def posture_to_core(model: JointPostureModel, loc: Location) -> JointPosture:
    """The library's :class:`~planner.planning.JointPosture` of a posture model (a start, a
    joint goal), its error located at ``loc``."""
    import numpy as np

    from planner.planning.problem import JointPosture

    with located(*loc):
        return JointPosture(np.array(model.q), model.assembly_mode)


def goal_to_core(
    model: JointPostureModel | CartesianTargetModel, loc: Location
) -> JointPosture | CartesianTarget:
    """A goal model (a joint posture, or a Cartesian target with its working mode) as the
    library's goal, its error located at ``loc``."""
    import numpy as np

    from planner.planning.problem import CartesianTarget

    if isinstance(model, JointPostureModel):
        return posture_to_core(model, loc)
    for name in ("velocity", "t0"):
        if getattr(model, name, None) is not None:
            from planner.exceptions import InputError

            with located(*loc, name):
                raise InputError(
                    "a moving target (velocity, t0) is accepted only among a sequence's "
                    "targets (/v1/sequence)"
                )
    with located(*loc):
        return CartesianTarget(np.array(model.p), model.working_mode)


def motion_problem(
    request: PlanRequest | SequenceRequest | CartesianRequest,
    *,
    deadline: float | None = None,
    max_samples: int | None = None,
) -> MotionProblem:
    """The request's :class:`~planner.motion.MotionProblem`, converted once: design, start,
    the scene's and the request's obstacles, margins, the search options of its ``planner``
    (where it has one), its ``timing`` with ``limits.cartesian_speed`` and the answer's
    sample bound ``max_samples``, the limits, the inertia of its design, gravity, the
    budget ending at ``deadline`` (a :func:`time.monotonic` value), and the start's
    velocity and acceleration; with ``replace``, the start is the running state at
    ``replace.at`` exactly (:func:`planner.wire.execution.replace_start`)."""
    from dataclasses import replace

    from planner.motion.problem import Budget, MotionProblem
    from planner.planning.problem import JointPosture, PlanOptions
    from planner.wire.execution import replace_start

    design = design_to_core(request.design)
    start = posture_to_core(request.start, ("body", "start"))
    qd, qdd = triple_to_core(request.start.qd), triple_to_core(request.start.qdd)
    running = replace_start(request)
    if running is not None:  # the running state at replace.at, exactly
        _, q, qd_at, qdd_at = running
        start = JointPosture(q, request.start.assembly_mode)
        qd, qdd = triple_to_core(qd_at), triple_to_core(qdd_at)
    obstacles = tuple(scene_obstacles(request))
    planner = getattr(request, "planner", None)
    options = PlanOptions() if planner is None else planner_options_to_core(planner)
    timing = timing_to_core(request.timing, request.limits)
    with located("body"):
        return MotionProblem(
            design,
            start,
            obstacles,
            margins_to_core(request.margins),
            options,
            replace(timing, max_samples=max_samples),
            joint_limits_to_core(request.limits),
            inertia_to_core(request.design),
            triple_to_core(request.gravity),
            Budget(deadline),
            qd,
            qdd,
        )


def planner_options_to_core(
    model: PlannerOptions, loc: tuple[str | int, ...] = ("body", "planner")
) -> PlanOptions:
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
