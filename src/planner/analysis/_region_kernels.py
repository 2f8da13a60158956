"""The numba kernels of :mod:`planner.analysis.regions`: cell bounds and verdicts, the
mirror image of a classified assembly mode, connected components of every layer at once,
and the transit cells.

Cells are coded as bit masks (:data:`BITS_OVER` ...) so that one pass over the grid labels
all the layers of an assembly mode (8 working modes over-approximated, 8 certified, 12
transit sets) at once: a cell belongs to a few layers only, and the work of a cell is one
union per layer it shares with each of its four earlier neighbours.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.core.errors import NumbaTypeError
from numba.core.extending import intrinsic
from numba.cpython.unsafe.numbers import trailing_zeros

__all__ = [
    "BITS_B",
    "BITS_OVER",
    "BITS_VALID",
    "BITS_ZERO",
    "LAYERS",
    "classify_kernel",
    "label_kernel",
    "mirror_kernel",
    "mirror_label_kernel",
    "transit_kernel",
]

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
                            L0, L1, L2, b_lo, b_hi, s, cc2, ss2, cc3, ss3, e2, e3,
                            sub_lo, sub_hi, sub_cen,
                        )  # fmt: skip
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
    """Index of the lowest set bit of 0 < x < 2**63 (the processor's count of trailing
    zeros)."""
    return trailing_zeros(x)


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


@intrinsic
def _ctpop(typingctx, x):  # pragma: no cover - compiled
    """LLVM's population count of an integer (one instruction where the processor has one)."""
    if not isinstance(x, types.Integer):
        raise NumbaTypeError(f"_ctpop needs an integer, got {x}")

    def codegen(context, builder, signature, args):
        return builder.ctpop(args[0])

    return x(x), codegen


@njit(cache=True, nogil=True, inline="always")
def _popcount(x):  # pragma: no cover - compiled
    """Set bits of 0 <= x < 2**63."""
    return _ctpop(x)


@njit(cache=True, nogil=True, inline="always")
def _join(parent, common, m, x0, mo, y0, fresh):  # pragma: no cover - compiled
    """Join, in every layer of ``common``, the slot of the cell (mask m, first slot x0) with
    that of a neighbour (mask mo, first slot y0). In the layers of ``fresh`` the cell's slot
    is still alone (a root without children, later than every neighbour's slot), so it is
    hung under the neighbour's root directly: the same sets as :func:`_union`, one find less."""
    while common:
        low = common & -common
        common ^= low
        below = low - 1
        x = x0 + _popcount(m & below)
        y = y0 + _popcount(mo & below)
        if fresh & low:
            parent[x] = _find(parent, y)
        else:
            _union(parent, x, y)


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
            if nb_b & m:
                _join(parent, m & nb_b, m, x0, nb_b, start[(i3 - 1) * n2 + i2], m)
            if rest:
                # a slot joined to c is no longer alone when d (or a) joins it
                if nb_c & rest:
                    _join(parent, rest & nb_c, m, x0, nb_c, start[(i3 - 1) * n2 + i2 + 1], m)
                if nb_d & rest:
                    _join(parent, rest & nb_d, m, x0, nb_d, start[i3 * n2 + i2 - 1], ~nb_c)
                if nb_a & rest & ~nb_d:
                    _join(parent, rest & ~nb_d & nb_a, m, x0, nb_a,
                          start[(i3 - 1) * n2 + i2 - 1], ~nb_c)  # fmt: skip
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
