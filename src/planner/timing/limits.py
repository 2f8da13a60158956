"""Per-joint kinematic limits of a trajectory, validated once at the boundary.

Each limit is 3 positive finite numbers, one per actuated joint (theta1, theta2, theta3), and
bounds the magnitude symmetrically: ``|qd_j| <= velocity[j]`` (rad/s),
``|qdd_j| <= acceleration[j]`` (rad/s^2), ``|qddd_j| <= jerk[j]`` (rad/s^3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.exceptions import LimitsError

__all__ = ["MAX_RATE", "MIN_RATE", "RUCKIG_DEFAULT_JERK", "JointLimits"]

#: Smallest limit accepted (rad/s, rad/s^2 or rad/s^3): below it a move would take ages and
#: squares of the profile underflow; a robot that slow is not being timed.
MIN_RATE = 1e-6
#: Largest limit accepted: far above any actuator, and safe to square and cube.
MAX_RATE = 1e6
#: The jerk Ruckig is given per joint (rad/s^3) when none is asked: Ruckig cannot work
#: without one (the acceleration ramps up in 40 ms at 8 rad/s^2). toppra takes no jerk unless
#: one is asked (``limits.jerk``), and then honours it (:mod:`planner.timing.jerk_filter`).
RUCKIG_DEFAULT_JERK = 200.0


def _positive_triple(name: str, value: object) -> tuple[float, float, float]:
    """``value`` as 3 positive finite floats, or :class:`LimitsError` naming ``name``."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise LimitsError(f"limits.{name} must be 3 numbers, got {value!r}", field=name) from exc
    if arr.shape != (3,):
        raise LimitsError(
            f"limits.{name} must be 3 numbers (one per joint), got shape {arr.shape}", field=name
        )
    for j, v in enumerate(arr.tolist()):
        if not math.isfinite(v):
            raise LimitsError(f"limits.{name}[{j}] must be finite, got {v}", field=name)
        if not MIN_RATE <= v <= MAX_RATE:
            raise LimitsError(
                f"limits.{name}[{j}] must lie in [{MIN_RATE:g}, {MAX_RATE:g}], got {v}",
                field=name,
            )
    return (float(arr[0]), float(arr[1]), float(arr[2]))


def _scaling(name: str, value: object) -> float:
    """A scaling factor in (0, 1], or :class:`LimitsError` naming ``limits.<name>``."""
    if isinstance(value, bool):
        raise LimitsError(f"limits.{name} must be a number in (0, 1], got {value!r}")
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise LimitsError(f"limits.{name} must be a number in (0, 1], got {value!r}") from exc
    if not (math.isfinite(x) and 0.0 < x <= 1.0):
        raise LimitsError(f"limits.{name} must lie in (0, 1], got {value!r}")
    return x


@dataclass(frozen=True, slots=True)
class JointLimits:
    """Symmetric per-joint limits of velocity, acceleration and (optionally) jerk.

    Parameters
    ----------
    velocity : 3 floats, rad/s, each > 0 and finite
    acceleration : 3 floats, rad/s^2, each > 0 and finite
    jerk : 3 floats, rad/s^3, each > 0 and finite, or None (not asked)
        Honoured by both methods when given: ``ruckig`` is jerk-limited by construction
        (without one it takes :data:`RUCKIG_DEFAULT_JERK`); ``toppra``'s time-optimal profile
        is moving-averaged per rest-to-rest section (:mod:`planner.timing.jerk_filter`).
        None: toppra's acceleration is piecewise constant (its jerk undefined).
    torque : 3 floats, N m, each > 0 and finite, or None
        ``|tau_j| <= torque[j]`` for the actuator torques of the inverse dynamics
        (:mod:`planner.timing.torque`); both methods meet it.

    Raises
    ------
    LimitsError
        A field is not 3 numbers, or a value is zero, negative, NaN or infinite; the message
        names the field, the joint and the rule (``limits.velocity[1] must be > 0, got 0.0``).
    """

    velocity: tuple[float, float, float]
    acceleration: tuple[float, float, float]
    jerk: tuple[float, float, float] | None = None
    torque: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "velocity", _positive_triple("velocity", self.velocity))
        object.__setattr__(
            self, "acceleration", _positive_triple("acceleration", self.acceleration)
        )
        if self.jerk is not None:
            object.__setattr__(self, "jerk", _positive_triple("jerk", self.jerk))
        if self.torque is not None:
            object.__setattr__(self, "torque", _positive_triple("torque", self.torque))

    @classmethod
    def default(cls) -> JointLimits:
        """Moderate limits for the reference designs: 2 rad/s, 8 rad/s^2 per joint, no jerk
        asked (ruckig then takes :data:`RUCKIG_DEFAULT_JERK`)."""
        return cls(velocity=(2.0,) * 3, acceleration=(8.0,) * 3)

    def with_ruckig_jerk(self) -> JointLimits:
        """These limits, with :data:`RUCKIG_DEFAULT_JERK` per joint where no jerk is asked
        (what ``method="ruckig"`` is timed under)."""
        if self.jerk is not None:
            return self
        return JointLimits(
            self.velocity, self.acceleration, (RUCKIG_DEFAULT_JERK,) * 3, self.torque
        )

    def scaled(
        self, velocity_scaling: float, acceleration_scaling: float | None = None
    ) -> JointLimits:
        """These limits with velocity multiplied by ``velocity_scaling`` and acceleration by
        ``acceleration_scaling`` (MoveIt's ``max_velocity_scaling_factor`` and
        ``max_acceleration_scaling_factor``), jerk unchanged.

        Parameters
        ----------
        velocity_scaling : float in (0, 1]
        acceleration_scaling : float in (0, 1], optional
            Default: ``velocity_scaling`` (one factor for both, the slower profile of a
            timing repair).

        Raises
        ------
        LimitsError
            A factor is not a number in (0, 1]; the message names the field
            (``limits.velocity_scaling`` or ``limits.acceleration_scaling``).
        """
        v = _scaling("velocity_scaling", velocity_scaling)
        a = (
            v
            if acceleration_scaling is None
            else _scaling("acceleration_scaling", acceleration_scaling)
        )
        return JointLimits(
            velocity=tuple(x * v for x in self.velocity),  # type: ignore[arg-type]
            acceleration=tuple(x * a for x in self.acceleration),  # type: ignore[arg-type]
            jerk=self.jerk,
            torque=self.torque,
        )

    @property
    def velocity_array(self) -> np.ndarray:
        """Shape (3,), rad/s."""
        return np.asarray(self.velocity)

    @property
    def acceleration_array(self) -> np.ndarray:
        """Shape (3,), rad/s^2."""
        return np.asarray(self.acceleration)

    @property
    def jerk_array(self) -> np.ndarray | None:
        """Shape (3,), rad/s^3, or None."""
        return None if self.jerk is None else np.asarray(self.jerk)

    @property
    def torque_array(self) -> np.ndarray | None:
        """Shape (3,), N m, or None."""
        return None if self.torque is None else np.asarray(self.torque)
