"""The region map's build as it was before its speed-up (issue 17), kept callable as the
reference of ``test_region_speed.py``: the numba kernels of
``planner.analysis._region_kernels`` and the pipeline of ``planner.analysis.regions``
(classification, mirror, labelling, transit graph) copied unchanged from that commit, so that
the fast build is compared with the old route, not with itself. Not a test module."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from planner.analysis.regions import Region, RegionMap, RegionTransit
from planner.design import Design
from planner.kinematics import ASSEMBLY_MODES, WORKING_MODES
from planner.transits import TRANSIT_KINDS
from planner.validity import Margins

_FLIP_NAMES = ("axis", "A", "B")
_REL_SLACK = 1e-9


#: Bit of working mode ``mi`` in a cell's mask: ``1 << (BITS_OVER + mi)`` when the cell is
#: not surely invalid in it, ``1 << (BITS_VALID + mi)`` when it is surely valid.
BITS_OVER, BITS_VALID = 0, 8
#: ``1 << (BITS_B + 4 j + c)``: the cell is not surely outside transit set (j, c)
#: (flip j, c = 2 [first other sign '-'] + [second other sign '-']).
BITS_B = 16
#: ``1 << (BITS_ZERO + k)``: serial measure k may vanish in the cell.
BITS_ZERO = 28
#: Layers labelled by :func:`label_kernel`: 8 over-approximated, 8 certified, 12 transit sets.
LAYERS = 28

# _PLUS[k]: the working modes (bit mi) whose sign k is '+' (mi = 4 [s_axis '-'] + 2 [s_A '-']
# + [s_B '-'], the order of planner.kinematics.WORKING_MODES)
_PLUS = (0x0F, 0x33, 0x55)
# index of the lowest set bit of a 32-bit word, by de Bruijn multiplication
_DE_BRUIJN = np.array(
    [0, 1, 28, 2, 29, 14, 24, 3, 30, 22, 20, 15, 25, 17, 4, 8,
     31, 27, 13, 23, 21, 19, 16, 7, 26, 12, 18, 6, 11, 5, 10, 9],
    dtype=np.int64,
)  # fmt: skip


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
def _decide(sure, miss, m_lo, m_hi, smin):  # pragma: no cover
    """The masks of one cell (or sub-cell) from its bounds: (over, valid, passable), bit mi
    of the first two for working mode mi (not surely invalid; surely valid), bit 4 j + c
    of the third for transit set (j, c) (not surely outside it).

    Mode mi is surely invalid when a signed measure's upper bound is below ``serial_min``
    and surely valid when the cell is all in the band and every signed lower bound is at
    least ``serial_min``; a transit set is passable unless one of its two fixed signed
    measures is surely below ``serial_min``. With _PLUS[k] the modes whose sign k is '+',
    each rule is a product over k of the masks of the signs it allows."""
    if miss:
        return 0, 0, 0
    over = 0xFF
    valid = 0xFF if sure else 0
    can = 0  # bit 2 k: measure k may be >= smin; bit 2 k + 1: may be <= -smin
    for k in range(3):
        plus = _PLUS[k]
        minus = 0xFF ^ plus
        can_p = m_hi[k] >= smin
        can_n = -m_lo[k] >= smin
        over &= (plus if can_p else 0) | (minus if can_n else 0)
        valid &= (plus if m_lo[k] >= smin else 0) | (minus if -m_hi[k] >= smin else 0)
        can |= (1 if can_p else 0) << (2 * k)
        can |= (1 if can_n else 0) << (2 * k + 1)
    passable = 0
    for j in range(3):
        o1 = 1 if j == 0 else 0
        o2 = 1 if j == 2 else 2
        for c in range(4):
            if (can >> (2 * o1 + (c >> 1))) & 1 and (can >> (2 * o2 + (c & 1))) & 1:
                passable |= 1 << (4 * j + c)
    return over, valid, passable


@njit(cache=True, nogil=True)
def classify_kernel(
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
    sub2,
    sub3,
    status,
    bits,
    kind,
    centre_mode,
    m_lo_out,
    m_hi_out,
):  # pragma: no cover - compiled
    """Classify every closed cell of one assembly mode (sign ``s``) by the bounds of
    :func:`_cell_bounds`. A cell left undecided in some mode is split into ``split x split``
    closed sub-cells (their union is the cell; ``sub2`` (n2, split, 2) and ``sub3`` hold
    the cosine and sine of their centres): it is surely valid (invalid) in a mode when every
    sub-cell is, passable for a transit set when some sub-cell is, and the bounds are the
    hull of the sub-cells'. Writes status (8, n, n), bits (n, n) (the masks of the module
    docstring), kind (3, n, n) (index in TRANSIT_KINDS at the centre), centre_mode (n, n)
    and the bounds (3, n, n) (NaN where no posture is in the band)."""
    n3, n2 = theta3.shape[0], theta2.shape[0]
    m_lo = np.empty(3)
    m_hi = np.empty(3)
    cen = np.empty(5)
    sub_lo = np.empty(3)
    sub_hi = np.empty(3)
    sub_cen = np.empty(5)
    c2s, s2s = np.cos(theta2), np.sin(theta2)
    b2, b3 = a2 / split, a3 / split
    e2, e3 = b2 * (1.0 + 1e-9), b3 * (1.0 + 1e-9)
    for i3 in range(n3):
        t3 = theta3[i3]
        c3, s3 = math.cos(t3), math.sin(t3)
        for i2 in range(n2):
            c2, s2 = c2s[i2], s2s[i2]
            sure, miss, d = _cell_bounds(
                L0, L1, L2, b_lo, b_hi, s, c2, s2, c3, s3, a2, a3, m_lo, m_hi, cen
            )
            over, valid, passable = _decide(sure, miss, m_lo, m_hi, smin)
            if over != valid and split > 1:
                # undecided in some mode: refine. Surely valid (invalid) where every sub-cell
                # is, passable where some sub-cell is; bounds: the hull of the sub-cells'.
                any_in = False
                over, valid, passable = 0, 0xFF, 0
                for k in range(3):
                    m_lo[k], m_hi[k] = np.inf, -np.inf
                for p3 in range(split):
                    cc3, ss3 = sub3[i3, p3, 0], sub3[i3, p3, 1]
                    for p2 in range(split):
                        cc2, ss2 = sub2[i2, p2, 0], sub2[i2, p2, 1]
                        ssure, smiss, _ = _cell_bounds(
                            L0,
                            L1,
                            L2,
                            b_lo,
                            b_hi,
                            s,
                            cc2,
                            ss2,
                            cc3,
                            ss3,
                            e2,
                            e3,
                            sub_lo,
                            sub_hi,
                            sub_cen,
                        )
                        so, sv, sp = _decide(ssure, smiss, sub_lo, sub_hi, smin)
                        over |= so
                        valid &= sv
                        passable |= sp
                        if not smiss:
                            any_in = True
                            for k in range(3):
                                m_lo[k] = min(m_lo[k], sub_lo[k])
                                m_hi[k] = max(m_hi[k], sub_hi[k])
                miss = not any_in
            for mi in range(8):
                status[mi, i3, i2] = ((over >> mi) & 1) + ((valid >> mi) & 1)
            mask = (over << BITS_OVER) | (valid << BITS_VALID) | (passable << BITS_B)
            centre_mode[i3, i2] = -1
            kind[0, i3, i2] = 0
            kind[1, i3, i2] = 1 if miss or cen[3] >= 0.0 else 2  # (cen is stale when miss)
            kind[2, i3, i2] = 3 if miss or cen[4] >= 0.0 else 4
            for k in range(3):
                if miss:
                    m_lo_out[k, i3, i2] = np.nan
                    m_hi_out[k, i3, i2] = np.nan
                else:
                    if m_lo[k] <= 0.0 and m_hi[k] >= 0.0:
                        mask |= 1 << (BITS_ZERO + k)
                    m_lo_out[k, i3, i2] = m_lo[k]
                    m_hi_out[k, i3, i2] = m_hi[k]
            bits[i3, i2] = mask
            # a sign within rounding of 0 (e.g. the base point of erratum 6) is no sign
            tiny = 1e-12
            if (
                not miss
                and b_lo <= d <= b_hi
                and abs(cen[0]) > tiny
                and abs(cen[1]) > tiny
                and abs(cen[2]) > tiny
            ):
                centre_mode[i3, i2] = 4 * (cen[0] < 0.0) + 2 * (cen[1] < 0.0) + (cen[2] < 0.0)


@njit(cache=True, nogil=True)
def mirror_kernel(
    status, bits, kind, centre_mode, m_lo, m_hi,
    status_m, bits_m, kind_m, centre_mode_m, m_lo_m, m_hi_m,
):  # fmt: skip  # pragma: no cover - compiled
    """The classification of the other assembly mode from one, by the reflection about AB.

    Reflecting the linkage plane about the line AB maps C(theta2), D(theta3) to C(-theta2),
    D(-theta3) and the apex to the other side of CD: the assembly mode flips, and so do the
    three signed serial measures (w, sin(theta4 - theta2), sin(theta5 - theta3) change sign),
    while |CD| and the kinds (cosines of the leg angles) stay. So the valid set of mode M in
    one assembly mode is that of the opposite mode -M (index 7 - mi) in the other, reflected
    through the origin of (theta2, theta3); on a grid over a box symmetric about 0, cell
    (k3, k2) maps onto cell (n - 1 - k3, n - 1 - k2), and the bounds of one are bounds of
    the other with the measures negated (the cells' half-widths carry a relative slack of
    1e-9, far above the rounding of the mirrored centres). Transit set (j, c) maps to
    (j, 3 - c): both other signs flip."""
    n3, n2 = bits.shape
    for i3 in range(n3):
        j3 = n3 - 1 - i3
        for i2 in range(n2):
            j2 = n2 - 1 - i2
            for mi in range(8):
                status_m[7 - mi, j3, j2] = status[mi, i3, i2]
            w = bits[i3, i2]
            v = 0
            for mi in range(8):
                if (w >> (BITS_OVER + mi)) & 1:
                    v |= 1 << (BITS_OVER + 7 - mi)
                if (w >> (BITS_VALID + mi)) & 1:
                    v |= 1 << (BITS_VALID + 7 - mi)
            for j in range(3):
                for c in range(4):
                    if (w >> (BITS_B + 4 * j + c)) & 1:
                        v |= 1 << (BITS_B + 4 * j + 3 - c)
                if (w >> (BITS_ZERO + j)) & 1:
                    v |= 1 << (BITS_ZERO + j)
            bits_m[j3, j2] = v
            for k in range(3):
                kind_m[k, j3, j2] = kind[k, i3, i2]
                m_lo_m[k, j3, j2] = -m_hi[k, i3, i2]
                m_hi_m[k, j3, j2] = -m_lo[k, i3, i2]
            cm = centre_mode[i3, i2]
            centre_mode_m[j3, j2] = -1 if cm < 0 else 7 - cm


@njit(cache=True, nogil=True, inline="always")
def _low_bit(x):  # pragma: no cover - compiled
    """Index of the lowest set bit of 0 < x < 2**32."""
    return _DE_BRUIJN[(((x & -x) * 0x077CB531) & 0xFFFFFFFF) >> 27]


@njit(cache=True, nogil=True, inline="always")
def _find(parent, x):  # pragma: no cover - compiled
    """Root of x, halving the path on the way."""
    while parent[x] != x:
        parent[x] = parent[parent[x]]
        x = parent[x]
    return x


@njit(cache=True, nogil=True, inline="always")
def _union(parent, x, y):  # pragma: no cover - compiled
    """Join the sets of x and y; the root is the smaller index (the earlier cell)."""
    rx, ry = _find(parent, x), _find(parent, y)
    if rx < ry:
        parent[ry] = rx
    elif ry < rx:
        parent[rx] = ry


@njit(cache=True, nogil=True, inline="always")
def _popcount(x):  # pragma: no cover - compiled
    """Set bits of 0 <= x < 2**32."""
    x = x - ((x >> 1) & 0x55555555)
    x = (x & 0x33333333) + ((x >> 2) & 0x33333333)
    x = (x + (x >> 4)) & 0x0F0F0F0F
    return ((x * 0x01010101) & 0xFFFFFFFF) >> 24


@njit(cache=True, nogil=True, inline="always")
def _join(parent, common, m, x0, mo, y0):  # pragma: no cover - compiled
    """Join, in every layer of ``common``, the slot of the cell (mask m, first slot x0) with
    that of a neighbour (mask mo, first slot y0)."""
    while common:
        low = common & -common
        common ^= low
        below = low - 1
        _union(parent, x0 + _popcount(m & below), y0 + _popcount(mo & below))


@njit(cache=True, nogil=True)
def label_kernel(bits, over, certified):  # pragma: no cover - compiled
    """8-connected components of every layer of one assembly mode, in one pass.

    Each set bit of a cell's mask is a *slot* (cell by cell in raster order, bits from the
    lowest): ``start[cell] + popcount(mask & ((1 << b) - 1))`` is the slot of layer b there.
    Union-find runs over the slots with the smaller slot as the root, so the root of a
    component is its first cell in raster order and the second pass meets it first; labels
    are 1-based and numbered in that order (as ``scipy.ndimage.label`` numbers them).

    Parameters
    ----------
    bits : (n3, n2) int64, the cells' masks (:data:`LAYERS` low bits used).
    over, certified : (8, n3, n2) int32, zeros: written with the labels of the 8
        over-approximated and the 8 certified layers.

    Returns
    -------
    counts : (LAYERS,) components per layer.
    first : (LAYERS, L + 1) int64, flat index of each component's first cell (L the
        largest count).
    sizes : (LAYERS, L + 1) int64, cells per component.
    valid : (8, L + 1) int64, surely valid cells of each over-approximated component.
    start : (n3 n2 + 1,) int64, first slot of each cell.
    slot_label : (slots,) int64, the label of each slot (every layer, transit sets too).
    """
    n3, n2 = bits.shape
    full = (1 << LAYERS) - 1
    start = _slot_starts(bits)
    total = start[n3 * n2]
    parent = np.arange(total)
    for i3 in range(n3):
        for i2 in range(n2):
            m = bits[i3, i2] & full
            if m == 0:
                continue
            x0 = start[i3 * n2 + i2]
            # the earlier neighbours: a b c above, d to the left. In a layer where b is set,
            # a, c and d are already joined to b; else c, and d (or a: a and d touch).
            nb_a = bits[i3 - 1, i2 - 1] & full if i3 > 0 and i2 > 0 else 0
            nb_b = bits[i3 - 1, i2] & full if i3 > 0 else 0
            nb_c = bits[i3 - 1, i2 + 1] & full if i3 > 0 and i2 + 1 < n2 else 0
            nb_d = bits[i3, i2 - 1] & full if i2 > 0 else 0
            rest = m & ~nb_b
            _join(parent, m & nb_b, m, x0, nb_b, start[(i3 - 1) * n2 + i2] if i3 > 0 else 0)
            if rest:
                if i3 > 0 and i2 + 1 < n2:
                    _join(parent, rest & nb_c, m, x0, nb_c, start[(i3 - 1) * n2 + i2 + 1])
                if i2 > 0:
                    _join(parent, rest & nb_d, m, x0, nb_d, start[i3 * n2 + i2 - 1])
                    if i3 > 0:
                        _join(
                            parent, rest & ~nb_d & nb_a, m, x0, nb_a, start[(i3 - 1) * n2 + i2 - 1]
                        )
    counts = np.zeros(LAYERS, dtype=np.int64)
    slot_label = np.empty(total, dtype=np.int64)
    for i3 in range(n3):
        for i2 in range(n2):
            t = bits[i3, i2] & full
            x = start[i3 * n2 + i2]
            while t:
                b = _low_bit(t)
                t &= t - 1
                r = _find(parent, x)
                if r == x:
                    counts[b] += 1
                    slot_label[x] = counts[b]
                else:
                    slot_label[x] = slot_label[r]
                if b < BITS_VALID:
                    over[b, i3, i2] = slot_label[x]
                elif b < BITS_B:
                    certified[b - BITS_VALID, i3, i2] = slot_label[x]
                x += 1
    first, sizes, valid = _component_sizes(bits, start, slot_label, counts, over)
    return counts, first, sizes, valid, start, slot_label


@njit(cache=True, nogil=True)
def mirror_label_kernel(bits, bits_src, start_src, label_src, over, certified):  # pragma: no cover
    """:func:`label_kernel` of the mirror image of a labelled assembly mode, without
    union-find: the component of layer b at cell (k3, k2) is that of the mirrored layer
    (modes mi -> 7 - mi, transit sets (j, c) -> (j, 3 - c)) at (n - 1 - k3, n - 1 - k2) in
    the source, renumbered in this raster order. ``bits`` are the mirrored masks of
    :func:`mirror_kernel` (with the same transit sets dropped), ``bits_src``, ``start_src``
    and ``label_src`` the source's masks, slot starts and slot labels. Same returns."""
    n3, n2 = bits.shape
    full = (1 << LAYERS) - 1
    start = _slot_starts(bits)
    total = start[n3 * n2]
    top = 1
    for x in range(label_src.shape[0]):
        top = max(top, label_src[x] + 1)
    renumber = np.zeros((LAYERS, top), dtype=np.int64)
    counts = np.zeros(LAYERS, dtype=np.int64)
    slot_label = np.empty(total, dtype=np.int64)
    for i3 in range(n3):
        for i2 in range(n2):
            t = bits[i3, i2] & full
            x = start[i3 * n2 + i2]
            k3, k2 = n3 - 1 - i3, n2 - 1 - i2
            m_src = bits_src[k3, k2] & full
            y0 = start_src[k3 * n2 + k2]
            while t:
                b = _low_bit(t)
                t &= t - 1
                if b < BITS_VALID:
                    bs = 7 - b
                elif b < BITS_B:
                    bs = BITS_VALID + 7 - (b - BITS_VALID)
                else:
                    bs = b - (b - BITS_B) % 4 + 3 - (b - BITS_B) % 4
                lab = label_src[y0 + _popcount(m_src & ((1 << bs) - 1))]
                if renumber[b, lab] == 0:
                    counts[b] += 1
                    renumber[b, lab] = counts[b]
                slot_label[x] = renumber[b, lab]
                if b < BITS_VALID:
                    over[b, i3, i2] = slot_label[x]
                elif b < BITS_B:
                    certified[b - BITS_VALID, i3, i2] = slot_label[x]
                x += 1
    first, sizes, valid = _component_sizes(bits, start, slot_label, counts, over)
    return counts, first, sizes, valid, start, slot_label


@njit(cache=True, nogil=True)
def _slot_starts(bits):  # pragma: no cover - compiled
    """(n3 n2 + 1,) first slot of each cell (the last entry: the number of slots)."""
    n3, n2 = bits.shape
    full = (1 << LAYERS) - 1
    start = np.empty(n3 * n2 + 1, dtype=np.int64)
    total = 0
    for cell in range(n3 * n2):
        start[cell] = total
        total += _popcount(bits[cell // n2, cell % n2] & full)
    start[n3 * n2] = total
    return start


@njit(cache=True, nogil=True)
def _component_sizes(bits, start, slot_label, counts, over):  # pragma: no cover - compiled
    """First cell (flat index), cells and surely valid cells of every component."""
    n3, n2 = bits.shape
    full = (1 << LAYERS) - 1
    top = 1 + max(1, counts.max())
    first = np.zeros((LAYERS, top), dtype=np.int64)
    sizes = np.zeros((LAYERS, top), dtype=np.int64)
    valid = np.zeros((8, top), dtype=np.int64)
    for i3 in range(n3):
        for i2 in range(n2):
            t = bits[i3, i2] & full
            x = start[i3 * n2 + i2]
            while t:
                b = _low_bit(t)
                t &= t - 1
                lab = slot_label[x]
                if sizes[b, lab] == 0:
                    first[b, lab] = i3 * n2 + i2
                sizes[b, lab] += 1
                if BITS_VALID <= b < BITS_B:
                    valid[b - BITS_VALID, over[b - BITS_VALID, i3, i2]] += 1
                x += 1
    return first, sizes, valid


@njit(cache=True, nogil=True)
def transit_kernel(bits, kind, start, slot_label, joining, kinds, cells):  # pragma: no cover
    """Where each transit set's components may cross their serial surface.

    Parameters
    ----------
    bits, kind : the masks and centre kinds of one assembly mode.
    start, slot_label : of :func:`label_kernel`.
    joining : (12, L + 1) bool: component l of transit set b joins regions of both modes.
    kinds : (12, L + 1, 5) int64, zeros: written with the count, per component and kind, of
        its cells where the flipped measure may vanish.
    cells : (3, n3, n2) int8, zeros: per flip, 1 + the kind at such cells of a joining
        component.
    """
    n3, n2 = bits.shape
    for i3 in range(n3):
        for i2 in range(n2):
            m = bits[i3, i2]
            x0 = start[i3 * n2 + i2]
            for j in range(3):
                if not (m >> (BITS_ZERO + j)) & 1:
                    continue
                k = kind[j, i3, i2]
                for c in range(4):
                    b = BITS_B + 4 * j + c
                    if (m >> b) & 1:
                        comp = slot_label[x0 + _popcount(m & ((1 << b) - 1))]
                        kinds[b - BITS_B, comp, k] += 1
                        if joining[b - BITS_B, comp]:
                            cells[j, i3, i2] = k + 1


def _grid(design: Design, n: int):
    lo, hi = np.asarray(design.joint_min), np.asarray(design.joint_max)
    h2 = (hi[1] - lo[1]) / n
    h3 = (hi[2] - lo[2]) / n
    theta2 = lo[1] + h2 * (np.arange(n) + 0.5)
    theta3 = lo[2] + h3 * (np.arange(n) + 0.5)
    return theta2, theta3, float(h2), float(h3)


def _sub_trig(centres: np.ndarray, a: float, split: int) -> np.ndarray:
    """(n, split, 2): cosine and sine of the sub-cell centres of each cell (half-width a)."""
    b = a / split
    u = centres[:, None] - a + (2 * np.arange(split) + 1) * b
    return np.ascontiguousarray(np.stack([np.cos(u), np.sin(u)], axis=-1))


def _mirrored(design: Design) -> bool:
    """The box of (theta2, theta3) is symmetric about 0: one assembly mode's classification
    is the other's mirror image (:func:`planner.analysis._region_kernels.mirror_kernel`)."""
    lo, hi = design.joint_min, design.joint_max
    return bool(lo[1] == -hi[1] and lo[2] == -hi[2])


@dataclass(frozen=True, slots=True)
class _Cells:
    """The cell-wise classification of both assembly modes (arrays of the kernels)."""

    status: np.ndarray  # (2, 8, n, n) int8
    bits: np.ndarray  # (2, n, n) int64 masks
    kind: np.ndarray  # (2, 3, n, n) int8
    centre_mode: np.ndarray  # (2, n, n) int8
    m_lo: np.ndarray  # (2, 3, n, n)
    m_hi: np.ndarray  # (2, 3, n, n)
    mirrored: bool  # the second assembly mode is the first's mirror image


def _classify(
    design: Design, margins: Margins, n: int, split: int, *, mirror: bool = True
) -> _Cells:
    """Classify every cell of both assembly modes; with ``mirror`` and a symmetric box the
    second assembly mode is the first's mirror image (half the work, the same bounds)."""
    theta2, theta3, h2, h3 = _grid(design, n)
    a2 = 0.5 * h2 * (1.0 + _REL_SLACK)
    a3 = 0.5 * h3 * (1.0 + _REL_SLACK)
    lo, hi = margins.cd_range
    cells = _Cells(
        status=np.empty((2, 8, n, n), dtype=np.int8),
        bits=np.empty((2, n, n), dtype=np.int64),
        kind=np.empty((2, 3, n, n), dtype=np.int8),
        centre_mode=np.empty((2, n, n), dtype=np.int8),
        m_lo=np.empty((2, 3, n, n)),
        m_hi=np.empty((2, 3, n, n)),
        mirrored=mirror and _mirrored(design),
    )
    sub2, sub3 = _sub_trig(theta2, a2, split), _sub_trig(theta3, a3, split)
    fields = ("status", "bits", "kind", "centre_mode", "m_lo", "m_hi")
    mirror = cells.mirrored
    for ai in (0,) if mirror else (0, 1):
        classify_kernel(
            design.L0,
            design.L1,
            design.L2,
            2.0 * design.L2 * lo,
            2.0 * design.L2 * hi,
            margins.serial_min,
            1.0 if ai == 0 else -1.0,
            theta2,
            theta3,
            a2,
            a3,
            split,
            sub2,
            sub3,
            *(getattr(cells, f)[ai] for f in fields),
        )
    if mirror:
        mirror_kernel(
            *(getattr(cells, f)[0] for f in fields), *(getattr(cells, f)[1] for f in fields)
        )
    return cells


def _transit_pairs() -> tuple[tuple[int, int], ...]:
    """The two working modes (sign j '+', sign j '-') of each transit set b = 4 j + c."""
    pairs = []
    for j in range(3):
        others = [k for k in range(3) if k != j]
        for c in range(4):
            fixed = (-1 if c >= 2 else 1, -1 if c % 2 else 1)
            pair = []
            for sj in (1, -1):
                sg = [0, 0, 0]
                sg[j], sg[others[0]], sg[others[1]] = sj, *fixed
                pair.append(4 * (sg[0] < 0) + 2 * (sg[1] < 0) + (sg[2] < 0))
            pairs.append((pair[0], pair[1]))
    return tuple(pairs)


_TRANSIT_PAIRS = _transit_pairs()


def _drop_unused_transit_sets(bits: np.ndarray) -> None:
    """Clear, in place, the bits of the transit sets of which one mode has no cell at all in
    that assembly mode: no transit can use them, and labelling them would be wasted work."""
    for ai in range(bits.shape[0]):
        present = int(np.bitwise_or.reduce(bits[ai], axis=None)) >> BITS_OVER
        keep = ~0
        for b, (mp, mm) in enumerate(_TRANSIT_PAIRS):
            if not (present >> mp) & 1 or not (present >> mm) & 1:
                keep &= ~(1 << (BITS_B + b))
        bits[ai] &= keep


def _slot_of(bits: int, start: np.ndarray, cell: int, layer: int) -> int:
    """The slot of ``layer`` at ``cell`` (see :func:`~planner.analysis._region_kernels.label_kernel`)."""
    return int(start[cell]) + (bits & ((1 << layer) - 1)).bit_count()


def _label_layers(cells: _Cells, n: int) -> tuple[np.ndarray, np.ndarray, list[tuple]]:
    """Labels (2, 8, n, n) and certified labels of every (assembly, working) mode, and the
    per-assembly outputs of :func:`~planner.analysis._region_kernels.label_kernel`."""
    labels = np.zeros((2, 8, n, n), dtype=np.int32)
    certified = np.zeros((2, 8, n, n), dtype=np.int32)
    layers = [label_kernel(cells.bits[0], labels[0], certified[0])]
    if cells.mirrored:  # the other assembly mode's components are the mirror images
        start, slot_label = layers[0][4], layers[0][5]
        layers.append(
            mirror_label_kernel(
                cells.bits[1], cells.bits[0], start, slot_label, labels[1], certified[1]
            )
        )
    else:
        layers.append(label_kernel(cells.bits[1], labels[1], certified[1]))
    return labels, certified, layers


def _transit_graph(
    cells: _Cells, layers: list[tuple], counts: np.ndarray, region_index: np.ndarray, n: int
) -> tuple[list[RegionTransit], np.ndarray, list[list[int]]]:
    """The transits, the transit cells (2, 3, n, n) and the groups of region ids that lie in
    one component of some transit set (to be joined in the union graph).

    For each assembly mode and transit set b (flip j, fixed signs c) whose two modes both
    have regions: every region lies in one component of b (its cells are passable for b),
    found from its first cell; regions of the two modes in one component are joined by a
    transit, labelled with the kinds of that component's cells where the flipped measure may
    vanish."""
    transits: list[RegionTransit] = []
    groups: list[list[int]] = []
    transit_cells = np.zeros((2, 3, n, n), dtype=np.int8)
    flat_bits = cells.bits.reshape(2, -1)
    for ai in range(2):
        _, first, _, _, start, slot_label = layers[ai]
        # members[b][comp]: the regions of both modes of transit set b in its component comp
        members: list[dict[int, tuple[list[int], list[int]]]] = [{} for _ in range(12)]
        joining = np.zeros((12, first.shape[1]), dtype=np.bool_)
        for b, pair in enumerate(_TRANSIT_PAIRS):
            if counts[ai, pair[0]] == 0 or counts[ai, pair[1]] == 0:
                continue
            for side, mi in enumerate(pair):
                for lab in range(1, int(counts[ai, mi]) + 1):
                    cell = int(first[mi, lab])
                    comp = int(
                        slot_label[_slot_of(int(flat_bits[ai, cell]), start, cell, BITS_B + b)]
                    )
                    members[b].setdefault(comp, ([], []))[side].append(
                        int(region_index[ai, mi, lab])
                    )
            for comp, (plus, minus) in members[b].items():
                joining[b, comp] = bool(plus and minus)
        kinds = np.zeros((12, first.shape[1], len(TRANSIT_KINDS)), dtype=np.int64)
        transit_kernel(
            cells.bits[ai], cells.kind[ai], start, slot_label, joining, kinds, transit_cells[ai]
        )
        for b in range(12):
            for comp, (plus, minus) in members[b].items():
                groups.append(plus + minus)
                found = [(TRANSIT_KINDS[k], int(v)) for k, v in enumerate(kinds[b, comp]) if v]
                names = tuple(name for name, _ in found)
                counted = tuple(v for _, v in found)
                transits.extend(
                    RegionTransit(a, b_, _FLIP_NAMES[b // 4], names, counted)
                    for a in plus
                    for b_ in minus
                )
    return transits, transit_cells, groups


def _components(count: int, groups: list[list[int]]) -> list[int]:
    """Component of each of ``count`` items once every group's members are joined
    (union-find; components numbered 0, 1, ... in the order of their roots)."""
    parent = list(range(count))

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for ids in groups:
        for other in ids[1:]:
            parent[find(other)] = find(ids[0])
    roots = sorted({find(i) for i in range(count)})
    comp_of = {r: k for k, r in enumerate(roots)}
    return [comp_of[find(i)] for i in range(count)]


def reference_region_map(design: Design, margins: Margins, n: int, split: int) -> RegionMap:
    """Build the map (the work of :func:`region_map`, uncached): classify the cells, label
    every layer, join regions through the transit sets' components."""
    theta2, theta3, h2, h3 = _grid(design, n)
    cells = _classify(design, margins, n, split)
    _drop_unused_transit_sets(cells.bits)
    labels, certified, layers = _label_layers(cells, n)
    counts = np.stack([lay[0][:8] for lay in layers])
    region_index = np.full((2, 8, int(counts.max()) + 1), -1, dtype=np.int32)
    raw: list[tuple[int, int, int]] = []  # (assembly, mode, label) of each region id
    for ai in range(2):
        for mi in range(8):
            for lab in range(1, int(counts[ai, mi]) + 1):
                region_index[ai, mi, lab] = len(raw)
                raw.append((ai, mi, lab))
    transits, transit_cells, groups = _transit_graph(cells, layers, counts, region_index, n)
    component = _components(len(raw), groups)
    regions = tuple(
        Region(
            id=i,
            assembly_mode=ASSEMBLY_MODES[ai],
            working_mode=WORKING_MODES[mi],
            label=lab,
            cells=int(layers[ai][2][mi, lab]),
            valid_cells=int(layers[ai][3][mi, lab]),
            component=component[i],
        )
        for i, (ai, mi, lab) in enumerate(raw)
    )
    status, centre_mode, m_lo, m_hi = cells.status, cells.centre_mode, cells.m_lo, cells.m_hi
    for arr in (
        theta2,
        theta3,
        status,
        labels,
        certified,
        centre_mode,
        transit_cells,
        region_index,
        m_lo,
        m_hi,
    ):
        arr.setflags(write=False)
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
