"""How a planned path is timed: the method, the output rate, the corner allowance and where
the trajectory comes to rest (:class:`TimingOptions`, the ``timing`` argument of
:func:`planner.solve`). Light: loads neither toppra nor ruckig."""

from __future__ import annotations

import math
from dataclasses import dataclass

from planner.exceptions import InputError

__all__ = [
    "DEFAULT_MAX_DEVIATION",
    "DEFAULT_SAMPLE_RATE_HZ",
    "METHODS",
    "TIMING_METHODS",
    "TimingOptions",
]

#: The time-parameterisation methods of :func:`planner.timing.time_path`.
METHODS = ("toppra", "ruckig")
#: What :class:`TimingOptions` accepts: a method, or "none" (the path only).
TIMING_METHODS = (*METHODS, "none")
#: Output sample rate, Hz.
DEFAULT_SAMPLE_RATE_HZ = 100.0
#: Largest distance from a vertex to its blend, rad (joint space).
DEFAULT_MAX_DEVIATION = 0.05


@dataclass(frozen=True, slots=True)
class TimingOptions:
    """Options of the timing step of :func:`planner.solve` (wire field ``timing``, with
    ``limits.cartesian_speed``).

    Parameters
    ----------
    method : "toppra" (time-optimal under velocity and acceleration limits), "ruckig"
        (jerk-limited) or "none" (no trajectory: the path only).
    sample_rate_hz : output sample rate, Hz (> 0).
    max_deviation : largest joint-space distance from a waypoint to its corner blend, rad
        (>= 0; 0 stops at every waypoint); also the allowance of the dense re-check near
        the planned path.
    stop_at_transits : come to rest at each working-mode transit (else a transit is passed at
        speed: the crossing is straight, so it is no corner).
    max_cartesian_speed : bound on the speed of P, m/s (> 0), or None.
    max_samples : most samples the trajectory may have (a larger duration x rate raises
        :class:`~planner.exceptions.InputError` naming ``sample_rate_hz``), or None: the
        library's cap.
    """

    method: str = "toppra"
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ
    max_deviation: float = DEFAULT_MAX_DEVIATION
    stop_at_transits: bool = False
    max_cartesian_speed: float | None = None
    max_samples: int | None = None

    def __post_init__(self) -> None:
        if self.method not in TIMING_METHODS:
            raise InputError(
                f"method must be one of {', '.join(TIMING_METHODS)}, got {self.method!r}",
                field="method",
            )
        if not (math.isfinite(self.sample_rate_hz) and self.sample_rate_hz > 0):
            raise InputError(
                f"sample_rate_hz must be a finite number > 0, got {self.sample_rate_hz!r}",
                field="sample_rate_hz",
            )
        if not (math.isfinite(self.max_deviation) and self.max_deviation >= 0):
            raise InputError(
                f"max_deviation must be a finite number >= 0, got {self.max_deviation!r}",
                field="max_deviation",
            )
        speed = self.max_cartesian_speed
        if speed is not None and not (math.isfinite(speed) and speed > 0):
            raise InputError(
                f"max_cartesian_speed must be a finite number > 0, got {speed!r}",
                field="max_cartesian_speed",
            )
        if self.max_samples is not None and self.max_samples < 2:
            raise InputError(
                f"max_samples must be >= 2, got {self.max_samples!r}", field="max_samples"
            )
