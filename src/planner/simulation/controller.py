"""The controllers of the simulated robot, as a value object.

- ``computed_torque``: the product's own inverse dynamics
  (:func:`planner.dynamics.inverse_dynamics`) of the reference as the feed-forward, plus a PD
  on the error mapped through the mass matrix at the reference:
  ``tau = ID(q_r, qd_r, qdd_r) + M(q_r) (kp e + kd e_dot)``, ``e = q_r - q``. The gains are
  those of the error's own dynamics (``e_ddot + kd e_dot + kp e = 0`` with a perfect model):
  ``kp`` in 1/s^2, ``kd`` in 1/s; default a critically damped 50 rad/s (``kp`` 2500, ``kd``
  100). The feed-forward holds over each control period: the inverse dynamics at the
  period's middle with its mean acceleration (:func:`planner.simulation.engine.simulate`);
  the error is read at the period's start.
- ``pd``: ``tau = kp e + kd e_dot`` alone, no model (``kp`` in N m/rad, ``kd`` in N m s/rad):
  gravity and inertia are the PD's to fight, so it lags and sags. Default: the gains that
  give the same 50 rad/s on the mass matrix's diagonal at the first posture,
  ``kp = 2500 M_jj(q_0)``, ``kd = 100 M_jj(q_0)`` (they depend on the robot, so they are
  chosen when the simulation starts).

Either controller's torque is clipped to the actuators' limits before it is applied.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from planner.exceptions import InputError

__all__ = ["CONTROLLER_KINDS", "DEFAULT_BANDWIDTH", "Controller", "ControllerKind"]

ControllerKind = Literal["computed_torque", "pd"]
#: The controllers the simulator knows.
CONTROLLER_KINDS: tuple[str, ...] = ("computed_torque", "pd")
#: The default closed-loop bandwidth of both controllers, rad/s (critically damped).
DEFAULT_BANDWIDTH = 50.0


@dataclass(frozen=True, slots=True)
class Controller:
    """One controller: its kind and its gains (3 each, >= 0; None: the kind's default)."""

    kind: str = "computed_torque"
    kp: tuple[float, float, float] | None = None
    kd: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        if self.kind not in CONTROLLER_KINDS:
            raise InputError(
                f"unknown controller {self.kind!r}: one of {', '.join(CONTROLLER_KINDS)}",
                field="kind",
            )
        for name in ("kp", "kd"):
            value = getattr(self, name)
            if value is None:
                continue
            gains = np.asarray(value, dtype=float)
            if gains.shape != (3,) or not np.all(np.isfinite(gains)) or np.any(gains < 0):
                raise InputError(f"{name} must be 3 finite gains >= 0, got {value!r}", field=name)
            object.__setattr__(self, name, tuple(float(g) for g in gains))

    def gains(self, mass_diagonal: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(kp, kd), each (3,), in the kind's units; ``mass_diagonal`` (3,), kg m^2: the mass
        matrix's diagonal at the first posture, which scales the defaults of ``pd``."""
        w = DEFAULT_BANDWIDTH
        scale = np.ones(3) if self.kind == "computed_torque" else np.asarray(mass_diagonal)
        kp = np.asarray(self.kp) if self.kp is not None else w**2 * scale
        kd = np.asarray(self.kd) if self.kd is not None else 2 * w * scale
        return kp.astype(float), kd.astype(float)
