"""Task sequences: one trajectory from a start through many targets (and back, for a cycle),
stopping at some and passing through the others, with the working modes chosen for the
shortest cycle.

:func:`plan_sequence` (:mod:`planner.sequence.solve`) answers a
:class:`~planner.motion.MotionProblem` and its targets through the motion pipeline
(:class:`SequenceMotion`); :func:`solve_sequence` is its keyword call, exported as
``planner.solve_sequence`` beside :func:`planner.solve`; its inputs and answer are the data
classes of :mod:`planner.sequence.problem` (light: the wire imports them alone), and the
working-mode search of ``objective="time"`` is :mod:`planner.sequence.mode_search`.
"""

from planner.sequence.motion import SequenceMotion
from planner.sequence.problem import (
    MAX_BELT_SPEED,
    MAX_SEQUENCE_TARGETS,
    OBJECTIVES,
    BlendUse,
    Leg,
    MovingTarget,
    SequenceDiagnostics,
    SequenceResult,
    SequenceTarget,
)
from planner.sequence.solve import plan_sequence, solve_sequence

__all__ = [
    "MAX_BELT_SPEED",
    "MAX_SEQUENCE_TARGETS",
    "OBJECTIVES",
    "BlendUse",
    "Leg",
    "MovingTarget",
    "SequenceDiagnostics",
    "SequenceMotion",
    "SequenceResult",
    "SequenceTarget",
    "plan_sequence",
    "solve_sequence",
]
