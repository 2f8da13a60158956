"""The product's exceptions.

Every error the library raises on purpose derives from :class:`PlannerError`, so a caller
can catch the product's errors apart from bugs. The web layer maps them to HTTP answers in
one place.

::

    PlannerError
    ├── DesignError            (ValueError)  a design's numbers break a rule
    ├── InputError             (ValueError)  an argument has the wrong shape or a non-finite value
    └── KinematicsError
        ├── AssemblyError                    q does not close the five-bar loop
        └── SingularPostureError             the asked quantity is undefined at a singularity
"""

from __future__ import annotations

__all__ = [
    "AssemblyError",
    "DesignError",
    "InputError",
    "KinematicsError",
    "PlannerError",
    "SingularPostureError",
]


class PlannerError(Exception):
    """Base of every error the product raises on purpose."""


class DesignError(PlannerError, ValueError):
    """A design's link lengths, radius or joint limits break a rule (the message names it)."""


class InputError(PlannerError, ValueError):
    """An argument has the wrong shape, or holds NaN or an infinity."""


class KinematicsError(PlannerError):
    """A kinematic quantity cannot be computed for the given posture."""


class AssemblyError(KinematicsError):
    """The actuated joints do not close the loop: |CD| > 2 L2, C = D, or the asked assembly
    mode does not exist there."""


class SingularPostureError(KinematicsError):
    """The quantity asked for is undefined at this posture (a parallel singularity for a
    Cartesian velocity, a degenerate point for inverse kinematics)."""
