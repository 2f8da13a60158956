"""Plan results: statuses and fields of the wire vocabulary (``docs/conventions.md``, /v1/plan).

Pure data, no OMPL, no wire format: the response model is built from these by
:func:`planner.wire.plan_response`. One constructor is shared by every proof that no path
exists (:func:`proven_no_path`), so such an answer always carries the same diagnostics.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

__all__ = [
    "Diagnostics",
    "PlanPath",
    "PlanResult",
    "PlanStatus",
    "Segment",
    "Transit",
    "proven_no_path",
]

logger = logging.getLogger(__name__)


class PlanStatus(StrEnum):
    """Outcome of a plan request; the values are the wire statuses."""

    SOLVED = "solved"
    NO_PATH = "no_path"
    UNREACHABLE = "unreachable"
    INVALID_START = "invalid_start"
    INVALID_GOAL = "invalid_goal"
    TIMEOUT = "timeout"


@dataclass(frozen=True, slots=True)
class Segment:
    """Waypoints ``start_index..end_index`` (inclusive) lie in one working and assembly mode."""

    working_mode: str
    assembly_mode: str
    start_index: int
    end_index: int


@dataclass(frozen=True, slots=True)
class Transit:
    """A serial-singularity crossing at waypoint ``index`` (filled by mode-change plans)."""

    index: int
    q: tuple[float, float, float]
    kind: str
    flipped: str


@dataclass(frozen=True, slots=True)
class PlanPath:
    """``waypoints`` (N, 3) rad; motions between consecutive ones are straight in joint space."""

    waypoints: np.ndarray
    segments: tuple[Segment, ...] = ()
    transits: tuple[Transit, ...] = ()


@dataclass(frozen=True, slots=True)
class Diagnostics:
    """Measures of a plan. Extremes along the path are taken over waypoints and samples every
    ``planner.validity.DIAGNOSTIC_STEP`` (0.02 rad); NaN when there is no path.

    Attributes
    ----------
    planning_time_s : wall time of the whole request, s.
    path_length : sum of Euclidean joint-space distances between waypoints, rad.
    min_clearance : least link-obstacle distance, m (inf without obstacles).
    max_kappa_A : largest kappa(A).
    min_serial_margin : smallest serial measure (signed by the working mode).
    planner : name of the planner that found the path ('direct' for the straight motion;
        'region_map' when the region map proved that no path exists).
    attempts : number of goal candidates tried.
    searches : number of OMPL searches run (0: the straight motion or the region map
        answered).
    proven_infeasible : True only with ``no_path`` when the region map proved that no valid
        path exists (:func:`planner.analysis.regions.prove_disconnected`), not merely that the
        budget ran out.
    """

    planning_time_s: float
    path_length: float = float("nan")
    min_clearance: float = float("nan")
    max_kappa_A: float = float("nan")
    min_serial_margin: float = float("nan")
    planner: str = ""
    attempts: int = 0
    searches: int = 0
    proven_infeasible: bool = False


@dataclass(frozen=True, slots=True)
class PlanResult:
    """Result of :func:`planner.planning.plan`: ``status``, ``message`` (for invalid start or
    goal: the rule and the measured value), ``path`` (None unless solved), ``diagnostics``."""

    status: PlanStatus
    message: str
    path: PlanPath | None
    diagnostics: Diagnostics = field(default_factory=lambda: Diagnostics(float("nan")))

    @property
    def solved(self) -> bool:
        return self.status is PlanStatus.SOLVED


def proven_no_path(message: str, t0: float) -> PlanResult:
    """``no_path`` with ``diagnostics.proven_infeasible``: the answer of a proof that no valid
    path exists (the region map's, with or without obstacles, for the goal candidates or a
    whole tolerance ball; :mod:`planner.planning.proofs`, :mod:`planner.planning.tolerance`).
    ``message`` says which proof and why; ``planning_time_s`` runs from ``t0`` (a
    :func:`time.monotonic` value, the request's start); ``planner`` is 'region_map'.
    Logged once here, at info level."""
    logger.info("plan no_path (proven): %s", message)
    return PlanResult(
        PlanStatus.NO_PATH,
        message,
        None,
        Diagnostics(
            planning_time_s=time.monotonic() - t0, planner="region_map", proven_infeasible=True
        ),
    )
