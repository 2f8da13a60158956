"""The outcomes of the validity checks: :class:`StateReport` (postures),
:class:`MotionReport` (one straight motion) and :class:`PathReport` (a waypoint path).

Plain frozen records that :class:`planner.validity.ValidityChecker` returns; their ``reason``
fields are rule names of :data:`planner.validity.REASONS`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MotionReport", "PathReport", "StateReport"]


@dataclass(frozen=True, slots=True)
class StateReport:
    """Validity and measures of N postures (arrays of shape (N,)).

    Attributes
    ----------
    valid : bool
    reason : str (object array), the first broken rule (see :data:`REASONS`), 'valid' if none.
    kappa_A : kappa(A) (inf at C = D or CD stretched, NaN where the loop does not close).
    serial_margin : the smallest serial measure, signed by the segment's working mode
        (negative: another working mode), NaN where the loop does not close.
    clearance : least distance link capsule - obstacle, m (inf without obstacles; negative
        when a link enters an obstacle), NaN where the loop does not close.
    """

    valid: np.ndarray
    reason: np.ndarray
    kappa_A: np.ndarray
    serial_margin: np.ndarray
    clearance: np.ndarray


@dataclass(frozen=True, slots=True)
class MotionReport:
    """Outcome of one certified straight motion: ``valid``; else ``reason`` (a rule of
    :data:`REASONS`) and ``t`` in [0, 1], where along the motion it was found."""

    valid: bool
    reason: str
    t: float


@dataclass(frozen=True, slots=True)
class PathReport:
    """Outcome of a certified waypoint path and measures sampled along it.

    ``valid``; ``bad_motion`` (index i of the first invalid motion i -> i+1, 0 for an invalid
    single posture, or -1), ``reason`` and ``t``; ``min_clearance``, ``max_kappa_A``,
    ``min_serial_margin``: extremes over the waypoints and samples every ``sample_step`` rad
    (max-norm) along the path (the certificate guarantees the margins hold in between);
    ``length``: sum of Euclidean joint distances, rad.
    """

    valid: bool
    bad_motion: int
    reason: str
    t: float
    min_clearance: float
    max_kappa_A: float
    min_serial_margin: float
    length: float
