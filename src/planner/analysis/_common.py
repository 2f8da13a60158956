"""Helpers shared by the analysis modules: joint-limit tests and slot bookkeeping."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from planner.design import Design
from planner.exceptions import InputError
from planner.kinematics import WORKING_MODES, mode_signs

__all__ = [
    "KAPPA_SINGULAR",
    "MODE_INDEX",
    "MODE_SIGNS",
    "parse_modes",
    "within_limits_mod_2pi",
]

#: kappa(A) at or above which a sampled posture counts as parallel-singular in the analyses
#: (the bound of the design-check test of the issue).
KAPPA_SINGULAR = 1e6

#: Slot index of each working-mode label in :func:`planner.inverse_batch`.
MODE_INDEX: dict[str, int] = {m: k for k, m in enumerate(WORKING_MODES)}

#: Shape (8, 3), int8: the signs (s_axis, s_A, s_B) of each slot of :data:`WORKING_MODES`.
MODE_SIGNS = np.array([mode_signs(m) for m in WORKING_MODES])


def parse_modes(working_modes: str | Iterable[str] | None) -> np.ndarray:
    """Boolean mask, shape (8,), of the allowed working modes.

    ``None`` or ``"any"`` allows all eight; otherwise an iterable of labels such as ``"+-+"``.
    """
    mask = np.zeros(len(WORKING_MODES), dtype=bool)
    if working_modes is None or working_modes == "any":
        mask[:] = True
        return mask
    if isinstance(working_modes, str):
        working_modes = [working_modes]
    for m in working_modes:
        if m not in MODE_INDEX:
            raise InputError(f"working_mode must be one of {WORKING_MODES} or 'any', got {m!r}")
        mask[MODE_INDEX[m]] = True
    return mask


def within_limits_mod_2pi(design: Design, q: np.ndarray) -> np.ndarray:
    """Whether some 2-pi shift of each joint value lies inside the design's literal limits.

    A posture found by inverse kinematics carries angles in (-pi, pi]; the robot reaches the
    same posture at ``q + 2 k pi`` for any integer ``k`` per joint, so a point is reachable
    within the limits when one such shift of every joint fits. NaN gives False.

    Parameters
    ----------
    q : shape S + (3,), rad

    Returns
    -------
    shape S, bool
    """
    lo = np.asarray(design.joint_min)
    hi = np.asarray(design.joint_max)
    two_pi = 2.0 * np.pi
    with np.errstate(invalid="ignore"):
        shifted = q + two_pi * np.ceil((lo - q) / two_pi)
        inside = shifted <= hi
    return np.all(inside, axis=-1)
