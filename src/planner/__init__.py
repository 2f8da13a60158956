"""hybrid-planner: plan, time and analyse motions of the 3-DOF hybrid manipulator of
Chablat, Wenger and Angeles (a symmetric five-bar A-C-P-D-B whose plane turns about AB).

Frames, mode labels and formulas: ``docs/conventions.md`` and :mod:`planner.kinematics`.

The names below are imported on first use (PEP 562), so that importing a light module of
the package (the client, ``planner.wire``, ``planner.design``) does not load the kinematics
and their numba kernels, which cost seconds on a slow machine: ``from planner import
Manipulator`` loads them, ``import planner.client`` does not.
"""

from __future__ import annotations

import logging
from importlib.metadata import PackageNotFoundError, version
from typing import TYPE_CHECKING

from planner._lazy import lazy_exports

if TYPE_CHECKING:
    from planner.calibration import Measurements, calibrate
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
    from planner.sequence import SequenceResult, SequenceTarget, solve_sequence
    from planner.solver import Solution, solve

try:
    __version__ = version("hybrid-planner")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0+unknown"

logging.getLogger(__name__).addHandler(logging.NullHandler())

#: Where each exported name lives (a submodule of the package), imported on first use.
_HOMES = {
    "Measurements": "calibration",
    "calibrate": "calibration",
    "Design": "design",
    "AssemblyError": "exceptions",
    "DesignError": "exceptions",
    "InputError": "exceptions",
    "KinematicsError": "exceptions",
    "PlannerError": "exceptions",
    "SingularPostureError": "exceptions",
    "ASSEMBLY_MODES": "kinematics",
    "WORKING_MODES": "kinematics",
    "Conditioning": "kinematics",
    "Manipulator": "kinematics",
    "Posture": "kinematics",
    "PostureBatch": "kinematics",
    "conditioning": "kinematics",
    "forward_batch": "kinematics",
    "inverse_batch": "kinematics",
    "link_points": "kinematics",
    "SequenceResult": "sequence",
    "SequenceTarget": "sequence",
    "solve_sequence": "sequence",
    "Solution": "solver",
    "solve": "solver",
}


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
    "Measurements",
    "PlannerError",
    "Posture",
    "PostureBatch",
    "SequenceResult",
    "SequenceTarget",
    "SingularPostureError",
    "Solution",
    "__version__",
    "calibrate",
    "conditioning",
    "forward_batch",
    "inverse_batch",
    "link_points",
    "solve",
    "solve_sequence",
]

__getattr__, __dir__ = lazy_exports(__name__, _HOMES, __all__)
