"""Joint-space planning with OMPL inside one working mode (the only package importing OMPL).

Entry point: :func:`plan` (``plan(design, start, goal, *, obstacles, margins, options)``),
returning a :class:`PlanResult` whose statuses and fields are the wire vocabulary's.
"""

from planner.planning.planner import goal_candidates, plan, plan_in_region, posture_mode
from planner.planning.problem import PLANNERS, CartesianTarget, JointPosture, PlanOptions
from planner.planning.result import (
    Diagnostics,
    PlanPath,
    PlanResult,
    PlanStatus,
    Segment,
    Transit,
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
    "plan",
    "plan_in_region",
    "posture_mode",
]
