"""Bounds on the apex P and the distal links' midpoints over a cell of (theta2, theta3).

Over every posture of a closed cell of the region map that lies inside the kappa(A) band (the
only postures that can be valid), P = (C + D) / 2 + s g(|CD|) J (D - C),
g(d) = sqrt(L2^2 / d^2 - 1/4), lies in a planar rectangle of the loop's plane, bounded by
interval arithmetic: C, D and D - C move by at most L1 a2, L1 a3, L1 (a2 + a3) (a2, a3 the
half-widths), and g is decreasing, taken on the part of the cell's |CD| interval inside the
band. The midpoints of C-P and D-P follow. Two proofs use these rectangles: the region map
with obstacles (:mod:`planner.analysis.obstacle_regions`: a link point inside an obstacle)
and the goal cells of a goal tolerance (:mod:`planner.analysis.goal_cells`: which cells can
put P near a target point).
"""

from __future__ import annotations

import numpy as np

from planner.analysis import regions as R
from planner.design import Design
from planner.validity import Margins

__all__ = ["REL_SLACK", "point_sets"]

#: Relative inflation of half-widths (rounding, points on a cell's edge).
REL_SLACK = 1e-9


def _interval_product(a0, a1, b0, b1):
    p = np.stack([a0 * b0, a0 * b1, a1 * b0, a1 * b1])
    return p.min(axis=0), p.max(axis=0)


def point_sets(
    design: Design, margins: Margins, rmap: R.RegionMap, assembly_mode: str
) -> np.ndarray:
    """Shape (n, n, 3, 4) [k3, k2]: planar rectangles (u_lo, u_hi, w_lo, w_hi) of the loop's
    plane holding P, the midpoint of C-P and the midpoint of D-P at every posture of the
    2-D cell inside the kappa(A) band (NaN where no posture of the cell is in the band)."""
    L0, L1, L2 = design.L0, design.L1, design.L2
    a2 = 0.5 * rmap.h2 * (1.0 + REL_SLACK)
    a3 = 0.5 * rmap.h3 * (1.0 + REL_SLACK)
    t3, t2 = np.meshgrid(rmap.theta3, rmap.theta2, indexing="ij")
    c2, s2, c3, s3 = np.cos(t2), np.sin(t2), np.cos(t3), np.sin(t3)
    cu, cw = -0.5 * L0 + L1 * c2, L1 * s2
    du, dw = 0.5 * L0 + L1 * c3, L1 * s3
    rc, rd, re = L1 * a2, L1 * a3, L1 * (a2 + a3)
    eu, ew = du - cu, dw - cw
    d = np.hypot(eu, ew)
    lo, hi = margins.cd_range
    d_lo = np.maximum(d - re, 2.0 * L2 * lo)
    d_hi = np.minimum(d + re, 2.0 * L2 * hi)
    inside = d_lo <= d_hi
    with np.errstate(invalid="ignore", divide="ignore"):
        g_lo = np.sqrt(np.maximum(L2 * L2 / (d_hi * d_hi) - 0.25, 0.0))
        g_hi = np.sqrt(np.maximum(L2 * L2 / (d_lo * d_lo) - 0.25, 0.0))
    s = 1.0 if assembly_mode == "+" else -1.0
    # P = (C + D) / 2 + s g (-e_w, e_u)
    gw0, gw1 = _interval_product(g_lo, g_hi, ew - re, ew + re)
    gu0, gu1 = _interval_product(g_lo, g_hi, eu - re, eu + re)
    mu, mw = 0.5 * (cu + du), 0.5 * (cw + dw)
    half = 0.5 * (rc + rd)
    if s > 0:
        pu0, pu1 = mu - half - gw1, mu + half - gw0
        pw0, pw1 = mw - half + gu0, mw + half + gu1
    else:
        pu0, pu1 = mu - half + gw0, mu + half + gw1
        pw0, pw1 = mw - half - gu1, mw + half - gu0
    out = np.full((*t2.shape, 3, 4), np.nan)
    out[..., 0, :] = np.stack([pu0, pu1, pw0, pw1], axis=-1)
    for m, (xu, xw, r) in enumerate(((cu, cw, rc), (du, dw, rd)), start=1):
        out[..., m, :] = np.stack(
            [
                0.5 * (xu - r + pu0),
                0.5 * (xu + r + pu1),
                0.5 * (xw - r + pw0),
                0.5 * (xw + r + pw1),
            ],
            axis=-1,
        )
    out[~inside] = np.nan
    return out
