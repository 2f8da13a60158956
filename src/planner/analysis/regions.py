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
that need no path inside the cell (:func:`~planner.analysis._region_kernels._bounds_batch`):

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
:mod:`planner.planning.crossings` checks. For flip j of mode M that set is
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

import numpy as np

from planner.analysis import _region_kernels as K
from planner.analysis.region_queries import locate, prove_disconnected, regions_at
from planner.caching import BoundedCache, bounded_cache
from planner.design import Design
from planner.exceptions import InputError, check_deadline
from planner.kinematics import ASSEMBLY_MODES, WORKING_MODES
from planner.transits import TRANSIT_KINDS
from planner.validity import Margins

__all__ = [
    "DEFAULT_RESOLUTION",
    "INVALID",
    "UNDECIDED",
    "VALID",
    "Region",
    "RegionMap",
    "RegionTransit",
    "cached_region_map",
    "locate",
    "prove_disconnected",
    "region_map",
    "regions_at",
]

#: Cells per axis of a region map by default.
DEFAULT_RESOLUTION = 256
#: Sub-cells per axis on which an undecided cell is bounded again.
DEFAULT_REFINE = 4
#: Largest accepted cells per axis (memory: 2 x 8 x n^2 bytes of status).
MAX_RESOLUTION = 2048
#: Cell status codes of :attr:`RegionMap.status`.
INVALID, UNDECIDED, VALID = 0, 1, 2

_FLIP_NAMES = ("axis", "A", "B")
_REL_SLACK = 1e-9
_ABS_SLACK = 1e-12


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
    deadline: float | None = None,
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
    deadline : float, optional
        A :func:`time.monotonic` value, checked between the steps of a build (classify,
        label, join): past it, :class:`~planner.exceptions.DeadlineError` (nothing cached).

    Returns
    -------
    RegionMap
        Read-only; the same object for the same (design with its joint limits, kappa_max,
        serial_min, n, refine) while it stays in the per-process LRU cache
        ``regions.maps`` (at most 16 maps and its share of the cache budget,
        :mod:`planner.caching`: the least recently used go first).
    """
    margins = Margins() if margins is None else margins
    if not isinstance(n, int | np.integer) or isinstance(n, bool) or not 8 <= n <= MAX_RESOLUTION:
        raise InputError(f"n must be an integer in [8, {MAX_RESOLUTION}], got {n!r}")
    if not isinstance(refine, int) or isinstance(refine, bool) or not 1 <= refine <= 16:
        raise InputError(f"refine must be an integer in [1, 16], got {refine!r}")
    key = _cache_key(design, margins, n, refine)
    hit = _CACHE.get(key)
    if hit is not None:
        return hit
    rmap = _region_map(*key, deadline=deadline)
    _CACHE.put(key, rmap)
    return rmap


def cached_region_map(
    design: Design,
    margins: Margins | None = None,
    n: int = DEFAULT_RESOLUTION,
    *,
    refine: int = DEFAULT_REFINE,
) -> RegionMap | None:
    """The map :func:`region_map` would return, if it is in this process's cache now; None
    otherwise (nothing is built). The planner uses it to consult a map only when it is
    free."""
    margins = Margins() if margins is None else margins
    return _CACHE.get(_cache_key(design, margins, n, refine))


def _cache_key(design: Design, margins: Margins, n: int, refine: int) -> tuple:
    """The cache key: the design with its joint limits, the two margins a map depends on
    (``clearance`` needs obstacles), the resolution and the refinement."""
    return (design, Margins(margins.kappa_max, margins.serial_min, 0.0), int(n), refine)


#: The per-process LRU cache of :func:`region_map`: key -> map (a map of n x n cells holds
#: about 250 n^2 bytes: 16 MB at 256, 62 MB at 512; its share:
#: :data:`planner.caching.CACHES`).
_CACHE: BoundedCache[RegionMap] = bounded_cache("regions.maps")


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


#: The arrays a map keeps, in the order they are laid out in its one block of memory.
_MAP_ARRAYS = (
    ("status", (2, 8), np.int8),
    ("labels", (2, 8), np.int32),
    ("certified", (2, 8), np.int32),
    ("centre_mode", (2,), np.int8),
    ("transit_cells", (2, 3), np.int8),
    ("m_lo", (2, 3), np.float64),
    ("m_hi", (2, 3), np.float64),
)


def _map_arrays(n: int) -> dict[str, np.ndarray]:
    """The arrays a map of ``n x n`` cells keeps (uninitialised), carved out of one block.

    Why one block: most of a cold build's time on a loaded machine used to go to page faults
    on its seven fresh arrays (about 4,000 at n = 256, several microseconds each). One block
    of one size is what the allocator hands back, already mapped, when an earlier map of the
    same resolution has been freed (e.g. dropped from the LRU cache), so a later build
    writes into memory it need not fault in. Each array is C-contiguous and 64-byte aligned
    in the block; the map's ``nbytes`` accounting counts each view's own bytes."""
    sizes = [(name, (*lead, n, n), np.dtype(dt)) for name, lead, dt in _MAP_ARRAYS]
    offsets, total = [], 0
    for _, shape, dt in sizes:
        offsets.append(total)
        total += -(-math.prod(shape) * dt.itemsize // 64) * 64
    block = np.empty(total + 64, dtype=np.uint8)
    skew = -block.ctypes.data % 64
    return {
        name: block[skew + off : skew + off + math.prod(shape) * dt.itemsize]
        .view(dt)
        .reshape(shape)
        for (name, shape, dt), off in zip(sizes, offsets, strict=True)
    }


def _classify(
    design: Design,
    margins: Margins,
    n: int,
    split: int,
    *,
    mirror: bool = True,
    out: dict[str, np.ndarray] | None = None,
) -> _Cells:
    """Classify every cell of both assembly modes; with ``mirror`` and a symmetric box the
    second assembly mode is the first's mirror image (half the work, the same bounds).
    ``out``: the arrays of :func:`_map_arrays` to write status, centre modes and bounds into
    (fresh arrays without it)."""
    theta2, theta3, h2, h3 = _grid(design, n)
    a2 = 0.5 * h2 * (1.0 + _REL_SLACK)
    a3 = 0.5 * h3 * (1.0 + _REL_SLACK)
    lo, hi = margins.cd_range
    out = _map_arrays(n) if out is None else out
    cells = _Cells(
        status=out["status"],
        bits=np.empty((2, n, n), dtype=np.int64),
        kind=np.empty((2, 3, n, n), dtype=np.int8),
        centre_mode=out["centre_mode"],
        m_lo=out["m_lo"],
        m_hi=out["m_hi"],
        mirrored=mirror and _mirrored(design),
    )
    sub2, sub3 = _sub_trig(theta2, a2, split), _sub_trig(theta3, a3, split)
    fields = ("status", "bits", "kind", "centre_mode", "m_lo", "m_hi")
    mirror = cells.mirrored
    for ai in (0,) if mirror else (0, 1):
        K.classify_kernel(
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
        K.mirror_kernel(
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
        present = int(np.bitwise_or.reduce(bits[ai], axis=None)) >> K.BITS_OVER
        keep = ~0
        for b, (mp, mm) in enumerate(_TRANSIT_PAIRS):
            if not (present >> mp) & 1 or not (present >> mm) & 1:
                keep &= ~(1 << (K.BITS_B + b))
        bits[ai] &= keep


def _slot_of(bits: int, start: np.ndarray, cell: int, layer: int) -> int:
    """The slot of ``layer`` at ``cell`` (see :func:`~planner.analysis._region_kernels.label_kernel`)."""
    return int(start[cell]) + (bits & ((1 << layer) - 1)).bit_count()


def _label_layers(
    cells: _Cells, out: dict[str, np.ndarray]
) -> tuple[np.ndarray, np.ndarray, list[tuple]]:
    """Labels (2, 8, n, n) and certified labels of every (assembly, working) mode, written
    into ``out`` (:func:`_map_arrays`), and the per-assembly outputs of
    :func:`~planner.analysis._region_kernels.label_kernel`."""
    labels, certified = out["labels"], out["certified"]
    labels.fill(0)
    certified.fill(0)
    layers = [K.label_kernel(cells.bits[0], labels[0], certified[0])]
    if cells.mirrored:  # the other assembly mode's components are the mirror images
        _, _, sizes, valid, start, slot_label = layers[0]
        layers.append(
            K.mirror_label_kernel(
                cells.bits[1],
                cells.bits[0],
                start,
                slot_label,
                sizes,
                valid,
                labels[1],
                certified[1],
            )
        )
    else:
        layers.append(K.label_kernel(cells.bits[1], labels[1], certified[1]))
    return labels, certified, layers


def _transit_graph(
    cells: _Cells,
    layers: list[tuple],
    counts: np.ndarray,
    region_index: np.ndarray,
    out: dict[str, np.ndarray],
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
    transit_cells = out["transit_cells"]
    transit_cells.fill(0)
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
                        slot_label[_slot_of(int(flat_bits[ai, cell]), start, cell, K.BITS_B + b)]
                    )
                    members[b].setdefault(comp, ([], []))[side].append(
                        int(region_index[ai, mi, lab])
                    )
            for comp, (plus, minus) in members[b].items():
                joining[b, comp] = bool(plus and minus)
        kinds = np.zeros((12, first.shape[1], len(TRANSIT_KINDS)), dtype=np.int64)
        K.transit_kernel(
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


def _region_map(
    design: Design, margins: Margins, n: int, split: int, *, deadline: float | None = None
) -> RegionMap:
    """Build the map (the work of :func:`region_map`, uncached): classify the cells, label
    every layer, join regions through the transit sets' components."""
    check_deadline(deadline, "before the region map was built")
    theta2, theta3, h2, h3 = _grid(design, n)
    out = _map_arrays(n)
    cells = _classify(design, margins, n, split, out=out)
    check_deadline(deadline, "while building the region map (cells classified)")
    _drop_unused_transit_sets(cells.bits)
    labels, certified, layers = _label_layers(cells, out)
    check_deadline(deadline, "while building the region map (regions labelled)")
    counts = np.stack([lay[0][:8] for lay in layers])
    region_index = np.full((2, 8, int(counts.max()) + 1), -1, dtype=np.int32)
    raw: list[tuple[int, int, int]] = []  # (assembly, mode, label) of each region id
    for ai in range(2):
        for mi in range(8):
            for lab in range(1, int(counts[ai, mi]) + 1):
                region_index[ai, mi, lab] = len(raw)
                raw.append((ai, mi, lab))
    transits, transit_cells, groups = _transit_graph(cells, layers, counts, region_index, out)
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
