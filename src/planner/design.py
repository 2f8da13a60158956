"""The design of the manipulator: link lengths, link radius and joint limits.

Frame and symbols follow ``docs/conventions.md``: ``L0 = |AB|``, ``L1 = |AC| = |BD|``,
``L2 = |CP| = |DP|``; metres and radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from planner.exceptions import DesignError

__all__ = ["MAX_JOINT_TRAVEL", "MAX_LENGTH", "MIN_LENGTH", "PRESET_NAMES", "Design"]

#: Shortest link accepted, m. Shorter links make every squared length underflow-prone.
MIN_LENGTH = 1e-6
#: Longest link (and largest L0 and link radius) accepted, m: a sanity bound, far above any robot.
MAX_LENGTH = 1e3
#: Joint limits must lie in [-MAX_JOINT_TRAVEL, MAX_JOINT_TRAVEL], rad (two turns each way).
MAX_JOINT_TRAVEL = 4 * math.pi

#: Names accepted by :meth:`Design.preset` (and the service's ``PLANNER_DEFAULT_DESIGN``).
PRESET_NAMES: tuple[str, ...] = ("default", "singularity-free", "paper-optimum")

_FULL_TURN = (-math.pi, -math.pi, -math.pi), (math.pi, math.pi, math.pi)


def _as_triple(name: str, value: object) -> tuple[float, float, float]:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise DesignError(f"{name} must be 3 numbers, got {value!r}", field=name) from exc
    if arr.shape != (3,):
        raise DesignError(f"{name} must be 3 numbers, got shape {arr.shape}", field=name)
    if not np.all(np.isfinite(arr)):
        raise DesignError(f"{name} must be finite, got {arr.tolist()}", field=name)
    return (float(arr[0]), float(arr[1]), float(arr[2]))


@dataclass(frozen=True, slots=True)
class Design:
    """Geometry and joint limits of one manipulator.

    Parameters
    ----------
    L0 : float
        Distance |AB| between the two actuated pivots, m, ``L0 >= 0``.
    L1 : float
        Proximal link length |AC| = |BD|, m, ``L1 > 0``.
    L2 : float
        Distal link length |CP| = |DP|, m, ``L2 > 0``.
    link_radius : float
        Radius of the capsules AC, BD, CP, DP used for collision checks, m, ``>= 0``.
    joint_min, joint_max : tuple of 3 floats
        Literal limits of (theta1, theta2, theta3), rad, ``joint_min < joint_max``. Values are
        never wrapped: 3.5 rad is not -2.78 rad for a limit check.

    Raises
    ------
    DesignError
        A number is not finite or breaks one of the rules above (the message names it, and
        ``field`` is its wire name: ``"L1"``, ``"joint_max"``, or ``("joint_min", 2)`` for one
        limit, as a request's ``loc`` writes it).
    """

    L0: float
    L1: float
    L2: float
    link_radius: float = 0.02
    joint_min: tuple[float, float, float] = field(default=_FULL_TURN[0])
    joint_max: tuple[float, float, float] = field(default=_FULL_TURN[1])

    def __post_init__(self) -> None:
        for name in ("L0", "L1", "L2", "link_radius"):
            value = getattr(self, name)
            try:
                value = float(value)
            except (TypeError, ValueError) as exc:
                raise DesignError(f"{name} must be a number, got {value!r}", field=name) from exc
            if not math.isfinite(value):
                raise DesignError(f"{name} must be finite, got {value}", field=name)
            if value > MAX_LENGTH:
                raise DesignError(f"{name} must be at most {MAX_LENGTH} m, got {value}", field=name)
            object.__setattr__(self, name, value)
        for name in ("L1", "L2"):
            if getattr(self, name) < MIN_LENGTH:
                raise DesignError(
                    f"{name} must be at least {MIN_LENGTH} m (a link has a length), "
                    f"got {getattr(self, name)}",
                    field=name,
                )
        if self.L0 < 0:
            raise DesignError(f"L0 must be >= 0, got {self.L0}", field="L0")
        if self.link_radius < 0:
            raise DesignError(
                f"link_radius must be >= 0, got {self.link_radius}", field="link_radius"
            )
        lo = _as_triple("joint_min", self.joint_min)
        hi = _as_triple("joint_max", self.joint_max)
        for i in range(3):
            if not lo[i] < hi[i]:
                raise DesignError(
                    f"joint_min[{i}] must be below joint_max[{i}], got {lo[i]} >= {hi[i]}",
                    field=("joint_min", i),
                )
            for name, v in (("joint_min", lo[i]), ("joint_max", hi[i])):
                if abs(v) > MAX_JOINT_TRAVEL:
                    raise DesignError(
                        f"{name}[{i}] must lie within +-{MAX_JOINT_TRAVEL:.4f} rad, got {v}",
                        field=(name, i),
                    )
        object.__setattr__(self, "joint_min", lo)
        object.__setattr__(self, "joint_max", hi)

    # ------------------------------------------------------------------ presets
    @classmethod
    def paper_optimum(cls, reach: float = 0.8) -> Design:
        """The paper's workspace optimum: ``L0 = 0``, ``L1 = L2 = reach / 2`` (figures 8-9).

        Largest workspace for a fixed ``L1 + L2``, but only two working modes are operative:
        the modes with ``s_A = s_B`` lie on the C = D parallel singularity everywhere.
        """
        return cls(L0=0.0, L1=reach / 2, L2=reach / 2)

    @classmethod
    def singularity_free(cls) -> Design:
        """``L0 = 0.5, L1 = 0.2, L2 = 0.6`` m: ``2 L1 < L0 < 2 (L2 - L1)``, so neither parallel
        singularity (C = D, CD stretched) can occur anywhere (figures 10-11)."""
        return cls(L0=0.5, L1=0.2, L2=0.6)

    @classmethod
    def default(cls) -> Design:
        """The robot a new user gets: the :meth:`singularity_free` design.

        Why: with ``2 L1 < L0 < 2 (L2 - L1)`` no posture of the workspace is parallel-singular,
        so kappa(A) is bounded over the whole workspace, all eight working modes are operative
        and every mode change is a plain serial-singularity transit. The paper's optimum has a
        larger workspace for its size, but half of its working modes are unusable.
        """
        return cls.singularity_free()

    @classmethod
    def preset(cls, name: str) -> Design:
        """The preset called ``name``: one of :data:`PRESET_NAMES`."""
        makers = {
            "default": cls.default,
            "singularity-free": cls.singularity_free,
            "paper-optimum": cls.paper_optimum,
        }
        if name not in makers:
            raise DesignError(f"no preset {name!r}: presets are {', '.join(PRESET_NAMES)}")
        return makers[name]()

    # ------------------------------------------------------------------ derived
    @property
    def reach(self) -> float:
        """Outer radius ``L1 + L2`` of each leg's reachable shell, m."""
        return self.L1 + self.L2

    @property
    def joint_limits(self) -> np.ndarray:
        """Shape (2, 3): row 0 the lower, row 1 the upper joint limits, rad."""
        return np.array([self.joint_min, self.joint_max])
