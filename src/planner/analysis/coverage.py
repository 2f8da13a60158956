"""Where a region map's regions reach in the linkage plane: each certified region's Cartesian
image, the union of several regions' images, and the volume they sweep as theta1 turns.

Two independent routes: :func:`cartesian_images` goes from the map's cells to the apex P of
each (forward kinematics); :func:`cartesian_coverage` goes from the points of a raster of the
plane to the map (inverse kinematics, then the cell holding each solution), so that the union
of several regions' images, which overlap across working modes, has a well-defined area
(:meth:`Coverage.area`) and volume of revolution (:meth:`Coverage.volume`). The figures of
:mod:`planner.plotting` and the "twice as large" table of ``benchmarks/regions.py`` are
drawn from these.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.analysis.regions import VALID, RegionMap
from planner.exceptions import InputError
from planner.kinematics import ASSEMBLY_MODES, WORKING_MODES

__all__ = ["Coverage", "cartesian_coverage", "cartesian_images"]


def cartesian_images(
    rmap: RegionMap, *, certified: bool = True
) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Cell centres of each region and their apex P in the linkage plane.

    Parameters
    ----------
    certified : only the surely valid cells of each region (default), else all its cells.

    Returns
    -------
    dict
        region id -> (q, p): q (K, 2) the cells' (theta2, theta3), rad; p (K, 2) P's (u, w)
        in m (u along AB, w in the plane; 3-D at theta1: (w cos theta1, u, -w sin theta1)).
    """
    from planner.kinematics import forward_batch

    out: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for region in rmap.regions:
        ai = ASSEMBLY_MODES.index(region.assembly_mode)
        mi = WORKING_MODES.index(region.working_mode)
        mask = rmap.labels[ai, mi] == region.label
        if certified:
            mask &= rmap.status[ai, mi] == VALID
        k3, k2 = np.nonzero(mask)
        q = np.stack([np.zeros(len(k2)), rmap.theta2[k2], rmap.theta3[k3]], axis=1)
        if len(q):
            fb = forward_batch(rmap.design, q, region.assembly_mode)
            p = np.stack([fb.p[:, 1], fb.w], axis=1)
        else:
            p = np.empty((0, 2))
        out[region.id] = (q[:, 1:], p)
    return out


@dataclass(frozen=True, slots=True)
class Coverage:
    """Which points of the linkage plane each certified region reaches.

    Attributes
    ----------
    u, w : shape (m,), m: centres of the square raster cells of the plane.
    pixel_area : m^2 of one raster cell.
    reached : dict region id -> shape (m, m) bool, rows w, columns u: the region's
        certified cells reach the point (inverse kinematics in the region's working mode,
        joint values shifted by multiples of 2 pi into the joint box, then looked up).
    theta1_span : rad, joint_max - joint_min of theta1 (what :meth:`volume` needs).
    """

    u: np.ndarray
    w: np.ndarray
    pixel_area: float
    reached: dict[int, np.ndarray]
    theta1_span: float = 2.0 * math.pi

    def _union(self, region_ids) -> np.ndarray | None:
        """The union (m, m) bool of the given regions' images; None for no region."""
        ids = list(region_ids)
        if not ids:
            return None
        union = np.zeros_like(self.reached[ids[0]])
        for i in ids:
            union |= self.reached[i]
        return union

    def area(self, region_ids) -> float:
        """Area (m^2) of the union of the given regions' images."""
        union = self._union(region_ids)
        return 0.0 if union is None else float(union.sum()) * self.pixel_area

    def volume(self, region_ids) -> float:
        """Volume (m^3) of the 3-D points the given regions reach as theta1 turns.

        The plane point (u, w) at theta1 is the 3-D point at distance |w| from the axis AB,
        at angle theta1 (w > 0) or theta1 + pi (w < 0) about it: with theta1 spanning a full
        turn, a region reaches every point of the circle of radius |w| through (u, |w|),
        whichever sign of w reached it. The volume is that of the solid of revolution of the
        union of the images folded onto w > 0 (Pappus: the sum of 2 pi |w| over its raster
        cells). Raises InputError when theta1 spans less than a full turn."""
        if self.theta1_span < 2.0 * math.pi * (1.0 - 1e-12):
            raise InputError(
                f"volume needs theta1 limits spanning a full turn, got {self.theta1_span:.6g} rad"
            )
        union = self._union(region_ids)
        if union is None:
            return 0.0
        folded = union | union[::-1]  # the raster is symmetric about w = 0
        upper = self.w > 0.0
        ring = 2.0 * math.pi * self.w[upper] * self.pixel_area
        return float((folded[upper].sum(axis=1) * ring).sum())


def cartesian_coverage(rmap: RegionMap, m: int = 256) -> Coverage:
    """The image of every certified region in the linkage plane, on an ``m x m`` raster.

    An independent route from :func:`cartesian_images`: it starts from the Cartesian points
    (inverse kinematics, :func:`planner.kinematics.inverse_batch`) and asks the map which
    region, if any, holds each solution, so the union of several regions' images (which
    overlap across working modes) has a well-defined area.

    Parameters
    ----------
    m : raster cells per axis over [-L0/2 - reach, L0/2 + reach] x [-reach, reach].
    """
    from planner.kinematics import inverse_batch

    d = rmap.design
    reach = d.reach
    u = np.linspace(-d.L0 / 2 - reach, d.L0 / 2 + reach, m + 1)
    w = np.linspace(-reach, reach, m + 1)
    u = 0.5 * (u[1:] + u[:-1])
    w = 0.5 * (w[1:] + w[:-1])
    uu, ww = np.meshgrid(u, w)
    p = np.stack([ww.ravel(), uu.ravel(), np.zeros(uu.size)], axis=1)  # theta1 = 0 plane
    ib = inverse_batch(d, p)
    lo, hi = np.asarray(d.joint_min), np.asarray(d.joint_max)
    two_pi = 2.0 * np.pi
    reached: dict[int, np.ndarray] = {r.id: np.zeros(uu.shape, dtype=bool) for r in rmap.regions}
    for mi in range(len(WORKING_MODES)):
        q = ib.q[:, mi, :]
        # the raster is the linkage plane (u, w): a slot reaches (u, w) itself only where its
        # axis sign is that of w (the other slot reaches the mirror point at theta1 + pi)
        ok = ib.ok[:, mi] & (np.sign(p[:, 0]) == (1 if WORKING_MODES[mi][0] == "+" else -1))
        with np.errstate(invalid="ignore"):
            shifted = q + two_pi * np.ceil((lo - q) / two_pi)
        ok &= np.all(shifted <= hi, axis=1)
        # the IK slot is the mode; its assembly mode follows from the passive angles
        asm_sign = np.sign(np.sin(ib.passive[:, mi, 1] - ib.passive[:, mi, 0]))
        for ai, sgn in ((0, 1), (1, -1)):
            sel = np.nonzero(ok & (asm_sign == sgn))[0]
            if len(sel) == 0:
                continue
            k2 = np.clip(((shifted[sel, 1] - lo[1]) / rmap.h2).astype(int), 0, rmap.n - 1)
            k3 = np.clip(((shifted[sel, 2] - lo[2]) / rmap.h3).astype(int), 0, rmap.n - 1)
            lab = rmap.certified[ai, mi][k3, k2]
            over = rmap.labels[ai, mi][k3, k2]
            hit = lab > 0
            for i, lab_over in zip(sel[hit].tolist(), over[hit].tolist(), strict=True):
                rid = int(rmap.region_index[ai, mi, lab_over])
                reached[rid].flat[i] = True
    span = float(d.joint_max[0] - d.joint_min[0])
    return Coverage(u, w, float((u[1] - u[0]) * (w[1] - w[0])), reached, span)
