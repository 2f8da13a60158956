"""The safety margins of a valid posture (:class:`Margins`) and their defaults: a value
object the checker, its kernels and every caller share, kept apart from the checker so the
kernels need not import it."""

from __future__ import annotations

import math
from dataclasses import dataclass

from planner.exceptions import InputError

__all__ = ["DEFAULT_CLEARANCE", "DEFAULT_KAPPA_MAX", "DEFAULT_SERIAL_MIN", "Margins"]

#: Default bound on kappa(A): the apex angle C-P-D stays more than 11.4 deg away from 0 and
#: 180 deg, where the Cartesian velocity error gain of the parallel part is at most 10.
DEFAULT_KAPPA_MAX = 10.0
#: Default lower bound on each serial measure: legs at least 2.9 deg from stretched/folded and
#: P at least 5 % of the reach from the axis AB (kappa(B) stays finite and modes cannot flip).
DEFAULT_SERIAL_MIN = 0.05
#: Default least distance between link capsules and obstacles, m.
DEFAULT_CLEARANCE = 0.01


@dataclass(frozen=True, slots=True)
class Margins:
    """Safety margins of a valid posture (``docs/conventions.md``, wire field ``margins``).

    Parameters
    ----------
    kappa_max : float, default :data:`DEFAULT_KAPPA_MAX` (10)
        Upper bound on kappa(A), finite and > 1.
    serial_min : float, default :data:`DEFAULT_SERIAL_MIN` (0.05)
        Lower bound on |w| / (L1 + L2), |sin(theta4 - theta2)|, |sin(theta5 - theta3)|, in
        (0, 1). It must be positive: a zero margin would let a motion touch a serial
        singularity, where the working mode is undefined.
    clearance : float, default :data:`DEFAULT_CLEARANCE` (0.01 m)
        Least distance from every link capsule to every obstacle, m, >= 0.
    """

    kappa_max: float = DEFAULT_KAPPA_MAX
    serial_min: float = DEFAULT_SERIAL_MIN
    clearance: float = DEFAULT_CLEARANCE

    def __post_init__(self) -> None:
        for name in ("kappa_max", "serial_min", "clearance"):
            value = getattr(self, name)
            try:
                value = float(value)
            except (TypeError, ValueError) as exc:
                raise InputError(f"margins.{name} must be a number, got {value!r}") from exc
            if not math.isfinite(value):
                raise InputError(f"margins.{name} must be finite, got {value}")
            object.__setattr__(self, name, value)
        if not self.kappa_max > 1.0:
            raise InputError(f"margins.kappa_max must be > 1, got {self.kappa_max}")
        if not 0.0 < self.serial_min < 1.0:
            raise InputError(f"margins.serial_min must lie in (0, 1), got {self.serial_min}")
        if self.clearance < 0.0:
            raise InputError(f"margins.clearance must be >= 0, got {self.clearance}")

    @property
    def cd_range(self) -> tuple[float, float]:
        """(low, high) bounds on |CD| / (2 L2) equivalent to kappa(A) <= kappa_max."""
        k = self.kappa_max
        r = math.sqrt(1.0 + k * k)
        return 1.0 / r, k / r
