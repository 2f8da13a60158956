"""The design side of the dynamics: how large the inertia the motors see gets over the
workspace, and the peak and RMS torque of a motion.

M(q) does not depend on theta1 (the planar linkage's geometry does not; theta1 only turns
it, and gravity is in h, not in M), so the map of M over the (theta2, theta3) square of one
assembly mode is the whole story (:func:`inertia_map`), like the isoconditioning maps of
kappa(A).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.design import Design
from planner.dynamics.inertia import Inertia
from planner.dynamics.inverse import mass_matrix
from planner.exceptions import InputError

__all__ = ["InertiaMap", "TorqueStats", "inertia_map", "torque_stats"]


@dataclass(frozen=True, eq=False)
class InertiaMap:
    """Eigenvalues of M(q) over the (theta2, theta3) grid of one assembly mode.

    Attributes
    ----------
    theta2, theta3 : shape (n,), rad -- the grid's axes (within the design's joint limits)
    eigenvalues : shape (n, n, 3), kg m^2 -- ascending; NaN where the posture does not
        assemble or is parallel-singular (row i: theta2[i], column j: theta3[j])
    """

    theta2: np.ndarray
    theta3: np.ndarray
    eigenvalues: np.ndarray

    @property
    def largest(self) -> float:
        """The largest eigenvalue over the map, kg m^2 (NaN if nothing assembles)."""
        return (
            float(np.nanmax(self.eigenvalues)) if np.any(np.isfinite(self.eigenvalues)) else np.nan
        )


def inertia_map(
    design: Design, inertia: Inertia, *, assembly_mode: str = "+", resolution: int = 64
) -> InertiaMap:
    """M's eigenvalues on a ``resolution`` x ``resolution`` grid of (theta2, theta3) over the
    design's joint limits (theta1 = 0: M does not depend on it)."""
    if not 2 <= int(resolution) <= 1024:
        raise InputError(f"resolution must lie in [2, 1024], got {resolution}", field="resolution")
    n = int(resolution)
    t2 = np.linspace(design.joint_min[1], design.joint_max[1], n)
    t3 = np.linspace(design.joint_min[2], design.joint_max[2], n)
    g2, g3 = np.meshgrid(t2, t3, indexing="ij")
    q = np.stack([np.zeros(n * n), g2.ravel(), g3.ravel()], axis=1)
    m = mass_matrix(design, inertia, q, assembly_mode=assembly_mode)
    ok = np.all(np.isfinite(m), axis=(1, 2))
    eig = np.full((n * n, 3), np.nan)
    eig[ok] = np.linalg.eigvalsh(m[ok])
    return InertiaMap(t2, t3, eig.reshape(n, n, 3))


@dataclass(frozen=True, eq=False)
class TorqueStats:
    """Peak |tau_j| and RMS tau_j over a motion, N m, shape (3,) each."""

    peak: np.ndarray
    rms: np.ndarray


def torque_stats(t: np.ndarray, tau: np.ndarray) -> TorqueStats:
    """Peak and RMS torque per actuator of samples ``tau`` (M, 3) at times ``t`` (M,), the
    RMS as a time average (trapezoid rule: uneven sample spacing counts by duration)."""
    t = np.asarray(t, dtype=float)
    tau = np.asarray(tau, dtype=float)
    if t.ndim != 1 or t.shape[0] < 2 or tau.shape != (t.shape[0], 3):
        raise InputError(f"need t (M,) with M >= 2 and tau (M, 3), got {t.shape}, {tau.shape}")
    duration = float(t[-1] - t[0])
    if not duration > 0:
        raise InputError("t must span a positive duration")
    mean_square = np.trapezoid(tau**2, t, axis=0) / duration
    return TorqueStats(np.max(np.abs(tau), axis=0), np.sqrt(mean_square))
