"""Synthetic robots for the calibration tests: a nominal design, a perturbed "as built" one
(lengths +-2 mm, offsets +-0.5 deg, tracker frame +-10 mm / 1 deg) and exact measurements of
it, made with the calibration model's own forward kinematics of the true parameters (which
a test checks against the product's kinematics for equal legs)."""

from __future__ import annotations

import numpy as np

from planner import Design
from planner.calibration import Measurements
from planner.calibration.model import FULL_NAMES, loop_state, rotation_matrix

NOMINAL = Design.default()


def true_parameters(seed: int = 1, *, legs: bool = False) -> np.ndarray:
    """The full parameter vector (:data:`FULL_NAMES`) of a perturbed robot."""
    rng = np.random.default_rng(seed)
    full = np.zeros(len(FULL_NAMES))
    d = NOMINAL
    full[:5] = (d.L0, d.L1, d.L1, d.L2, d.L2)
    dl = rng.uniform(-0.002, 0.002, size=5)
    if not legs:
        dl[2], dl[4] = dl[1], dl[3]
    full[:5] += dl
    full[5:8] = np.radians(rng.uniform(-0.5, 0.5, size=3))
    full[8:11] = rng.uniform(-0.01, 0.01, size=3)
    full[11:14] = np.radians(rng.uniform(-1.0, 1.0, size=3))
    return full


def measure(
    full: np.ndarray,
    q: np.ndarray,
    modes: list[str],
    *,
    noise: float = 0.0,
    seed: int = 0,
    with_modes: bool = True,
) -> Measurements:
    """Measured points (tracker frame) of the robot ``full`` at commanded ``q``."""
    branch = np.where(np.asarray(modes) == "+", 1.0, -1.0)
    p3 = loop_state(full, q, branch).p3
    r = rotation_matrix(full[11:14])
    p = (p3 - full[8:11]) @ r  # R^T (P - t), row-wise
    p = p + np.random.default_rng(seed).normal(0.0, noise, size=p.shape)
    return Measurements(q, p, assembly_mode=list(modes) if with_modes else [])


def random_valid(n: int, seed: int) -> tuple[np.ndarray, list[str]]:
    """n valid postures of the nominal design (random, both assembly modes)."""
    from planner.calibration.poses import valid_sample

    sample = valid_sample(NOMINAL, max(20 * n, 2000), seed)
    idx = np.random.default_rng(seed).choice(len(sample.q), size=n, replace=False)
    return sample.q[idx], [sample.assembly_mode[i] for i in idx]
