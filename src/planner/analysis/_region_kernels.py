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


def _sign_tables() -> tuple[np.ndarray, np.ndarray]:
    """Two tables over the 64 sign patterns p (bit 2 k: sign k may be (or surely is) '+',
    bit 2 k + 1: '-'): the working modes whose three signs the pattern allows (with
    _PLUS[k] the modes whose sign k is '+', the product over k of the masks of the allowed
    signs), and the transit sets (j, c) whose two fixed signs it allows (bit 4 j + c; c = 2
    [first other sign '-'] + [second other sign '-'])."""
    modes = np.zeros(64, dtype=np.int64)
    passable = np.zeros(64, dtype=np.int64)
    for p in range(64):
        m = 0xFF
        for k in range(3):
            plus, minus = _PLUS[k], 0xFF ^ _PLUS[k]
            m &= (plus if (p >> (2 * k)) & 1 else 0) | (minus if (p >> (2 * k + 1)) & 1 else 0)
        modes[p] = m
        for j in range(3):
            o1, o2 = (1, 2) if j == 0 else (0, 2) if j == 1 else (0, 1)
            for c in range(4):
                if (p >> (2 * o1 + (c >> 1))) & 1 and (p >> (2 * o2 + (c & 1))) & 1:
                    passable[p] |= 1 << (4 * j + c)
    return modes, passable


_MODES_OF, _PASSABLE_OF = _sign_tables()


def _mirror_tables() -> tuple[np.ndarray, np.ndarray]:
    """The bit permutations of :func:`mirror_kernel`: a byte of mode bits reversed (mode mi
    -> 7 - mi) and a nibble of transit-set bits reversed (c -> 3 - c)."""
    rev8 = np.array([sum(((x >> b) & 1) << (7 - b) for b in range(8)) for x in range(256)])
    rev4 = np.array([sum(((x >> b) & 1) << (3 - b) for b in range(4)) for x in range(16)])
    return rev8.astype(np.int64), rev4.astype(np.int64)


_REV8, _REV4 = _mirror_tables()


#: Rows of the output of :func:`_bounds_batch`: lower bounds of the three measures, upper
#: bounds, the three measures and the two kind signs at the centre, and the flags. Twelve
#: rows, not thirteen: with |CD| at the centre as a thirteenth, numba 0.68 no longer ran the
#: loop on SIMD lanes (seen in its assembly; LLVM's limit on runtime overlap checks), so the
#: flags say instead whether |CD| at the centre lies in the band.
_LO, _HI, _CEN, _FLAGS, _ROWS = 0, 3, 6, 11, 12
#: Flags of a cell: all of it in the kappa band, none of it, its centre in the band.
_SURE, _MISS, _CENTRE_IN = 1, 2, 4


@njit(cache=True, nogil=True, error_model="numpy")
def _bounds_batch(L0, L1, L2, b_lo, b_hi, s, trig, a2, a3, count, out):  # pragma: no cover
    """Bounds over ``count`` closed cells at once: ``trig`` (4, count) the cosine and sine
    of theta2 and of theta3 at each centre, half-widths a2, a3 rad. Writes ``out``
    (:data:`_ROWS`, count): from rows :data:`_LO` and :data:`_HI` the bounds of the three
    serial measures over each cell's postures in the kappa band; from :data:`_CEN` their
    values at the centre (|CD| clipped into the band), then the signs of
    cos(theta4 - theta2) and cos(theta5 - theta3) there; row :data:`_FLAGS` the sum of
    :data:`_SURE` (the whole cell is in the band), :data:`_MISS` (none of it is: the other
    rows are then meaningless) and :data:`_CENTRE_IN` (|CD| at the centre is in the band).

    Every value is computed for every cell, with selects in place of branches, into two
    arrays, so that the compiler runs the loop on SIMD lanes (several cells per division
    and square root); each value is the same expression, rounded the same way (IEEE
    operations, no fast-math), as a cell-by-cell evaluation would give.

    The bounds: |CD| moves by at most r = L1 (a2 + a3) over the cell; g(d) is evaluated on
    the part of the |CD| interval inside the band; each measure U + s g V by interval
    products (:func:`_measure`); where the whole cell is in the band, the centred form along
    straight paths inside it tightens them; all widened by 1e-12 for rounding."""
    r = L1 * (a2 + a3)
    for i in range(count):
        cc2, ss2, cc3, ss3 = trig[0, i], trig[1, i], trig[2, i], trig[3, i]
        c32 = cc3 * cc2 + ss3 * ss2
        s32 = ss3 * cc2 - cc3 * ss2
        e_u = L0 + L1 * (cc3 - cc2)
        e_w = L1 * (ss3 - ss2)
        d = math.sqrt(e_u * e_u + e_w * e_w)
        d_lo, d_hi = d - r, d + r
        sure = (d_lo >= b_lo) & (d_hi <= b_hi)
        miss = (d_hi < b_lo) | (d_lo > b_hi)
        dv_lo = min(max(d_lo, b_lo), b_hi)
        dv_hi = min(max(d_hi, b_lo), b_hi)
        g_lo = math.sqrt(max(L2 * L2 / (dv_hi * dv_hi) - 0.25, 0.0))
        g_hi = math.sqrt(max(L2 * L2 / (dv_lo * dv_lo) - 0.25, 0.0))
        dc = min(max(d, b_lo), b_hi)
        g_c = math.sqrt(max(L2 * L2 / (dc * dc) - 0.25, 0.0))
        x_a = L1 * s32 - L0 * ss2
        y_a = L0 * cc2 + L1 * c32 - L1
        x_b = L1 * s32 - L0 * ss3
        y_b = L0 * cc3 + L1 - L1 * c32
        # the three signed measures U + s g V (module docstring of planner.analysis.regions)
        u0, r_u0, v0, r_v0, n0 = 0.5 * L1 * (ss2 + ss3), 0.5 * r, e_u, r, L1 + L2
        u1, r_u1, v1, r_v1 = 0.5 * x_a, 0.5 * (r + L0 * a2), y_a, r + L0 * a2
        u2, r_u2, v2, r_v2 = -0.5 * x_b, 0.5 * (r + L0 * a3), y_b, r + L0 * a3
        lo0, hi0, ce0 = _measure(u0, r_u0, v0, r_v0, n0, g_lo, g_hi, g_c, s)
        lo1, hi1, ce1 = _measure(u1, r_u1, v1, r_v1, L2, g_lo, g_hi, g_c, s)
        lo2, hi2, ce2 = _measure(u2, r_u2, v2, r_v2, L2, g_lo, g_hi, g_c, s)
        # all of the cell in the band: the centred form along straight paths inside it
        rl, rh = d_lo / (2.0 * L2), min(d_hi / (2.0 * L2), 1.0)
        s_apex = min(
            2.0 * rl * math.sqrt(max(1.0 - rl * rl, 0.0)),
            2.0 * rh * math.sqrt(max(1.0 - rh * rh, 0.0)),
        )
        centred = sure & (s_apex > 0.0)
        r45 = r / (L2 * s_apex)
        w0 = (L1 * min(a2, a3) + L2 * r45) / (L1 + L2)
        w1 = r45 + a2
        w2 = r45 + a3
        lo0 = max(lo0, ce0 - w0) if centred else lo0
        hi0 = min(hi0, ce0 + w0) if centred else hi0
        lo1 = max(lo1, ce1 - w1) if centred else lo1
        hi1 = min(hi1, ce1 + w1) if centred else hi1
        lo2 = max(lo2, ce2 - w2) if centred else lo2
        hi2 = min(hi2, ce2 + w2) if centred else hi2
        out[0, i] = lo0 - 1e-12
        out[1, i] = lo1 - 1e-12
        out[2, i] = lo2 - 1e-12
        out[3, i] = hi0 + 1e-12
        out[4, i] = hi1 + 1e-12
        out[5, i] = hi2 + 1e-12
        out[6, i], out[7, i], out[8, i] = ce0, ce1, ce2
        # kinds at the centre: signs of cos(theta4 - theta2), cos(theta5 - theta3)
        out[9, i] = 0.5 * y_a - s * g_c * x_a
        out[10, i] = -0.5 * y_b - s * g_c * x_b
        centre_in = (b_lo <= d) & (d <= b_hi)
        out[11, i] = (1.0 if sure else 0.0) + (2.0 if miss else 0.0) + (4.0 if centre_in else 0.0)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _measure(u, r_u, v, r_v, norm, g_lo, g_hi, g_c, s):  # pragma: no cover - compiled
    """Bounds (lo, hi) of one signed measure (u + s g v) / norm over a cell (u within r_u,
    v within r_v, g in [g_lo, g_hi]) by interval products, and its value at the centre."""
    v_lo, v_hi = v - r_v, v + r_v
    p_lo = v_lo * g_hi if v_lo < 0.0 else v_lo * g_lo
    p_hi = v_hi * g_hi if v_hi > 0.0 else v_hi * g_lo
    n_lo, n_hi = -p_hi, -p_lo
    if s < 0:
        p_lo, p_hi = n_lo, n_hi
    return (u - r_u + p_lo) / norm, (u + r_u + p_hi) / norm, (u + s * g_c * v) / norm


@njit(cache=True, nogil=True, inline="always")
def _decide(sure, miss, out, i, smin):  # pragma: no cover
    """The masks of cell (or sub-cell) i from its bounds (rows of :func:`_bounds_batch`):
    (over, valid, passable), bit mi of the first two for working mode mi (not surely
    invalid; surely valid), bit 4 j + c of the third for transit set (j, c) (not surely
    outside it).

    Mode mi is surely invalid when a signed measure's upper bound is below ``serial_min``
    and surely valid when the cell is all in the band and every signed lower bound is at
    least ``serial_min``; a transit set is passable unless one of its two fixed signed
    measures is surely below ``serial_min``. The six comparisons of each kind index the
    tables of :func:`_sign_tables`."""
    if miss:
        return 0, 0, 0
    can = 0  # bit 2 k: measure k may be >= smin; bit 2 k + 1: may be <= -smin
    sure_of = 0  # bit 2 k: measure k is surely >= smin; bit 2 k + 1: surely <= -smin
    for k in range(3):
        lo, hi = out[_LO + k, i], out[_HI + k, i]
        can |= ((1 if hi >= smin else 0) << (2 * k)) | ((1 if -lo >= smin else 0) << (2 * k + 1))
        sure_of |= ((1 if lo >= smin else 0) << (2 * k)) | (
            (1 if -hi >= smin else 0) << (2 * k + 1)
        )
    return _MODES_OF[can], _MODES_OF[sure_of] if sure else 0, _PASSABLE_OF[can]


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
    :func:`_bounds_batch`. A cell left undecided in some mode is split into ``split x split``
    closed sub-cells (their union is the cell; ``sub2`` (n2, split, 2) and ``sub3`` hold
    the cosine and sine of their centres): it is surely valid (invalid) in a mode when every
    sub-cell is, passable for a transit set when some sub-cell is, and the bounds are the
    hull of the sub-cells'. Writes status (8, n, n), bits (n, n) (the masks of the module
    docstring), kind (3, n, n) (index in TRANSIT_KINDS at the centre), centre_mode (n, n)
    and the bounds (3, n, n) (NaN where no posture is in the band)."""
    n3, n2 = theta3.shape[0], theta2.shape[0]
    b2, b3 = a2 / split, a3 / split
    e2, e3 = b2 * (1.0 + 1e-9), b3 * (1.0 + 1e-9)
    per = split * split
    # the row's cells, then the sub-cells of its undecided cells
    trig_r, out_r = np.empty((4, n2)), np.empty((_ROWS, n2))
    trig_s, out_s = np.empty((4, n2 * per)), np.empty((_ROWS, n2 * per))
    trig_r[0], trig_r[1] = np.cos(theta2), np.sin(theta2)
    over_r = np.empty(n2, dtype=np.int64)
    valid_r = np.empty(n2, dtype=np.int64)
    pass_r = np.empty(n2, dtype=np.int64)
    miss_r = np.empty(n2, dtype=np.bool_)
    todo = np.empty(n2, dtype=np.int64)
    for i3 in range(n3):
        t3 = theta3[i3]
        trig_r[2] = math.cos(t3)
        trig_r[3] = math.sin(t3)
        _bounds_batch(L0, L1, L2, b_lo, b_hi, s, trig_r, a2, a3, n2, out_r)
        nt = 0
        for i2 in range(n2):
            fl = int(out_r[_FLAGS, i2])
            miss = fl & _MISS != 0
            over, valid, passable = _decide(fl & _SURE != 0, miss, out_r, i2, smin)
            over_r[i2], valid_r[i2], pass_r[i2], miss_r[i2] = over, valid, passable, miss
            if over != valid and split > 1:
                todo[nt] = i2
                nt += 1
        if nt:
            _refine_row(
                L0,
                L1,
                L2,
                b_lo,
                b_hi,
                smin,
                s,
                e2,
                e3,
                split,
                sub2,
                sub3[i3],
                todo[:nt],
                trig_s,
                out_s,
                out_r,
                over_r,
                valid_r,
                pass_r,
                miss_r,
            )
        _write_row(
            out_r,
            over_r,
            valid_r,
            pass_r,
            miss_r,
            status[:, i3],
            bits[i3],
            kind[:, i3],
            centre_mode[i3],
            m_lo_out[:, i3],
            m_hi_out[:, i3],
        )


@njit(cache=True, nogil=True)
def _refine_row(
    L0,
    L1,
    L2,
    b_lo,
    b_hi,
    smin,
    s,
    e2,
    e3,
    split,
    sub2,
    sub3_row,
    todo,
    trig_s,
    out_s,
    out_r,
    over_r,
    valid_r,
    pass_r,
    miss_r,
):  # pragma: no cover - compiled
    """The refinement step of :func:`classify_kernel` for one row: the cells ``todo``
    (indices into the row) left undecided in some mode are bounded on their ``split x
    split`` sub-cells (centres from ``sub2`` and the row's ``sub3_row`` (split, 2), half-
    widths ``e2``, ``e3``; scratch ``trig_s``, ``out_s``), and their masks (``over_r``,
    ``valid_r``, ``pass_r``, ``miss_r``) and bounds (rows of ``out_r``) replaced by those of
    the sub-cells together."""
    per = split * split
    j = 0
    for t in range(todo.shape[0]):
        i2 = todo[t]
        for p3 in range(split):
            for p2 in range(split):
                trig_s[0, j], trig_s[1, j] = sub2[i2, p2, 0], sub2[i2, p2, 1]
                trig_s[2, j], trig_s[3, j] = sub3_row[p3, 0], sub3_row[p3, 1]
                j += 1
    _bounds_batch(L0, L1, L2, b_lo, b_hi, s, trig_s, e2, e3, j, out_s)
    for t in range(todo.shape[0]):
        # undecided in some mode: refined. Surely valid (invalid) where every sub-cell
        # is, passable where some sub-cell is; bounds: the hull of the sub-cells'.
        i2 = todo[t]
        any_in = False
        over, valid, passable = 0, 0xFF, 0
        lo0 = lo1 = lo2 = np.inf
        hi0 = hi1 = hi2 = -np.inf
        for j in range(t * per, (t + 1) * per):
            fl = int(out_s[_FLAGS, j])
            smiss = fl & _MISS != 0
            so, sv, sp = _decide(fl & _SURE != 0, smiss, out_s, j, smin)
            over |= so
            valid &= sv
            passable |= sp
            if not smiss:
                any_in = True
                lo0, hi0 = min(lo0, out_s[_LO, j]), max(hi0, out_s[_HI, j])
                lo1, hi1 = min(lo1, out_s[_LO + 1, j]), max(hi1, out_s[_HI + 1, j])
                lo2, hi2 = min(lo2, out_s[_LO + 2, j]), max(hi2, out_s[_HI + 2, j])
        out_r[_LO, i2], out_r[_LO + 1, i2], out_r[_LO + 2, i2] = lo0, lo1, lo2
        out_r[_HI, i2], out_r[_HI + 1, i2], out_r[_HI + 2, i2] = hi0, hi1, hi2
        over_r[i2], valid_r[i2], pass_r[i2] = over, valid, passable
        miss_r[i2] = not any_in


@njit(cache=True, nogil=True)
def _write_row(
    out_r, over_r, valid_r, pass_r, miss_r, status, bits, kind, centre_mode, m_lo, m_hi
):  # pragma: no cover - compiled
    """The output step of :func:`classify_kernel` for one row: from the row's masks and
    bounds, its cells' status (8, n2), bits (n2,), kind (3, n2), centre_mode (n2,) and
    bounds m_lo, m_hi (3, n2) (views of the row in the kernel's outputs)."""
    for i2 in range(out_r.shape[1]):
        over, valid, miss = over_r[i2], valid_r[i2], miss_r[i2]
        for mi in range(8):
            status[mi, i2] = ((over >> mi) & 1) + ((valid >> mi) & 1)
        mask = (over << BITS_OVER) | (valid << BITS_VALID) | (pass_r[i2] << BITS_B)
        centre_mode[i2] = -1
        kind[0, i2] = 0
        kind[1, i2] = 1 if miss or out_r[_CEN + 3, i2] >= 0.0 else 2
        kind[2, i2] = 3 if miss or out_r[_CEN + 4, i2] >= 0.0 else 4
        for k in range(3):
            lo, hi = out_r[_LO + k, i2], out_r[_HI + k, i2]
            if miss:
                m_lo[k, i2] = np.nan
                m_hi[k, i2] = np.nan
            else:
                if lo <= 0.0 and hi >= 0.0:
                    mask |= 1 << (BITS_ZERO + k)
                m_lo[k, i2] = lo
                m_hi[k, i2] = hi
        bits[i2] = mask
        # a sign within rounding of 0 (e.g. the base point of erratum 6) is no sign
        tiny = 1e-12
        c0, c1, c2 = out_r[_CEN, i2], out_r[_CEN + 1, i2], out_r[_CEN + 2, i2]
        if (
            not miss
            and int(out_r[_FLAGS, i2]) & _CENTRE_IN
            and abs(c0) > tiny
            and abs(c1) > tiny
            and abs(c2) > tiny
        ):
            centre_mode[i2] = 4 * (c0 < 0.0) + 2 * (c1 < 0.0) + (c2 < 0.0)


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
            v = (_REV8[(w >> BITS_OVER) & 0xFF] << BITS_OVER) | (
                _REV8[(w >> BITS_VALID) & 0xFF] << BITS_VALID
            )
            for j in range(3):
                v |= _REV4[(w >> (BITS_B + 4 * j)) & 0xF] << (BITS_B + 4 * j)
            bits_m[j3, j2] = v | (w & (7 << BITS_ZERO))
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
                    _join(
                        parent,
                        rest & ~nb_d & nb_a,
                        m,
                        x0,
                        nb_a,
                        start[(i3 - 1) * n2 + i2 - 1],
                        ~nb_c,
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
def _cut(a, top):  # pragma: no cover - compiled
    """The first ``top`` columns of ``a`` (rows, m), zeros added where m < top, as a new
    C-contiguous array."""
    out = np.zeros((a.shape[0], top), dtype=a.dtype)
    m = min(top, a.shape[1])
    out[:, :m] = a[:, :m]
    return out


@njit(cache=True, nogil=True)
def mirror_label_kernel(
    bits, bits_src, start_src, label_src, sizes_src, valid_src, over, certified
):  # pragma: no cover - compiled
    """:func:`label_kernel` of the mirror image of a labelled assembly mode, without
    union-find: the component of layer b at cell (k3, k2) is that of the mirrored layer
    (modes mi -> 7 - mi, transit sets (j, c) -> (j, 3 - c)) at (n - 1 - k3, n - 1 - k2) in
    the source, renumbered in this raster order. ``bits`` are the mirrored masks of
    :func:`mirror_kernel` (with the same transit sets dropped, a layer whole or not at
    all), ``bits_src``, ``start_src``, ``label_src``, ``sizes_src`` and ``valid_src`` the
    source's masks, slot starts, slot labels, component sizes and surely valid cells: a
    component's cells are its source's, so its sizes are copied, not counted. Same
    returns."""
    n3, n2 = bits.shape
    full = (1 << LAYERS) - 1
    start = _slot_starts(bits)
    total = start[n3 * n2]
    top = max(2, sizes_src.shape[1])
    renumber = np.zeros((LAYERS, top), dtype=np.int64)
    source = np.zeros(LAYERS, dtype=np.int64)  # the source layer of each layer
    for b in range(LAYERS):
        if b < BITS_VALID:
            source[b] = 7 - b
        elif b < BITS_B:
            source[b] = BITS_VALID + 7 - (b - BITS_VALID)
        else:
            source[b] = b - (b - BITS_B) % 4 + 3 - (b - BITS_B) % 4
    counts = np.zeros(LAYERS, dtype=np.int64)
    first = np.zeros((LAYERS, top), dtype=np.int64)
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
                lab = label_src[y0 + _popcount(m_src & ((1 << source[b]) - 1))]
                if renumber[b, lab] == 0:
                    counts[b] += 1
                    renumber[b, lab] = counts[b]
                    first[b, counts[b]] = i3 * n2 + i2
                slot_label[x] = renumber[b, lab]
                if b < BITS_VALID:
                    over[b, i3, i2] = slot_label[x]
                elif b < BITS_B:
                    certified[b - BITS_VALID, i3, i2] = slot_label[x]
                x += 1
    sizes = np.zeros((LAYERS, top), dtype=np.int64)
    valid = np.zeros((8, top), dtype=np.int64)
    for b in range(LAYERS):
        for lab in range(1, top):
            new = renumber[b, lab]
            if new:
                sizes[b, new] = sizes_src[source[b], lab]
                if b < BITS_VALID:
                    valid[b, new] = valid_src[7 - b, lab]
    top = 1 + max(1, counts.max())
    return counts, _cut(first, top), _cut(sizes, top), _cut(valid, top), start, slot_label


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
