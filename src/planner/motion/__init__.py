"""The motion problem and the one pipeline every kind of motion runs through.

:class:`MotionProblem` (:mod:`~planner.motion.problem`) holds what every kind shares, built
once; :func:`run` (:mod:`~planner.motion.pipeline`) runs validate -> plan -> time -> dense
check -> result for any :class:`Motion`. The kinds live in their own rooms and supply only
their planning step and their answer: a goal reached by a search (:class:`planner.solver.GoalMotion`),
a straight tool path (:class:`planner.cartesian.StraightMotion`), a task sequence
(:class:`planner.sequence.SequenceMotion`).
"""

from planner.motion.pipeline import (
    Motion,
    Planned,
    Timed,
    TimingRequest,
    path_timing,
    run,
    time_planned,
)
from planner.motion.problem import UNBOUNDED, Budget, MotionProblem

__all__ = [
    "UNBOUNDED",
    "Budget",
    "Motion",
    "MotionProblem",
    "Planned",
    "Timed",
    "TimingRequest",
    "path_timing",
    "run",
    "time_planned",
]
