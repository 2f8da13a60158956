"""Joint-space planning with OMPL (the only package importing OMPL): single-mode segments
and working-mode changes through serial-singularity transits.

The one entry point: :func:`plan` (``plan(design, start, goal, *, obstacles, margins,
options)``, from :mod:`planner.planning.dispatch`), returning a :class:`PlanResult` whose
statuses and fields are the wire vocabulary's. It plans in the start's working mode first
(:func:`plan_single_mode`, for callers that must not change mode) and through transits when
the goal needs another mode.
:func:`plan_with_goal_options` is the same call with MoveIt-like goal options on top (a goal
tolerance, and the working mode preferred for a Cartesian "any" goal); it calls :func:`plan`.
With obstacles, :mod:`planner.planning.corridor` (a coarse 3-D grid of a mode's valid set)
guides the search through narrow passages (``PlanOptions.corridor``).
"""

from planner.planning.dispatch import plan
from planner.planning.goal_options import plan_with_goal_options
from planner.planning.mode_graph import mode_sequences
from planner.planning.path_rules import path_state_checker
from planner.planning.problem import PLANNERS, CartesianTarget, JointPosture, PlanOptions
from planner.planning.result import (
    Diagnostics,
    PlanPath,
    PlanResult,
    PlanStatus,
    Segment,
    Transit,
)
from planner.planning.single_mode import (
    goal_candidates,
    plan_in_region,
    plan_single_mode,
    posture_mode,
)

__all__ = [
    "PLANNERS",
    "CartesianTarget",
    "Diagnostics",
    "JointPosture",
    "PlanOptions",
    "PlanPath",
    "PlanResult",
    "PlanStatus",
    "Segment",
    "Transit",
    "goal_candidates",
    "mode_sequences",
    "path_state_checker",
    "plan",
    "plan_in_region",
    "plan_single_mode",
    "plan_with_goal_options",
    "posture_mode",
]
