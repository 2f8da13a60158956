"""Kinematic calibration (``docs/calibration.md``): measured points P of commanded postures
-> the identified lengths, actuator zero offsets and tracker frame (:func:`calibrate`), and
the postures worth measuring (:func:`suggest_poses`).

Core: numpy and scipy; the model is the product's five-bar with its legs' lengths apart
(:mod:`planner.calibration.model`).
"""

from __future__ import annotations

from planner.calibration.fit import (
    IDENTIFY_DEFAULT,
    IDENTIFY_OPTIONS,
    CalibrationResult,
    Measurements,
    calibrate,
)
from planner.calibration.poses import SuggestedPoses, suggest_poses

__all__ = [
    "IDENTIFY_DEFAULT",
    "IDENTIFY_OPTIONS",
    "CalibrationResult",
    "Measurements",
    "SuggestedPoses",
    "calibrate",
    "suggest_poses",
]
