"""Labelled cross-sections of the workspace: the linkage plane (u, w) and joint space
(theta2, theta3).

Each section is a regular grid of cell centres with, per cell and per *slot*, whether the slot
reaches the cell within the joint limits, kappa(A), the working-mode and assembly-mode signs, and
whether the cell is singular. The slots of a Cartesian section are the eight working modes
(inverse kinematics, :func:`planner.inverse_batch`); those of a joint section are the two
assembly modes (direct kinematics, :func:`planner.forward_batch`). These grids back the
paper's figures 8-11 and 13-14.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from planner.analysis._common import KAPPA_SINGULAR, MODE_SIGNS, within_limits_mod_2pi
from planner.design import Design
from planner.exceptions import InputError
from planner.kinematics import (
    ASSEMBLY_MODES,
    WORKING_MODES,
    conditioning,
    forward_batch,
    inverse_batch,
)

__all__ = ["Section", "cartesian_section", "joint_section"]

#: Largest grid side accepted (cells per axis): a sanity bound on memory (8 slots per cell).
MAX_GRID = 2048


@dataclass(frozen=True, slots=True)
class Section:
    """A labelled grid over one plane of the workspace.

    Attributes
    ----------
    kind : 'cartesian' | 'joint'
    x, y : shape (nx,), (ny,)
        Cell centres: (u, w) in m for a Cartesian section (u along AB, w in the linkage plane
        at ``theta1``), (theta2, theta3) in rad for a joint section.
    theta1 : float
        The plane's theta1, rad.
    labels : tuple of str, length K
        Slot names: the eight working modes (Cartesian) or the two assembly modes (joint).
    reached : shape (ny, nx, K), bool
        The slot has a posture at the cell, within the joint limits.
    kappa_A : shape (ny, nx, K)
        kappa(A) of that posture (NaN where not reached).
    working_mode : shape (ny, nx, K, 3), int8
        (s_axis, s_A, s_B) of the posture, 0 on a serial singularity or where not reached.
    assembly_mode : shape (ny, nx, K), int8
        Sign of sin(theta5 - theta4), 0 where not reached.
    singular : shape (ny, nx, K), bool
        A singularity meets the cell: kappa(A) >= ``KAPPA_SINGULAR``, a mode sign is 0, or a
        sign that flips only across a singularity differs from a reached 4-neighbour (the
        assembly sign in a Cartesian slot: parallel; a working-mode sign in a joint slot: serial).
    """

    kind: Literal["cartesian", "joint"]
    x: np.ndarray
    y: np.ndarray
    theta1: float
    labels: tuple[str, ...]
    reached: np.ndarray
    kappa_A: np.ndarray
    working_mode: np.ndarray
    assembly_mode: np.ndarray
    singular: np.ndarray

    @property
    def best_kappa(self) -> np.ndarray:
        """Shape (ny, nx): smallest kappa(A) over the reaching slots (NaN where none)."""
        k = np.where(self.reached, self.kappa_A, np.inf).min(axis=-1)
        return np.where(np.isfinite(k) | self.reached.any(axis=-1), k, np.nan)

    def slot(self, label: str) -> int:
        """Index of a slot label ('+-+' or '+'/'-')."""
        try:
            return self.labels.index(label)
        except ValueError:
            raise InputError(f"label must be one of {self.labels}, got {label!r}") from None


def _grid_side(name: str, n: int) -> int:
    if not (isinstance(n, int | np.integer) and 2 <= n <= MAX_GRID):
        raise InputError(f"{name} must be an integer in [2, {MAX_GRID}], got {n!r}")
    return int(n)


def _centres(lo: float, hi: float, n: int) -> np.ndarray:
    step = (hi - lo) / n
    return lo + step * (np.arange(n) + 0.5)


def _flips(sign: np.ndarray, reached: np.ndarray) -> np.ndarray:
    """Cells (ny, nx, K) whose sign differs from a reached 4-neighbour in the same slot."""
    out = np.zeros(sign.shape, dtype=bool)
    for axis in (0, 1):
        a = np.swapaxes(sign, 0, axis)
        r = np.swapaxes(reached, 0, axis)
        o = np.swapaxes(out, 0, axis)
        diff = (a[1:] != a[:-1]) & r[1:] & r[:-1]
        o[1:] |= diff
        o[:-1] |= diff
    return out


def _labelled(
    kind: Literal["cartesian", "joint"],
    x: np.ndarray,
    y: np.ndarray,
    theta1: float,
    labels: tuple[str, ...],
    reached: np.ndarray,
    kappa: np.ndarray,
    wm: np.ndarray,
    am: np.ndarray,
) -> Section:
    wm = np.where(reached[..., None], wm, 0).astype(np.int8)
    am = np.where(reached, am, 0).astype(np.int8)
    kappa = np.where(reached, kappa, np.nan)
    with np.errstate(invalid="ignore"):
        singular = reached & ((kappa >= KAPPA_SINGULAR) | np.any(wm == 0, axis=-1) | (am == 0))
    if kind == "cartesian":
        singular |= _flips(am, reached)
    else:
        for i in range(3):
            singular |= _flips(wm[..., i], reached)
    return Section(kind, x, y, float(theta1), labels, reached, kappa, wm, am, singular)


def cartesian_section(
    design: Design,
    n: int = 256,
    *,
    theta1: float = 0.0,
    extent: tuple[float, float, float, float] | None = None,
    joint_limits: bool = True,
) -> Section:
    """The linkage plane at ``theta1`` as a labelled (u, w) grid of n x n cells.

    Parameters
    ----------
    design : Design
    n : int
        Cells per axis.
    theta1 : float
        The plane, rad. A cell reaches in a working mode only with the posture whose theta1 is
        this plane's (``s_axis = sign w``); its theta1 must pass the limits.
    extent : (u_min, u_max, w_min, w_max), m, optional
        Default: the workspace's bounding box plus 5 %.
    joint_limits : bool
        Apply the design's joint limits (any 2-pi shift of a joint may be used).

    Returns
    -------
    Section
        ``kind='cartesian'``, x = u, y = w, slots = the eight working modes.
    """
    n = _grid_side("n", n)
    if not math.isfinite(theta1):
        raise InputError(f"theta1 must be finite, got {theta1}")
    if extent is None:
        half_len = max(design.reach - design.L0 / 2, 1e-3 * design.reach)
        radius = math.sqrt(max(design.reach**2 - design.L0**2 / 4, (1e-3 * design.reach) ** 2))
        extent = (-1.05 * half_len, 1.05 * half_len, -1.05 * radius, 1.05 * radius)
    ext = np.asarray(extent, dtype=float)
    if ext.shape != (4,) or not np.all(np.isfinite(ext)) or ext[0] >= ext[1] or ext[2] >= ext[3]:
        raise InputError(f"extent must be finite (u_min < u_max, w_min < w_max), got {extent}")
    u = _centres(ext[0], ext[1], n)
    w = _centres(ext[2], ext[3], n)
    uu, ww = np.meshgrid(u, w)
    p = np.stack([ww * math.cos(theta1), uu, -ww * math.sin(theta1)], axis=-1).reshape(-1, 3)
    batch = inverse_batch(design, p, theta1_on_axis=theta1)
    side = np.sign(ww.reshape(-1))
    in_plane = np.where(side[:, None] >= 0, MODE_SIGNS[None, :, 0] > 0, MODE_SIGNS[None, :, 0] < 0)
    reached = batch.ok & in_plane
    if joint_limits:
        reached &= within_limits_mod_2pi(design, batch.q)
    kappa = conditioning(design, batch.q, batch.passive, batch.w).kappa_A
    shape = (n, n, len(WORKING_MODES))
    return _labelled(
        "cartesian",
        u,
        w,
        theta1,
        WORKING_MODES,
        reached.reshape(shape),
        kappa.reshape(shape),
        batch.working_mode_signs.reshape(*shape, 3),
        batch.assembly_mode_signs.reshape(shape),
    )


def joint_section(
    design: Design,
    n: int = 256,
    *,
    theta1: float = 0.0,
    extent: tuple[float, float, float, float] | None = None,
    joint_limits: bool = True,
) -> Section:
    """Joint space (theta2, theta3) at ``theta1`` as a labelled grid of n x n cells.

    Parameters
    ----------
    design : Design
    n : int
        Cells per axis.
    theta1 : float
        rad; the planar quantities do not depend on it.
    extent : (theta2_min, theta2_max, theta3_min, theta3_max), rad, optional
        Default: the design's joint limits of theta2 and theta3.
    joint_limits : bool
        Mark cells outside the literal joint limits (or theta1 outside its limits) unreached.

    Returns
    -------
    Section
        ``kind='joint'``, x = theta2, y = theta3, slots = the two assembly modes.
    """
    n = _grid_side("n", n)
    if not math.isfinite(theta1):
        raise InputError(f"theta1 must be finite, got {theta1}")
    if extent is None:
        extent = (
            design.joint_min[1],
            design.joint_max[1],
            design.joint_min[2],
            design.joint_max[2],
        )
    ext = np.asarray(extent, dtype=float)
    if ext.shape != (4,) or not np.all(np.isfinite(ext)) or ext[0] >= ext[1] or ext[2] >= ext[3]:
        raise InputError(f"extent must be finite (min < max on each axis), got {extent}")
    t2 = _centres(ext[0], ext[1], n)
    t3 = _centres(ext[2], ext[3], n)
    g2, g3 = np.meshgrid(t2, t3)
    q = np.stack([np.full(g2.size, theta1), g2.ravel(), g3.ravel()], axis=1)
    slots = []
    for mode in ASSEMBLY_MODES:
        b = forward_batch(design, q, mode)
        ok = b.ok.copy()
        if joint_limits:
            ok &= np.all((q >= design.joint_min) & (q <= design.joint_max), axis=1)
        kappa = conditioning(design, b.q, b.passive, b.w).kappa_A
        slots.append((ok, kappa, b.working_mode_signs, b.assembly_mode_signs))
    shape = (n, n, len(ASSEMBLY_MODES))
    return _labelled(
        "joint",
        t2,
        t3,
        theta1,
        ASSEMBLY_MODES,
        np.stack([s[0] for s in slots], axis=-1).reshape(shape),
        np.stack([s[1] for s in slots], axis=-1).reshape(shape),
        np.stack([s[2] for s in slots], axis=1).reshape(*shape, 3),
        np.stack([s[3] for s in slots], axis=-1).reshape(shape),
    )
