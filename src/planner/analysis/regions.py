"""Region maps: the certified valid set of each working mode in joint space, its connected
regions, the serial transits between them, and proofs that no path exists.

Why a 2-D map covers the whole problem
--------------------------------------
Without obstacles every validity rule of :mod:`planner.validity` but theta1's joint limit
depends on (theta2, theta3) and the assembly mode only: |CD| (the kappa(A) band and the
loop closure) is a function of C and D, and so are the apex P in the linkage plane (u, w),
the passive angles theta4, theta5 and the three serial measures w / (L1 + L2),
sin(theta4 - theta2), sin(theta5 - theta3). theta1 only turns the plane about AB: the 3-D
point is P = (w cos theta1, u, -w sin theta1). In particular the axis sign s_axis = sign w
is a function of (theta2, theta3) too, so every cell of the map carries the full working
mode (s_axis, s_A, s_B): the 2-D map of one assembly mode covers all eight working modes. A
Cartesian point is reached with w > 0 at theta1 and with w < 0 at theta1 + pi, by two
different (theta2, theta3): that is how the two axis signs share one target. The valid set of
mode M in 3-D is the product [theta1_min, theta1_max] x V_M(theta2, theta3) (an interval times
the 2-D set), so its connected components are those of V_M, one for one.

Cells and bounds
----------------
The grid has ``n x n`` closed cells over the literal joint box [joint_min, joint_max] of
(theta2, theta3) (limits are never wrapped: theta = pi and theta = -pi are different joint
values, so a region that crosses +-pi in angle is cut there). Each cell is classified per
assembly mode and working mode, for every posture of the closed cell at once, with bounds
that need no path inside the cell (:func:`_cell_bounds`):

* |CD| moves by at most L1 (|dtheta2| + |dtheta3|) (C and D turn on circles of radius L1),
  so |CD| over the cell lies within the centre's value +- L1 (a2 + a3), a2, a3 the half-widths.
  The kappa(A) rule is the band 2 L2 [lo, hi] on |CD| (``Margins.cd_range``), which also
  implies the loop closure.
* With e = D - C and g(d) = sqrt(L2^2 / d^2 - 1/4) (decreasing in d = |e|), the apex is
  P = (C + D) / 2 + s g(d) J e (s the assembly sign, J the quarter turn), and each signed
  serial measure has the closed form U + s g(d) V:

  - w / (L1 + L2): U = L1 (sin theta2 + sin theta3) / 2, V = e_u = L0 + L1 cos theta3 - L1 cos theta2;
  - sin(theta4 - theta2) = [X / 2 + s g Y] / L2 with X = L1 sin(theta3 - theta2) - L0 sin theta2,
    Y = L0 cos theta2 + L1 cos(theta3 - theta2) - L1 (cross and dot products of AC with CD);
  - sin(theta5 - theta3) = [-X' / 2 + s g Y'] / L2 with X' = L1 sin(theta3 - theta2) - L0 sin theta3,
    Y' = L0 cos theta3 + L1 - L1 cos(theta3 - theta2).

  U, V, X, Y are trigonometric polynomials with explicit Lipschitz constants (e.g.
  |dX| <= L1 (a2 + a3) + L0 a2); g is evaluated on the part of the cell's |CD| interval that
  lies inside the kappa band, because only those postures can be valid. Interval products
  then bound every measure over every *possibly valid* posture of the cell, a rigorous bound
  that, unlike the motion certificate of :meth:`ValidityChecker.check_motion` (same |CD|
  constant, passive-angle rates through a path in the band), needs no path in the band, so
  it also works in cells that straddle the band's edge.

A cell is *surely valid* in mode M when the whole |CD| interval is inside the band and every
signed measure's lower bound is >= ``serial_min``; *surely invalid* when the |CD| interval
misses the band, or some signed measure's upper bound over the possibly valid postures is
below ``serial_min``; *undecided* otherwise. Half-widths are inflated by a relative 1e-9 and
bounds by an absolute 1e-12, for rounding and for points on a cell's edge.

Regions, transits and the union graph
-------------------------------------
Closed cells that share an edge or a corner intersect, so the union of a set of closed cells
is connected along 8-connected cell components. *Regions* are the 8-connected components of
the over-approximation (surely valid + undecided) of V_M, per assembly and working mode; the
components of the surely valid cells are *certified regions*: every posture of them is valid
and any two are joined by a valid path (through shared corners, all valid).

A mode change crosses one serial surface: the flipped measure goes through zero while the
non-serial rules and the other two signed measures (>= ``serial_min``) hold, which is what
:mod:`planner.planning.modes` builds. For flip j of mode M that set is
B = {kappa band, s_k m_k >= serial_min for k != j}; it contains V_M and V_M' (M' = M with sign j
flipped), and two such sets for different sign pairs meet only inside a V. The over-
approximation of B (cells not surely outside it) splits into 8-connected components; a
*transit* joins two regions of M and M' that lie in one component of B, and is labelled with
the kinds (``P_on_axis``, ``leg_A_stretched``, ...) of the cells of that component where the
flipped measure may vanish. Regions joined by transits (and regions of one mode joined
through B) form the components of the *union graph*.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit
from scipy import ndimage

from planner.design import Design
from planner.exceptions import InputError
from planner.kinematics import ASSEMBLY_MODES, WORKING_MODES
from planner.transits import TRANSIT_KINDS
from planner.validity import Margins

__all__ = [
    "DEFAULT_RESOLUTION",
    "INVALID",
    "UNDECIDED",
    "VALID",
    "Coverage",
    "Region",
    "RegionMap",
    "RegionTransit",
    "cartesian_coverage",
    "cartesian_images",
    "clear_cache",
    "locate",
    "prove_disconnected",
    "region_map",
]

#: Cells per axis of a region map by default.
DEFAULT_RESOLUTION = 256
#: Sub-cells per axis on which an undecided cell is bounded again.
DEFAULT_REFINE = 4
#: Largest accepted cells per axis (memory: 2 x 8 x n^2 bytes of status).
MAX_RESOLUTION = 2048
#: Cell status codes of :attr:`RegionMap.status`.
INVALID, UNDECIDED, VALID = 0, 1, 2

_MODE_SIGNS = np.array([[1 if c == "+" else -1 for c in m] for m in WORKING_MODES], dtype=np.int8)
_MODE_INDEX = {m: k for k, m in enumerate(WORKING_MODES)}
_FLIP_NAMES = ("axis", "A", "B")
_EIGHT = np.ones((3, 3), dtype=bool)
_REL_SLACK = 1e-9
_ABS_SLACK = 1e-12
_CACHE_SIZE = 16


@dataclass(frozen=True, slots=True)
class Region:
    """One connected region: an 8-connected component of cells of one working mode.

    Attributes
    ----------
    id : index in :attr:`RegionMap.regions`.
    assembly_mode : '+' | '-'
    working_mode : e.g. '+-+'
    label : its label in ``RegionMap.labels[assembly, mode]`` (1-based).
    cells : number of cells (surely valid + undecided).
    valid_cells : number of surely valid cells in it.
    component : its component of the union graph (regions joined by transits).
    """

    id: int
    assembly_mode: str
    working_mode: str
    label: int
    cells: int
    valid_cells: int
    component: int


@dataclass(frozen=True, slots=True)
class RegionTransit:
    """Two regions of one assembly mode whose working modes differ by the sign ``flipped``,
    joined inside one component of that flip's transit set.

    Attributes
    ----------
    a, b : region ids (``a`` in the mode whose flipped sign is '+').
    flipped : 'axis' | 'A' | 'B'
    kinds : wire names of the serial surfaces the flipped measure may vanish on there.
    cells : number of cells of that component where the flipped measure may vanish, per kind
        (same order as ``kinds``).
    """

    a: int
    b: int
    flipped: str
    kinds: tuple[str, ...]
    cells: tuple[int, ...]


@dataclass(frozen=True, slots=True, eq=False)
class RegionMap:
    """The region map of a design with its margins and joint limits (no obstacles).

    Arrays are indexed ``[assembly, mode, k3, k2]``: assembly 0 '+', 1 '-'; mode the index in
    :data:`planner.kinematics.WORKING_MODES`; rows theta3, columns theta2 (as
    :func:`planner.analysis.sections.joint_section`). All arrays are read-only.

    Attributes
    ----------
    design, margins, n
    theta2, theta3 : shape (n,), rad: cell centres.
    h2, h3 : cell widths, rad.
    status : shape (2, 8, n, n), int8: :data:`INVALID`, :data:`UNDECIDED`, :data:`VALID`.
    labels : shape (2, 8, n, n), int32: region label (1-based, 0 where surely invalid).
    certified : shape (2, 8, n, n), int32: label of the certified region (surely valid
        cells; 0 elsewhere).
    centre_mode : shape (2, n, n), int8: working mode index of the cell centre's posture
        (-1 where the loop does not close in the kappa band, or a sign is 0).
    transit_cells : shape (2, 3, n, n), int8: per flip (axis, A, B), 1 + the index in
        :data:`planner.transits.TRANSIT_KINDS` of the kind at the cell centre where the flipped
        measure may vanish with the other two >= serial_min, in a component of the transit
        set that joins regions of both modes; 0 elsewhere.
    regions : tuple of :class:`Region`.
    transits : tuple of :class:`RegionTransit`.
    region_index : shape (2, 8, L + 1), int32: region id of label l (-1 for l = 0).
    measure_low, measure_high : shape (2, 3, n, n): bounds of the serial measures
        (w / (L1 + L2), sin(theta4 - theta2), sin(theta5 - theta3)) over the postures of each
        cell inside the kappa band (NaN where none is).
    """

    design: Design
    margins: Margins
    n: int
    theta2: np.ndarray
    theta3: np.ndarray
    h2: float
    h3: float
    status: np.ndarray
    labels: np.ndarray
    certified: np.ndarray
    centre_mode: np.ndarray
    transit_cells: np.ndarray
    regions: tuple[Region, ...]
    transits: tuple[RegionTransit, ...]
    region_index: np.ndarray
    measure_low: np.ndarray
    measure_high: np.ndarray

    def regions_of(self, assembly_mode: str, working_mode: str) -> list[Region]:
        """The regions of one assembly and working mode, largest first."""
        out = [
            r
            for r in self.regions
            if r.assembly_mode == assembly_mode and r.working_mode == working_mode
        ]
        return sorted(out, key=lambda r: -r.cells)

    def region_count(self, *, certified: bool = False) -> np.ndarray:
        """Shape (2, 8), int: number of regions (or certified regions) per assembly and mode."""
        src = self.certified if certified else self.labels
        return src.reshape(2, 8, -1).max(axis=-1).astype(int)

    def cell_of(self, q: np.ndarray) -> tuple[int, int] | None:
        """(k3, k2) of the cell holding posture q (3,) rad (its theta1 ignored), or None when
        (theta2, theta3) lie outside the joint box."""
        return locate(self, q)


# ----------------------------------------------------------------------------- bounds
@njit(cache=True, nogil=True, inline="always")
def _cell_bounds(
    L0, L1, L2, b_lo, b_hi, s, c2, s2, c3, s3, a2, a3, m_lo, m_hi, cen
):  # pragma: no cover
    """Bounds over one closed cell (centre trig values, half-widths a2, a3 rad), written
    into m_lo, m_hi (the serial measures over the cell's postures in the kappa band) and cen
    (their values at the centre, |CD| clipped into the band). Returns (sure, miss, d): the
    whole cell is in the band, none of it is, and |CD| at the centre."""
    c32 = c3 * c2 + s3 * s2
    s32 = s3 * c2 - c3 * s2
    e_u = L0 + L1 * (c3 - c2)
    e_w = L1 * (s3 - s2)
    d = math.sqrt(e_u * e_u + e_w * e_w)
    r = L1 * (a2 + a3)
    d_lo, d_hi = d - r, d + r
    sure = d_lo >= b_lo and d_hi <= b_hi
    miss = d_hi < b_lo or d_lo > b_hi
    if miss:
        return sure, miss, d
    dv_lo = min(max(d_lo, b_lo), b_hi)
    dv_hi = min(max(d_hi, b_lo), b_hi)
    g_lo = math.sqrt(max(L2 * L2 / (dv_hi * dv_hi) - 0.25, 0.0))
    g_hi = math.sqrt(max(L2 * L2 / (dv_lo * dv_lo) - 0.25, 0.0))
    dc = min(max(d, b_lo), b_hi)
    g_c = math.sqrt(max(L2 * L2 / (dc * dc) - 0.25, 0.0))
    x_a = L1 * s32 - L0 * s2
    y_a = L0 * c2 + L1 * c32 - L1
    x_b = L1 * s32 - L0 * s3
    y_b = L0 * c3 + L1 - L1 * c32
    for k in range(3):
        if k == 0:
            u, r_u, v, r_v, norm = 0.5 * L1 * (s2 + s3), 0.5 * r, e_u, r, L1 + L2
        elif k == 1:
            u, r_u, v, r_v, norm = 0.5 * x_a, 0.5 * (r + L0 * a2), y_a, r + L0 * a2, L2
        else:
            u, r_u, v, r_v, norm = -0.5 * x_b, 0.5 * (r + L0 * a3), y_b, r + L0 * a3, L2
        v_lo, v_hi = v - r_v, v + r_v
        p_lo = v_lo * g_hi if v_lo < 0.0 else v_lo * g_lo
        p_hi = v_hi * g_hi if v_hi > 0.0 else v_hi * g_lo
        if s < 0:
            p_lo, p_hi = -p_hi, -p_lo
        m_lo[k] = (u - r_u + p_lo) / norm
        m_hi[k] = (u + r_u + p_hi) / norm
        cen[k] = (u + s * g_c * v) / norm
    if sure:
        # centred form along straight paths inside the cell, all of it in the band
        rl, rh = d_lo / (2.0 * L2), min(d_hi / (2.0 * L2), 1.0)
        s_apex = min(
            2.0 * rl * math.sqrt(max(1.0 - rl * rl, 0.0)),
            2.0 * rh * math.sqrt(max(1.0 - rh * rh, 0.0)),
        )
        if s_apex > 0.0:
            r45 = r / (L2 * s_apex)
            m_lo[0] = max(m_lo[0], cen[0] - (L1 * min(a2, a3) + L2 * r45) / (L1 + L2))
            m_hi[0] = min(m_hi[0], cen[0] + (L1 * min(a2, a3) + L2 * r45) / (L1 + L2))
            m_lo[1] = max(m_lo[1], cen[1] - (r45 + a2))
            m_hi[1] = min(m_hi[1], cen[1] + (r45 + a2))
            m_lo[2] = max(m_lo[2], cen[2] - (r45 + a3))
            m_hi[2] = min(m_hi[2], cen[2] + (r45 + a3))
    for k in range(3):
        m_lo[k] -= 1e-12
        m_hi[k] += 1e-12
    # kinds at the centre: cos(theta4 - theta2), cos(theta5 - theta3) signs in cen[3], cen[4]
    cen[3] = 0.5 * y_a - s * g_c * x_a
    cen[4] = -0.5 * y_b - s * g_c * x_b
    return sure, miss, d


@njit(cache=True, nogil=True, inline="always")
def _decide(sure, miss, m_lo, m_hi, smin, mode_signs, st, bp):  # pragma: no cover
    """Per-mode status (st, 8) and transit-set passability (bp, 12) of one cell from its
    bounds."""
    if miss:
        for mi in range(8):
            st[mi] = 0
        for b in range(12):
            bp[b] = False
        return
    for mi in range(8):
        valid = sure
        invalid = False
        for k in range(3):
            if mode_signs[mi, k] > 0:
                lo_k, hi_k = m_lo[k], m_hi[k]
            else:
                lo_k, hi_k = -m_hi[k], -m_lo[k]
            if lo_k < smin:
                valid = False
            if hi_k < smin:
                invalid = True
        st[mi] = 0 if invalid else (2 if valid else 1)
    for j in range(3):
        o1 = 1 if j == 0 else 0
        o2 = 1 if j == 2 else 2
        for c in range(4):
            h1 = -m_lo[o1] if c >= 2 else m_hi[o1]
            h2 = -m_lo[o2] if c % 2 == 1 else m_hi[o2]
            bp[4 * j + c] = h1 >= smin and h2 >= smin


@njit(cache=True, nogil=True)
def _classify_kernel(
    L0,
    L1,
    L2,
    b_lo,
    b_hi,
    smin,
    s,
    theta2,
    theta3,
    a2,
    a3,
    split,
    mode_signs,
    status,
    bpass,
    zero,
    kind,
    centre_mode,
    m_lo_out,
    m_hi_out,
):  # pragma: no cover - compiled
    """Classify every closed cell of one assembly mode (sign ``s``) by the bounds of the
    module docstring. A cell left undecided in some mode is split into ``split x split``
    closed sub-cells (their union is the cell): it is surely valid (invalid) in a mode when
    every sub-cell is, passable for a transit set when some sub-cell is, and the bounds are
    the hull of the sub-cells'. Writes status (8, n, n), bpass (12, n, n) (flip j, combo
    c = 2 [first other sign '-'] + [second other sign '-']), zero (3, n, n): the measure may
    vanish, kind (3, n, n) (index in TRANSIT_KINDS at the centre), centre_mode (n, n) and
    the bounds (3, n, n) (NaN where no posture is in the band)."""
    n3, n2 = theta3.shape[0], theta2.shape[0]
    m_lo = np.empty(3)
    m_hi = np.empty(3)
    cen = np.empty(5)
    sub_lo = np.empty(3)
    sub_hi = np.empty(3)
    sub_cen = np.empty(5)
    st = np.empty(8, dtype=np.int8)
    bp = np.empty(12, dtype=np.bool_)
    sst = np.empty(8, dtype=np.int8)
    sbp = np.empty(12, dtype=np.bool_)
    c2s, s2s = np.cos(theta2), np.sin(theta2)
    for i3 in range(n3):
        t3 = theta3[i3]
        c3, s3 = math.cos(t3), math.sin(t3)
        for i2 in range(n2):
            c2, s2 = c2s[i2], s2s[i2]
            sure, miss, d = _cell_bounds(
                L0, L1, L2, b_lo, b_hi, s, c2, s2, c3, s3, a2, a3, m_lo, m_hi, cen
            )
            _decide(sure, miss, m_lo, m_hi, smin, mode_signs, st, bp)
            undecided = False
            for mi in range(8):
                if st[mi] == 1:
                    undecided = True
            if undecided and split > 1:
                # refine: hull of the sub-cells' bounds, all / any of their verdicts
                any_in = False
                for mi in range(8):
                    st[mi] = 3  # 3: no sub-cell seen yet
                for b in range(12):
                    bp[b] = False
                for k in range(3):
                    m_lo[k], m_hi[k] = np.inf, -np.inf
                b2, b3 = a2 / split, a3 / split
                for p3 in range(split):
                    u3 = theta3[i3] - a3 + (2 * p3 + 1) * b3
                    cc3, ss3 = math.cos(u3), math.sin(u3)
                    for p2 in range(split):
                        u2 = theta2[i2] - a2 + (2 * p2 + 1) * b2
                        cc2, ss2 = math.cos(u2), math.sin(u2)
                        ssure, smiss, _ = _cell_bounds(
                            L0, L1, L2, b_lo, b_hi, s, cc2, ss2, cc3, ss3,
                            b2 * (1.0 + 1e-9), b3 * (1.0 + 1e-9), sub_lo, sub_hi, sub_cen,
                        )  # fmt: skip
                        _decide(ssure, smiss, sub_lo, sub_hi, smin, mode_signs, sst, sbp)
                        for mi in range(8):
                            if st[mi] == 3:
                                st[mi] = sst[mi]
                            elif st[mi] != sst[mi]:
                                st[mi] = 1
                        for b in range(12):
                            bp[b] = bp[b] or sbp[b]
                        if not smiss:
                            any_in = True
                            for k in range(3):
                                m_lo[k] = min(m_lo[k], sub_lo[k])
                                m_hi[k] = max(m_hi[k], sub_hi[k])
                miss = not any_in
            for mi in range(8):
                status[mi, i3, i2] = st[mi]
            for b in range(12):
                bpass[b, i3, i2] = bp[b]
            centre_mode[i3, i2] = -1
            kind[0, i3, i2] = 0
            kind[1, i3, i2] = 1 if cen[3] >= 0.0 else 2
            kind[2, i3, i2] = 3 if cen[4] >= 0.0 else 4
            for k in range(3):
                if miss:
                    zero[k, i3, i2] = False
                    m_lo_out[k, i3, i2] = np.nan
                    m_hi_out[k, i3, i2] = np.nan
                else:
                    zero[k, i3, i2] = m_lo[k] <= 0.0 and m_hi[k] >= 0.0
                    m_lo_out[k, i3, i2] = m_lo[k]
                    m_hi_out[k, i3, i2] = m_hi[k]
            if not miss and b_lo <= d <= b_hi and cen[0] != 0.0 and cen[1] != 0.0 and cen[2] != 0.0:
                centre_mode[i3, i2] = 4 * (cen[0] < 0.0) + 2 * (cen[1] < 0.0) + (cen[2] < 0.0)


def _grid(design: Design, n: int):
    lo, hi = np.asarray(design.joint_min), np.asarray(design.joint_max)
    h2 = (hi[1] - lo[1]) / n
    h3 = (hi[2] - lo[2]) / n
    theta2 = lo[1] + h2 * (np.arange(n) + 0.5)
    theta3 = lo[2] + h3 * (np.arange(n) + 0.5)
    return theta2, theta3, float(h2), float(h3)


# ----------------------------------------------------------------------------- the map
def region_map(
    design: Design,
    margins: Margins | None = None,
    n: int = DEFAULT_RESOLUTION,
    *,
    refine: int = DEFAULT_REFINE,
) -> RegionMap:
    """The region map of ``design`` under ``margins`` at ``n x n`` cells (cached).

    Parameters
    ----------
    design : Design
        Link lengths and joint limits (``link_radius`` plays no part without obstacles).
    margins : Margins, default ``Margins()``
        ``kappa_max`` and ``serial_min`` are used (``clearance`` needs obstacles).
    n : int
        Cells per axis over [joint_min, joint_max] of theta2 and theta3, 8 .. 2048.
    refine : int
        A cell undecided in some mode is re-bounded on ``refine x refine`` sub-cells (1: no
        refinement), 1 .. 16. The map keeps n x n cells; only the verdicts get sharper.

    Returns
    -------
    RegionMap
        Read-only; the same object for the same (design, kappa_max, serial_min, n) while it
        stays in the per-process LRU cache (16 entries).
    """
    margins = Margins() if margins is None else margins
    if not isinstance(n, int | np.integer) or isinstance(n, bool) or not 8 <= n <= MAX_RESOLUTION:
        raise InputError(f"n must be an integer in [8, {MAX_RESOLUTION}], got {n!r}")
    if not isinstance(refine, int) or isinstance(refine, bool) or not 1 <= refine <= 16:
        raise InputError(f"refine must be an integer in [1, 16], got {refine!r}")
    key = Margins(margins.kappa_max, margins.serial_min, 0.0)
    return _region_map(design, key, int(n), refine)


def clear_cache() -> None:
    """Forget every cached region map of this process."""
    _region_map.cache_clear()


@lru_cache(maxsize=_CACHE_SIZE)
def _region_map(design: Design, margins: Margins, n: int, split: int) -> RegionMap:
    theta2, theta3, h2, h3 = _grid(design, n)
    a2 = 0.5 * h2 * (1.0 + _REL_SLACK)
    a3 = 0.5 * h3 * (1.0 + _REL_SLACK)
    lo, hi = margins.cd_range
    smin = margins.serial_min
    status = np.empty((2, 8, n, n), dtype=np.int8)
    labels = np.zeros((2, 8, n, n), dtype=np.int32)
    certified = np.zeros((2, 8, n, n), dtype=np.int32)
    centre_mode = np.empty((2, n, n), dtype=np.int8)
    transit_cells = np.zeros((2, 3, n, n), dtype=np.int8)
    bpass = np.empty((2, 12, n, n), dtype=np.bool_)
    zero = np.empty((2, 3, n, n), dtype=np.bool_)
    kind = np.empty((2, 3, n, n), dtype=np.int8)
    m_lo = np.empty((2, 3, n, n))
    m_hi = np.empty((2, 3, n, n))
    counts = np.zeros((2, 8), dtype=np.int64)
    for ai, asm in enumerate(ASSEMBLY_MODES):
        _classify_kernel(
            design.L0, design.L1, design.L2, 2.0 * design.L2 * lo, 2.0 * design.L2 * hi,
            smin, 1.0 if asm == "+" else -1.0, theta2, theta3, a2, a3, split, _MODE_SIGNS,
            status[ai], bpass[ai], zero[ai], kind[ai], centre_mode[ai], m_lo[ai], m_hi[ai],
        )  # fmt: skip
        for mi in range(8):
            st = status[ai, mi]
            over = st != INVALID
            if over.any():
                labels[ai, mi], counts[ai, mi] = ndimage.label(over, structure=_EIGHT)
                sure = st == VALID
                if sure.any():
                    certified[ai, mi] = ndimage.label(sure, structure=_EIGHT)[0]
    # regions, then the union graph over the transit sets' components
    max_l = int(counts.max())
    region_index = np.full((2, 8, max_l + 1), -1, dtype=np.int32)
    raw: list[tuple[int, int, int]] = []
    for ai in range(2):
        for mi in range(8):
            for lab in range(1, int(counts[ai, mi]) + 1):
                region_index[ai, mi, lab] = len(raw)
                raw.append((ai, mi, lab))
    parent = list(range(len(raw)))

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    transits: list[RegionTransit] = []
    for ai in range(2):
        for j in range(3):
            others = [k for k in range(3) if k != j]
            zero_any = np.zeros((n, n), dtype=bool)
            for c in range(4):
                so = (-1 if c >= 2 else 1, -1 if c % 2 else 1)
                # the two modes of this transit set: sign j '+' (mp) and '-' (mm)
                pair = []
                for sj in (1, -1):
                    sg = [0, 0, 0]
                    sg[j], sg[others[0]], sg[others[1]] = sj, so[0], so[1]
                    pair.append(4 * (sg[0] < 0) + 2 * (sg[1] < 0) + (sg[2] < 0))
                mp, mm = pair
                if counts[ai, mp] == 0 or counts[ai, mm] == 0:
                    continue
                passable = bpass[ai, 4 * j + c]
                b_lab, _ = ndimage.label(passable, structure=_EIGHT)
                z = passable & zero[ai, j]
                kinds_here: dict[int, dict[str, int]] = {}
                zl, zk = b_lab[z], kind[ai, j][z]
                for kk in np.unique(zk).tolist():
                    comp, cnt = np.unique(zl[zk == kk], return_counts=True)
                    for c_, n_ in zip(comp.tolist(), cnt.tolist(), strict=True):
                        kinds_here.setdefault(c_, {})[TRANSIT_KINDS[kk]] = n_
                members: dict[int, tuple[list[int], list[int]]] = {}
                for side, mi in enumerate((mp, mm)):
                    rep = np.zeros(int(counts[ai, mi]) + 1, dtype=np.int64)
                    rep[labels[ai, mi].ravel()] = b_lab.ravel()
                    for lab in range(1, len(rep)):
                        members.setdefault(int(rep[lab]), ([], []))[side].append(
                            int(region_index[ai, mi, lab])
                        )
                joining = [c_ for c_, (pl, mn) in members.items() if pl and mn and c_ > 0]
                if joining:
                    zero_any |= z & np.isin(b_lab, joining)
                for comp, (plus, minus) in members.items():
                    ids = plus + minus
                    for other in ids[1:]:
                        parent[find(other)] = find(ids[0])
                    ks = kinds_here.get(comp, {})
                    transits.extend(
                        RegionTransit(a, b, _FLIP_NAMES[j], tuple(ks), tuple(ks.values()))
                        for a in plus
                        for b in minus
                    )
            transit_cells[ai, j] = np.where(zero_any, kind[ai, j] + 1, 0)
    roots = sorted({find(i) for i in range(len(raw))})
    comp_of = {r: k for k, r in enumerate(roots)}
    sizes: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
    for ai in range(2):
        for mi in range(8):
            m = int(counts[ai, mi]) + 1
            lab = labels[ai, mi]
            sizes[ai, mi] = (
                np.bincount(lab.ravel(), minlength=m),
                np.bincount(lab[status[ai, mi] == VALID], minlength=m),
            )
    regions = tuple(
        Region(
            id=i,
            assembly_mode=ASSEMBLY_MODES[ai],
            working_mode=WORKING_MODES[mi],
            label=lab,
            cells=int(sizes[ai, mi][0][lab]),
            valid_cells=int(sizes[ai, mi][1][lab]),
            component=comp_of[find(i)],
        )
        for i, (ai, mi, lab) in enumerate(raw)
    )
    for arr in (theta2, theta3, status, labels, certified, centre_mode, transit_cells):
        arr.setflags(write=False)
    region_index.setflags(write=False)
    m_lo.setflags(write=False)
    m_hi.setflags(write=False)
    return RegionMap(
        design=design,
        margins=margins,
        n=n,
        theta2=theta2,
        theta3=theta3,
        h2=h2,
        h3=h3,
        status=status,
        labels=labels,
        certified=certified,
        centre_mode=centre_mode,
        transit_cells=transit_cells,
        regions=regions,
        transits=tuple(transits),
        region_index=region_index,
        measure_low=m_lo,
        measure_high=m_hi,
    )


# ----------------------------------------------------------------------------- queries
def locate(rmap: RegionMap, q: np.ndarray) -> tuple[int, int] | None:
    """(k3, k2) of a closed cell holding posture q (3,) rad, or None when (theta2, theta3)
    lie outside the joint box (theta1 is ignored: no rule but its limit depends on it).

    A posture on a cell edge lies in two or four closed cells; the one returned is any of
    them (each holds it, which is all the proofs need)."""
    q = np.asarray(q, dtype=float).reshape(-1)
    if q.shape != (3,) or not np.all(np.isfinite(q)):
        raise InputError(f"q must be 3 finite numbers, got {q!r}")
    lo, hi = rmap.design.joint_min, rmap.design.joint_max
    if not (lo[1] <= q[1] <= hi[1] and lo[2] <= q[2] <= hi[2]):
        return None
    k2 = min(max(math.floor((q[1] - lo[1]) / rmap.h2), 0), rmap.n - 1)
    k3 = min(max(math.floor((q[2] - lo[2]) / rmap.h3), 0), rmap.n - 1)
    return k3, k2


def _components_at(rmap: RegionMap, q: np.ndarray, ai: int) -> set[int] | None:
    """Union-graph components of every region whose cells hold q (None: q outside the box
    or theta1 outside its limits)."""
    q = np.asarray(q, dtype=float).reshape(-1)
    cell = locate(rmap, q)
    d = rmap.design
    if cell is None or not d.joint_min[0] <= q[0] <= d.joint_max[0]:
        return None
    k3, k2 = cell
    labs = rmap.labels[ai, :, k3, k2]
    return {
        rmap.regions[int(rmap.region_index[ai, mi, lab])].component
        for mi, lab in enumerate(labs.tolist())
        if lab > 0
    }


def prove_disconnected(
    rmap: RegionMap, start_q: np.ndarray, goal_q: np.ndarray, assembly_mode: str
) -> bool:
    """True only when no valid path (mode changes through serial transits included) joins
    ``start_q`` to ``goal_q`` in ``assembly_mode``, proven by the region map.

    Parameters
    ----------
    rmap : RegionMap
        The map of the plan's design and margins (obstacle-free).
    start_q : shape (3,), rad
    goal_q : shape (3,) or (K, 3), rad: one goal posture or every candidate posture of a
        goal (e.g. the inverse kinematics solutions of a Cartesian target); True only when
        every candidate is proven unreachable.
    assembly_mode : '+' | '-'

    Returns
    -------
    bool
        True: proven, no path exists. False: the map cannot prove it (a path may exist, or
        the start or a goal is outside the joint box, or lies in no region at all, i.e. is
        invalid, which the planner reports as ``invalid_start`` / ``invalid_goal``).

    Notes
    -----
    The argument. A plan is a continuous path q(t) in the joint box in one assembly mode,
    made of pieces valid in one working mode M (every rule: the set V_M) joined by transits,
    along which the non-serial rules hold and the two measures not being flipped keep their
    signs with margin ``serial_min`` (the set B of that flip, which contains V_M and V_M').
    So the path's (theta2, theta3) stays in the union of the closed sets V_M and B (theta1
    plays no part without obstacles; obstacles only remove postures, so a proof holds with
    them too). Every posture of V_M lies in a closed cell that is not surely invalid in M
    (a surely invalid cell holds no valid posture), hence inside the union of the closed
    cells of one region, and the same holds for B and its over-approximated components.
    A connected piece of the path inside V_M cannot leave its region's cells, since closed
    cells of two different 8-connected components share no point; it passes from V_M to a
    B, or from one B to another, only at a posture in both sets, i.e. (two transit sets meet
    only inside a V) inside V_M, where the region's cells and the B component's cells
    overlap, which is exactly how :func:`region_map` joins them. So the path stays inside
    the regions of one component of the union graph: if no region holding the start shares a
    component with a region holding a goal, any path would have to leave those cells, i.e.
    cross a cell that is surely invalid, which no valid posture is in. Undecided cells count
    as passable, so the proof is never claimed where the map cannot decide.
    """
    if assembly_mode not in ASSEMBLY_MODES:
        raise InputError(f"assembly_mode must be '+' or '-', got {assembly_mode!r}")
    ai = ASSEMBLY_MODES.index(assembly_mode)
    start = _components_at(rmap, start_q, ai)
    if not start:
        return False
    goals = np.atleast_2d(np.asarray(goal_q, dtype=float))
    if goals.ndim != 2 or goals.shape[1] != 3 or len(goals) == 0:
        raise InputError(f"goal_q must have shape (3,) or (K, 3), got {np.shape(goal_q)}")
    for g in goals:
        comps = _components_at(rmap, g, ai)
        if not comps or comps & start:
            return False
    return True


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
        mi = _MODE_INDEX[region.working_mode]
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
    """

    u: np.ndarray
    w: np.ndarray
    pixel_area: float
    reached: dict[int, np.ndarray]

    def area(self, region_ids) -> float:
        """Area (m^2) of the union of the given regions' images."""
        ids = list(region_ids)
        if not ids:
            return 0.0
        union = np.zeros_like(self.reached[ids[0]])
        for i in ids:
            union |= self.reached[i]
        return float(union.sum()) * self.pixel_area


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
    return Coverage(u, w, float((u[1] - u[0]) * (w[1] - w[0])), reached)
