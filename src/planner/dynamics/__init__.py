"""Dynamics of the manipulator: its inertial model and the inverse dynamics of the closed
chain in actuated coordinates (``docs/dynamics.md``).

Core: numpy and numba (no wire formats, no toppra); :mod:`planner.dynamics.mjcf` writes the
MJCF export, :mod:`planner.dynamics.analysis` the design-side maps,
:mod:`planner.dynamics.identify` the inertial parameters that measured torques determine
(``docs/calibration.md``). The timing uses it
through :mod:`planner.timing.torque` for torque limits.
"""

from __future__ import annotations

from planner.dynamics.inertia import DEFAULT_GRAVITY, Inertia, LinkInertia, check_gravity
from planner.dynamics.inverse import DynamicsBatch, inverse_dynamics, mass_matrix

__all__ = [
    "DEFAULT_GRAVITY",
    "DynamicsBatch",
    "Inertia",
    "LinkInertia",
    "check_gravity",
    "inverse_dynamics",
    "mass_matrix",
]
