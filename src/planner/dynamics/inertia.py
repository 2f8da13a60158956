"""The inertial model of the manipulator: links, payload, turning base and rotors.

Every link is a rigid body whose inertia tensor about its centre of mass is
``I_perp (Id - e e^T) + I_axial e e^T`` (e the link's unit direction), its centre of mass on
the link at the fraction ``com`` of its length from its proximal pivot (A or B for a proximal
link, C or D for a distal one). Both legs are identical (the design is symmetric). The payload
is a point mass at P; the base turns with theta1 about AB and carries the motors of theta2 and
theta3; each actuator's rotor inertia is reflected to its joint (``rotor_j qdd_j`` is added
to ``tau_j``).

:meth:`Inertia.default` derives the product's defaults from the design (``docs/dynamics.md``,
*Defaults*): thin-walled aluminium tubes of the design's ``link_radius``, a 0.5 kg payload,
a base carrying two 0.6 kg motors 6 cm off the axis, rotors of 2e-5 kg m^2 behind a 1:5
reduction. None of them is zero: a newcomer's first torques are those of a plausible robot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.design import Design
from planner.exceptions import InputError

__all__ = [
    "ALUMINIUM_DENSITY",
    "DEFAULT_BASE_MOTOR_MASS",
    "DEFAULT_BASE_MOTOR_RADIUS",
    "DEFAULT_GRAVITY",
    "DEFAULT_PAYLOAD_MASS",
    "DEFAULT_ROTOR_INERTIA",
    "DEFAULT_TUBE_RADIUS",
    "DEFAULT_WALL",
    "MAX_INERTIA",
    "MAX_MASS",
    "Inertia",
    "LinkInertia",
    "check_gravity",
    "tube_inertia",
]

#: Density of aluminium (6061), kg/m^3.
ALUMINIUM_DENSITY = 2700.0
#: Wall thickness of the default tubes, m (a tube thinner than twice this is solid).
DEFAULT_WALL = 0.002
#: Outer radius of the default tubes when the design's ``link_radius`` is 0 (a capsule of no
#: radius has no mass, but the robot has links), m.
DEFAULT_TUBE_RADIUS = 0.02
#: Default payload at P, kg.
DEFAULT_PAYLOAD_MASS = 0.5
#: The turning base carries the motors of theta2 and theta3: each this mass, kg ...
DEFAULT_BASE_MOTOR_MASS = 0.6
#: ... with its centre this far from the axis AB, m.
DEFAULT_BASE_MOTOR_RADIUS = 0.06
#: Each actuator's rotor reflected to its joint: 2e-5 kg m^2 (a 200 W servo) times the square
#: of a 1:5 reduction, kg m^2.
DEFAULT_ROTOR_INERTIA = 2e-5 * 5**2
#: Gravity in the base frame, m/s^2 (the wire's default ``gravity``).
DEFAULT_GRAVITY: tuple[float, float, float] = (0.0, 0.0, -9.81)
#: Sanity bounds (a mass in kg, an inertia in kg m^2): far above any robot, safe to square.
MAX_MASS = 1e6
MAX_INERTIA = 1e6


def _number(name: str, value: object, upper: float) -> float:
    """``value`` as a finite float in [0, upper], or :class:`InputError` naming ``name``."""
    if isinstance(value, bool):
        raise InputError(f"{name} must be a number, got {value!r}", field=name)
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a number, got {value!r}", field=name) from exc
    if not math.isfinite(x):
        raise InputError(f"{name} must be finite, got {x}", field=name)
    if x < 0:
        raise InputError(f"{name} must be >= 0, got {x}", field=name)
    if x > upper:
        raise InputError(f"{name} must be at most {upper:g}, got {x}", field=name)
    return x


@dataclass(frozen=True, slots=True)
class LinkInertia:
    """One link as a rigid body (axisymmetric about its own line).

    Parameters
    ----------
    mass : kg, >= 0
    com : centre of mass as a fraction of the link's length from its proximal pivot, in [0, 1]
    I_perp : kg m^2, >= 0 -- inertia about an axis through the centre of mass normal to the link
    I_axial : kg m^2, >= 0 -- inertia about the link's own line; a rod's tensor obeys the
        triangle inequality ``I_axial <= 2 I_perp`` (the two perpendicular moments sum to at
        least the third).

    ``name`` ("proximal" or "distal") prefixes the field named by an error.
    """

    mass: float
    com: float
    I_perp: float
    I_axial: float
    name: str = "link"

    def __post_init__(self) -> None:
        for key, upper in (("mass", MAX_MASS), ("I_perp", MAX_INERTIA), ("I_axial", MAX_INERTIA)):
            object.__setattr__(self, key, _number(f"{self.name}.{key}", getattr(self, key), upper))
        com = _number(f"{self.name}.com", self.com, 1.0)
        object.__setattr__(self, "com", com)
        if self.I_axial > 2 * self.I_perp * (1 + 1e-12):
            raise InputError(
                f"{self.name}.I_axial must be <= 2 {self.name}.I_perp (the triangle inequality "
                f"of a rod's inertia tensor), got I_axial = {self.I_axial:g} > 2 x "
                f"{self.I_perp:g}",
                field=f"{self.name}.I_axial",
            )


def tube_inertia(
    length: float,
    radius: float,
    name: str,
    *,
    wall: float = DEFAULT_WALL,
    density: float = ALUMINIUM_DENSITY,
) -> LinkInertia:
    """A uniform tube of outer radius ``radius`` and wall ``wall`` (solid when thinner),
    ``length`` long, centre of mass at its middle:
    ``m = rho pi (ro^2 - ri^2) L``, ``I_perp = m (3 (ro^2 + ri^2) + L^2) / 12``,
    ``I_axial = m (ro^2 + ri^2) / 2``."""
    ro = radius
    ri = max(ro - wall, 0.0)
    mass = density * math.pi * (ro**2 - ri**2) * length
    r2 = ro**2 + ri**2
    return LinkInertia(mass, 0.5, mass * (3 * r2 + length**2) / 12, mass * r2 / 2, name)


@dataclass(frozen=True, slots=True)
class Inertia:
    """The inertial model of one manipulator (``design.inertia`` on the wire).

    Parameters
    ----------
    proximal : :class:`LinkInertia` of AC and BD (``com`` from A or B)
    distal : :class:`LinkInertia` of CP and DP (``com`` from C or D)
    payload_mass : kg, >= 0 -- a point mass at P
    base_inertia : kg m^2, >= 0 -- the body turning with theta1, about AB
    rotor : 3 floats, kg m^2, >= 0 -- each actuator's rotor reflected to its joint
    """

    proximal: LinkInertia
    distal: LinkInertia
    payload_mass: float = DEFAULT_PAYLOAD_MASS
    base_inertia: float = 0.0
    rotor: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for key, kind in (("proximal", "proximal"), ("distal", "distal")):
            link = getattr(self, key)
            if not isinstance(link, LinkInertia):
                raise InputError(f"{key} must be a LinkInertia", field=key)
            if link.name != kind:
                object.__setattr__(
                    self, key, LinkInertia(link.mass, link.com, link.I_perp, link.I_axial, kind)
                )
        object.__setattr__(
            self, "payload_mass", _number("payload.mass", self.payload_mass, MAX_MASS)
        )
        object.__setattr__(
            self, "base_inertia", _number("base.inertia", self.base_inertia, MAX_INERTIA)
        )
        try:
            rotor = [float(x) for x in self.rotor]
        except (TypeError, ValueError) as exc:
            raise InputError(f"rotor must be 3 numbers, got {self.rotor!r}", field="rotor") from exc
        if len(rotor) != 3:
            raise InputError(f"rotor must be 3 numbers, got {len(rotor)}", field="rotor")
        object.__setattr__(
            self,
            "rotor",
            tuple(_number(f"rotor[{j}]", x, MAX_INERTIA) for j, x in enumerate(rotor)),
        )

    @classmethod
    def default(cls, design: Design) -> Inertia:
        """The documented defaults for ``design`` (module docstring): aluminium tubes of outer
        radius ``design.link_radius`` (:data:`DEFAULT_TUBE_RADIUS` when it is 0), wall
        :data:`DEFAULT_WALL`; payload :data:`DEFAULT_PAYLOAD_MASS`; base inertia
        ``2 m r^2`` of its two motors; rotors :data:`DEFAULT_ROTOR_INERTIA`."""
        radius = design.link_radius if design.link_radius > 0 else DEFAULT_TUBE_RADIUS
        return cls(
            proximal=tube_inertia(design.L1, radius, "proximal"),
            distal=tube_inertia(design.L2, radius, "distal"),
            payload_mass=DEFAULT_PAYLOAD_MASS,
            base_inertia=2 * DEFAULT_BASE_MOTOR_MASS * DEFAULT_BASE_MOTOR_RADIUS**2,
            rotor=(DEFAULT_ROTOR_INERTIA,) * 3,
        )

    @property
    def rotor_array(self) -> np.ndarray:
        """Shape (3,), kg m^2."""
        return np.asarray(self.rotor, dtype=float)


def check_gravity(gravity: object) -> np.ndarray:
    """``gravity`` as a finite array of shape (3,), m/s^2, or :class:`InputError` naming it."""
    try:
        g = np.asarray(gravity, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"gravity must be 3 numbers, got {gravity!r}", field="gravity") from exc
    if g.shape != (3,):
        raise InputError(f"gravity must be 3 numbers, got shape {g.shape}", field="gravity")
    if not np.all(np.isfinite(g)):
        raise InputError(f"gravity must be finite, got {g.tolist()}", field="gravity")
    if np.max(np.abs(g)) > 1e4:
        raise InputError(f"gravity must be within +-1e4 m/s^2, got {g.tolist()}", field="gravity")
    return g
