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
from planner.dynamics.inverse import inverse_dynamics, mass_matrix
from planner.dynamics.serial import SerialArm, serial_coordinates, serial_motion
from planner.exceptions import InputError
from planner.kinematics import WORKING_MODES, conditioning, forward_batch

__all__ = [
    "InertiaMap",
    "SerialComparison",
    "TorqueStats",
    "cycle_torques",
    "inertia_map",
    "serial_comparison",
    "torque_stats",
]


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


@dataclass(frozen=True, eq=False)
class SerialComparison:
    """The largest eigenvalue of M over the (theta2, theta3) grid of one assembly mode, for the
    five-bar and for its serial counterpart in the same postures (leg A of each posture,
    :class:`~planner.dynamics.serial.SerialArm`), with each cell's working mode.

    Attributes
    ----------
    theta2, theta3 : shape (n,), rad -- the grid's axes (the design's joint limits)
    parallel, serial : shape (n, n), kg m^2 -- largest eigenvalue of each robot's M; NaN
        outside the cells compared
    parallel_planar, serial_planar : shape (n, n), kg m^2 -- the same of the planar block
        (the theta2, theta3 rows and columns: what the shoulder and the elbow, or the two
        base motors, see; M has no coupling between theta1 and them)
    working_mode : shape (n, n), int -- index into :data:`~planner.kinematics.WORKING_MODES`
        of each compared cell, -1 elsewhere (not assembled, or outside the margins)
    assembly_mode : '+' or '-'
    """

    theta2: np.ndarray
    theta3: np.ndarray
    parallel: np.ndarray
    serial: np.ndarray
    parallel_planar: np.ndarray
    serial_planar: np.ndarray
    working_mode: np.ndarray
    assembly_mode: str

    def by_mode(self) -> dict[str, dict[str, float]]:
        """Per working mode with compared cells: ``cells`` and, for ``parallel``, ``serial``,
        ``parallel_planar`` and ``serial_planar``, the median, 95th percentile and maximum of
        the largest eigenvalue (keys ``<name>_median`` ...), and ``ratio_median`` and
        ``planar_ratio_median`` (medians over the cells of parallel / serial)."""
        out: dict[str, dict[str, float]] = {}
        for k, label in enumerate(WORKING_MODES):
            cell = self.working_mode == k
            if not np.any(cell):
                continue
            row = {"cells": float(np.count_nonzero(cell))}
            for name in ("parallel", "serial", "parallel_planar", "serial_planar"):
                v = getattr(self, name)[cell]
                row[f"{name}_median"] = float(np.median(v))
                row[f"{name}_p95"] = float(np.percentile(v, 95))
                row[f"{name}_max"] = float(np.max(v))
            row["ratio_median"] = float(np.median(self.parallel[cell] / self.serial[cell]))
            row["planar_ratio_median"] = float(
                np.median(self.parallel_planar[cell] / self.serial_planar[cell])
            )
            out[label] = row
        return out


def serial_comparison(
    design: Design,
    inertia: Inertia,
    *,
    arm: SerialArm | None = None,
    assembly_mode: str = "+",
    resolution: int = 64,
    kappa_max: float = 10.0,
    serial_min: float = 0.05,
) -> SerialComparison:
    """The reflected inertia of the five-bar against its serial counterpart over the
    workspace: on the (theta2, theta3) grid of :func:`inertia_map` (theta1 = 0: neither M
    depends on it), the largest eigenvalue of each robot's M in the cells where the five-bar
    assembles with kappa(A) <= ``kappa_max`` and every serial measure >= ``serial_min`` (the
    postures a plan may use under such margins; the defaults are the product's). ``arm``:
    the counterpart (default ``SerialArm(design, inertia)``: the documented elbow motor)."""
    imap = inertia_map(design, inertia, assembly_mode=assembly_mode, resolution=resolution)
    arm = arm if arm is not None else SerialArm(design, inertia)
    n = imap.theta2.shape[0]
    g2, g3 = np.meshgrid(imap.theta2, imap.theta3, indexing="ij")
    q = np.stack([np.zeros(n * n), g2.ravel(), g3.ravel()], axis=1)
    fb = forward_batch(design, q, assembly_mode)
    c = conditioning(design, fb.q, fb.passive, fb.w)
    m_par = mass_matrix(design, inertia, q, assembly_mode=assembly_mode)
    par = imap.eigenvalues[..., -1].ravel()
    keep = fb.ok & np.isfinite(par)
    keep &= np.nan_to_num(c.kappa_A, nan=np.inf) <= kappa_max
    keep &= np.nan_to_num(c.min_serial, nan=0.0) >= serial_min
    signs = fb.working_mode_signs
    index = np.full(n * n, -1)
    labels = {m: k for k, m in enumerate(WORKING_MODES)}
    for i in np.flatnonzero(keep):
        index[i] = labels["".join("+" if s > 0 else "-" for s in signs[i])]
    ser, par_planar, ser_planar = (np.full(n * n, np.nan) for _ in range(3))
    if np.any(keep):
        m_ser = arm.mass_matrix(serial_coordinates(fb.q[keep], fb.passive[keep]))
        ser[keep] = np.linalg.eigvalsh(m_ser)[:, -1]
        ser_planar[keep] = np.linalg.eigvalsh(m_ser[:, 1:, 1:])[:, -1]
        par_planar[keep] = np.linalg.eigvalsh(m_par[keep][:, 1:, 1:])[:, -1]
    par = np.where(keep, par, np.nan)
    return SerialComparison(
        imap.theta2,
        imap.theta3,
        par.reshape(n, n),
        ser.reshape(n, n),
        par_planar.reshape(n, n),
        ser_planar.reshape(n, n),
        index.reshape(n, n),
        assembly_mode,
    )


def cycle_torques(
    design: Design,
    inertia: Inertia,
    t: np.ndarray,
    q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    *,
    assembly_mode: str = "+",
    gravity: object = (0.0, 0.0, -9.81),
    arm: SerialArm | None = None,
) -> tuple[TorqueStats, TorqueStats]:
    """Peak and RMS torque per actuator of one motion of P, for the five-bar (its motion
    samples (M, 3) at times t (M,)) and for its serial counterpart moving P the same way
    (:func:`~planner.dynamics.serial.serial_motion`): (five-bar, serial)."""
    arm = arm if arm is not None else SerialArm(design, inertia)
    tau = inverse_dynamics(
        design, inertia, q, qd, qdd, assembly_mode=assembly_mode, gravity=gravity
    ).tau
    qs, qsd, qsdd = serial_motion(design, q, qd, qdd, assembly_mode)
    tau_s = arm.inverse_dynamics(qs, qsd, qsdd, gravity=gravity)
    if not (np.all(np.isfinite(tau)) and np.all(np.isfinite(tau_s))):
        raise InputError("the motion passes a posture where the five-bar does not assemble")
    return torque_stats(t, tau), torque_stats(t, tau_s)
