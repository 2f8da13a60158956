"""hybrid-planner: plan, time and analyse motions of the 3-DOF hybrid manipulator of
Chablat, Wenger and Angeles (a symmetric five-bar A-C-P-D-B whose plane turns about AB).

Frames, mode labels and formulas: ``docs/conventions.md`` and :mod:`planner.kinematics`.
"""

from __future__ import annotations

import logging
from importlib.metadata import PackageNotFoundError, version

from planner.design import Design
from planner.exceptions import (
    AssemblyError,
    DesignError,
    InputError,
    KinematicsError,
    PlannerError,
    SingularPostureError,
)
from planner.kinematics import (
    ASSEMBLY_MODES,
    WORKING_MODES,
    Conditioning,
    Manipulator,
    Posture,
    PostureBatch,
    conditioning,
    forward_batch,
    inverse_batch,
    link_points,
)

try:
    __version__ = version("hybrid-planner")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0+unknown"

logging.getLogger(__name__).addHandler(logging.NullHandler())

__all__ = [
    "ASSEMBLY_MODES",
    "WORKING_MODES",
    "AssemblyError",
    "Conditioning",
    "Design",
    "DesignError",
    "InputError",
    "KinematicsError",
    "Manipulator",
    "PlannerError",
    "Posture",
    "PostureBatch",
    "SingularPostureError",
    "__version__",
    "conditioning",
    "forward_batch",
    "inverse_batch",
    "link_points",
]
