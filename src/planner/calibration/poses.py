"""Postures to measure: a greedy D-optimal choice over a sample of the valid set.

The sample: ``candidates`` postures drawn uniformly within the joint limits, in both assembly
modes, kept where :class:`planner.validity.ValidityChecker` (default margins, no obstacles)
finds them valid in their working mode; so every working mode that the design operates is
represented in proportion to its share of the joint space. The choice: starting from nothing,
add the candidate that most increases ``log det`` of the information matrix ``sum J_i^T J_i``
of the identified parameters (the measurement Jacobian of :mod:`planner.calibration.model` at
the nominal design, each column scaled by its norm over the sample so that metres and radians
weigh alike; a tiny ridge keeps the first steps defined). One rank-1 update of ``det(I + J_i
M^-1 J_i^T)`` per candidate and step; the parameters the sample cannot identify (e.g.
``offsets[0]`` with the frame free) are left out before the choice.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from planner.calibration.fit import IDENTIFY_DEFAULT, _parameter_map, _select
from planner.calibration.model import measurement_jacobian
from planner.design import Design
from planner.exceptions import InputError
from planner.kinematics import WORKING_MODES, forward_batch, mode_label

__all__ = ["MAX_SUGGESTED", "SuggestedPoses", "suggest_poses", "valid_sample"]

#: Most postures one suggestion returns.
MAX_SUGGESTED = 500


@dataclass(frozen=True, eq=False)
class SuggestedPoses:
    """``q`` (N, 3) rad; ``assembly_mode`` and ``working_mode`` (N labels) of each."""

    q: np.ndarray
    assembly_mode: list[str]
    working_mode: list[str]


def valid_sample(design: Design, candidates: int, seed: int) -> SuggestedPoses:
    """The valid postures among ``candidates`` drawn uniformly within the joint limits
    (seeded), in both assembly modes, with their modes (module docstring)."""
    from planner.validity import ValidityChecker

    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(design.joint_min), np.asarray(design.joint_max)
    q = rng.uniform(lo, hi, size=(candidates, 3))
    qs, ams, wms = [], [], []
    for am in ("+", "-"):
        batch = forward_batch(design, q, am)
        signs = batch.working_mode_signs
        clear = batch.ok & np.all(signs != 0, axis=1)
        labels = np.array([mode_label(s) if c else "" for s, c in zip(signs, clear, strict=True)])
        for wm in WORKING_MODES:
            mine = labels == wm
            if not mine.any():
                continue
            sub = q[mine]
            valid = ValidityChecker(design, assembly_mode=am, working_mode=wm).is_valid(sub)
            qs.append(sub[valid])
            ams += [am] * int(valid.sum())
            wms += [wm] * int(valid.sum())
    if not qs or sum(len(x) for x in qs) == 0:
        raise InputError("no valid posture found in the design's joint limits", field="design")
    return SuggestedPoses(np.concatenate(qs), ams, wms)


def suggest_poses(
    design: Design,
    n: int,
    *,
    identify: Iterable[str] = IDENTIFY_DEFAULT,
    candidates: int = 2000,
    seed: int = 0,
) -> SuggestedPoses:
    """``n`` postures to measure for calibrating ``design`` (module docstring).

    Raises
    ------
    InputError
        ``n`` outside [1, :data:`MAX_SUGGESTED`], or no valid posture in the sample.
    """
    if not 1 <= n <= MAX_SUGGESTED:
        raise InputError(f"n must lie in [1, {MAX_SUGGESTED}], got {n}", field="n")
    sample = valid_sample(design, max(candidates, 4 * n), seed)
    _, tmap = _parameter_map(tuple(identify))
    full = np.zeros(tmap.shape[0])
    full[:5] = (design.L0, design.L1, design.L1, design.L2, design.L2)
    branch = np.where(np.array(sample.assembly_mode) == "+", 1.0, -1.0)
    m = len(branch)
    # at the identity frame p_tracker = P, so the residual Jacobian is the model's own
    from planner.calibration.model import loop_state

    p = loop_state(full, sample.q, branch).p3
    jac = measurement_jacobian(full, sample.q, branch, p) @ tmap
    jac = jac[:, _select(jac)]
    jac = jac / np.linalg.norm(jac, axis=0)
    blocks = jac.reshape(m, 3, -1)
    k = blocks.shape[2]
    info = 1e-9 * np.eye(k)
    chosen: list[int] = []
    free = np.ones(m, dtype=bool)
    for _ in range(min(n, m)):
        inv = np.linalg.inv(info)
        gain = np.linalg.det(np.eye(3) + (blocks @ inv) @ blocks.transpose(0, 2, 1))
        gain[~free] = -np.inf
        best = int(np.argmax(gain))
        chosen.append(best)
        free[best] = False
        info = info + blocks[best].T @ blocks[best]
    return SuggestedPoses(
        sample.q[chosen],
        [sample.assembly_mode[i] for i in chosen],
        [sample.working_mode[i] for i in chosen],
    )
