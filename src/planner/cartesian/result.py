"""Results of a straight tool path (:func:`planner.cartesian.plan.plan_cartesian`): the
answer, where and why it stops short, the surfaces the polyline meets, and its measures.

Pure data, like :mod:`planner.planning.result` (whose statuses and plan diagnostics these
reuse); the wire's response is built from them by :func:`planner.wire.cartesian_response`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from planner.planning.result import PlanPath, PlanStatus

if TYPE_CHECKING:
    from planner.timing.trajectory import Trajectory

__all__ = ["CartesianDiagnostics", "CartesianResult", "PathEvent", "StopPoint"]


@dataclass(frozen=True, slots=True)
class StopPoint:
    """Where and why a Cartesian path stops short.

    Attributes
    ----------
    rule : str
        ``joint_limits``, ``assembly``, ``kappa_max``, ``working_mode``, ``serial_min``,
        ``clearance`` (the validity rules), ``workspace`` (the working mode's branch does not
        reach the point), or ``path_tolerance`` (the line cannot be followed within the
        tolerance by a certified joint path there).
    value : float
        The measured value that breaks the rule (kappa(A), serial measure, clearance in m,
        joint value in rad, distance in m), NaN when none applies.
    p : shape (3,), m
        The last valid point of P on the polyline (where the path ends).
    fraction : float
        Share of the polyline's length achieved, in [0, 1).
    detail : str
        The sentence of the message (rule, value, point).
    """

    rule: str
    value: float
    p: np.ndarray
    fraction: float
    detail: str


@dataclass(frozen=True, slots=True)
class PathEvent:
    """A surface the polyline meets, found by
    :func:`planner.cartesian.inspection.inspect_cartesian`.

    Attributes
    ----------
    kind : str
        ``leg_A_stretched``, ``leg_A_folded``, ``leg_B_stretched``, ``leg_B_folded``,
        ``P_on_axis`` (a serial singular surface: the working mode's workspace ends there);
        ``serial_min`` (the surface where a serial measure equals ``margins.serial_min``,
        named in ``detail``); ``kappa_max`` (kappa(A) = ``margins.kappa_max``);
        ``parallel`` (kappa(A) infinite: C, D, P aligned); ``joint_limits``.
    segment : int
        Index of the polyline segment (0: start-P -> waypoints[0]).
    fraction : float
        Position along the whole polyline, share of its length, in [0, 1].
    p : shape (3,), m
    entering : bool
        True when the polyline goes from the valid side to the invalid side there.
    detail : str
    """

    kind: str
    segment: int
    fraction: float
    p: np.ndarray
    entering: bool
    detail: str


@dataclass(frozen=True, slots=True)
class CartesianDiagnostics:
    """Measures of a Cartesian path (the fields of a plan's diagnostics plus deviations).

    Attributes
    ----------
    planning_time_s, timing_time_s : float, s
    path_length : float, rad -- joint-space length of the path.
    cartesian_length : float, m -- length of the polyline achieved.
    max_kappa_A, min_serial_margin, min_clearance : extremes (as :class:`planner.planning.result.Diagnostics`).
    chord_bound : float, m -- largest certified chord deviation of the joint pieces.
    max_path_deviation : float, m -- largest measured distance of P from the polyline: over
        the timed trajectory's dense check times when timed, else over the joint pieces
        sampled finely.
    blend_deviation_bound : float, m -- certified bound on the extra deviation of the blends.
    waypoints : int -- joint waypoints of the path.
    """

    planning_time_s: float
    timing_time_s: float = 0.0
    path_length: float = float("nan")
    cartesian_length: float = 0.0
    max_kappa_A: float = float("nan")
    min_serial_margin: float = float("nan")
    min_clearance: float = float("nan")
    chord_bound: float = 0.0
    max_path_deviation: float = float("nan")
    blend_deviation_bound: float = 0.0
    waypoints: int = 0


@dataclass(frozen=True, eq=False)
class CartesianResult:
    """Result of :func:`planner.cartesian.plan.plan_cartesian`.

    Attributes
    ----------
    status : PlanStatus
        ``solved`` exactly when ``fraction == 1``; ``no_path`` when the path stops short;
        ``invalid_start`` when the start breaks a rule (fraction 0, no path).
    message : str
        For ``no_path``: the rule, the measured value, the point and the fraction.
    fraction : float
        Share of the polyline's length achieved, in [0, 1].
    path : PlanPath or None
        The joint path up to the last valid point (one segment in the start's modes).
    polyline : shape (K + 1, 3), m -- start-P followed by the waypoints.
    s : shape (N,), m -- arc length along the polyline of each joint waypoint.
    p : shape (N, 3), m -- P of each joint waypoint (on the polyline).
    stop : StopPoint or None
    trajectory : planner.timing.Trajectory or None
    timing_error : str -- why timing failed (empty when it did not).
    events : tuple of PathEvent -- the pre-check of the polyline.
    working_mode, assembly_mode : str
    diagnostics : CartesianDiagnostics
    """

    status: PlanStatus
    message: str
    fraction: float
    path: PlanPath | None
    polyline: np.ndarray
    s: np.ndarray
    p: np.ndarray
    stop: StopPoint | None
    trajectory: Trajectory | None
    timing_error: str
    events: tuple[PathEvent, ...]
    working_mode: str
    assembly_mode: str
    diagnostics: CartesianDiagnostics = field(
        default_factory=lambda: CartesianDiagnostics(float("nan"))
    )

    @property
    def solved(self) -> bool:
        return self.status is PlanStatus.SOLVED
