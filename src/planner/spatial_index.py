"""A bounding-volume hierarchy over obstacle rows, built once per obstacle set (numpy and
numba, no I/O).

Why: a validity check measures the distance from each of four link segments to the nearest
obstacle. Looping over every obstacle costs time linear in their number (1,000 spheres made
a plan take a second); a hierarchy of boxes lets the query skip every group of obstacles whose
box is farther than the best distance found so far, so its cost grows roughly with the
logarithm of the count. Library trees (scipy's ``cKDTree``) answer point queries from
Python; the kernels here need segment queries with a signed-distance bound from inside
compiled code, so the tree is a few flat arrays that the numba kernels read.

Layout (one tree per obstacle kind, :func:`build_tree`):

* the kind's rows are reordered along a Morton (Z-order) curve of their box centres, so that
  consecutive rows are near each other; leaf ``k`` holds rows ``k * LEAF .. (k + 1) * LEAF``
  (a kind of at most :data:`TREE_FROM` rows has one leaf, its whole loop);
* the tree is complete and implicit, ``M`` leaves (a power of two), ``2 M - 1`` nodes, the
  children of node ``i`` at ``2 i + 1`` and ``2 i + 2``, leaf ``k`` at node ``M - 1 + k``;
* node row ``[lo (3), hi (3), rho]``: the axis-aligned box holding every obstacle below the
  node, and the largest *depth* ``rho`` of one of them (how far inside it a point can be:
  a sphere's or capsule's radius, a box's smallest half size); an empty node has
  ``lo > hi``.

The bound (:func:`node_lower_bound`), for a segment S and any obstacle O below a node with
box B: O lies inside B, so when S misses B the signed distance of S to O is at least the
distance of S to B; when S meets B, the signed distance of S to O is at least ``-rho`` (no
point is deeper inside O than its depth). Both are *lower* bounds of the signed distance,
which is what lets a query prune a node: a node whose bound reaches the best distance found
holds no closer obstacle. The distance of a segment to a box is exact (the piecewise-quadratic
minimisation of :func:`local_segment_box_sq`) up to round-off, which :data:`BOUND_SLACK`
covers; the distance between the segment's own bounding box and B, cheaper and never
larger, is tried first.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = [
    "BOUND_SLACK",
    "GRID_CELLS",
    "GRID_FROM",
    "GRID_TO",
    "LEAF",
    "TREE_FROM",
    "build_grid",
    "build_tree",
    "local_segment_box_sq",
    "node_lower_bound",
    "row_boxes",
]

#: Taken off every distance bound of a node, m: far above the round-off of the box distance
#: (about 1e-16 of the coordinates, 1e-12 m at the wire's largest coordinate), far below any
#: clearance. The adversarial test (a segment 1 nm inside a cloud's balls) found a bound of
#: 1e-17 m where the true signed distance was -1e-9 m before it was there.
BOUND_SLACK = 1e-9
#: Obstacle rows per leaf of a tree.
LEAF = 16
#: Kinds with at most this many rows get a one-leaf tree: the plain loop. Measured (the
#: planner's checks, 4,000 postures, side by side): the walk is 33x (10,000-point cloud) and
#: 290x (100,000) faster than the loop over a cloud on a cell's surfaces, but 1.2-1.5x slower
#: over 100-1,000 small spheres strewn through the whole workspace, where a link has many
#: obstacles within its reach; the loop is kept up to here.
TREE_FROM = 1024
#: Bits per axis of the Morton code (30-bit codes).
_MORTON_BITS = 10


@njit(cache=True, inline="always")
def _cmp_swap(a, b):  # pragma: no cover - compiled
    return (a, b) if a <= b else (b, a)


@njit(cache=True, inline="always")
def _cuts(p, u, h):  # pragma: no cover - compiled
    """The parameters t in (0, 1) where p + t u = -h and = +h; 1.0 for each one outside."""
    lo = hi = 1.0
    if u != 0.0:
        t = (-h - p) / u
        if 0.0 < t < 1.0:
            lo = t
        t = (h - p) / u
        if 0.0 < t < 1.0:
            hi = t
    return lo, hi


@njit(cache=True)
def local_segment_box_sq(p, u, h):  # pragma: no cover - compiled
    """Least squared distance from the segment ``p + t u`` (t in [0, 1]) to the box
    ``|x_i| <= h_i`` (3-tuples in the box's own frame); 0 when the segment meets the box.

    The squared outside distance of the point at parameter t is
    ``sum_i max(|p_i(t)| - h_i, 0)^2``; between the parameters where some p_i(t) = +-h_i the
    active terms and their signs are fixed, so it is one quadratic per piece, minimised in
    closed form."""
    # the parameters where some |p_i(t)| = h_i, inside (0, 1); 1.0 where there is none (a
    # piece of length zero changes nothing)
    c0, c1 = _cuts(p[0], u[0], h[0])
    c2, c3 = _cuts(p[1], u[1], h[1])
    c4, c5 = _cuts(p[2], u[2], h[2])
    # sorting network on the six cuts (12 compare-exchanges)
    c0, c5 = _cmp_swap(c0, c5)
    c1, c3 = _cmp_swap(c1, c3)
    c2, c4 = _cmp_swap(c2, c4)
    c1, c2 = _cmp_swap(c1, c2)
    c3, c4 = _cmp_swap(c3, c4)
    c0, c3 = _cmp_swap(c0, c3)
    c2, c5 = _cmp_swap(c2, c5)
    c0, c1 = _cmp_swap(c0, c1)
    c2, c3 = _cmp_swap(c2, c3)
    c4, c5 = _cmp_swap(c4, c5)
    c1, c2 = _cmp_swap(c1, c2)
    c3, c4 = _cmp_swap(c3, c4)
    c = (0.0, c0, c1, c2, c3, c4, c5, 1.0)
    best = np.inf
    for k in range(7):
        t0, t1 = c[k], c[k + 1]
        if t1 <= t0 and k > 0:
            continue
        tm = 0.5 * (t0 + t1)
        saa = 0.0
        sab = 0.0
        for i in range(3):
            x = p[i] + tm * u[i]
            if abs(x) > h[i]:
                sg = 1.0 if x > 0.0 else -1.0
                al = sg * p[i] - h[i]
                be = sg * u[i]
                saa += be * be
                sab += al * be
        t = t0
        if saa > 0.0:
            t = min(max(-sab / saa, t0), t1)
        f = 0.0
        for i in range(3):
            x = abs(p[i] + t * u[i]) - h[i]
            if x > 0.0:
                f += x * x
        best = min(best, f)
    return best


@njit(cache=True, inline="always")
def node_lower_bound(
    node, ax, ay, az, bx, by, bz, slo0, slo1, slo2, shi0, shi1, shi2, best
):  # pragma: no cover - compiled
    """A lower bound (m) on the signed distance from segment a-b to every obstacle below a
    node row (module docstring); ``slo``/``shi`` the segment's bounding box. ``inf`` for an
    empty node. When the cheap box-to-box distance already reaches ``best`` it is returned
    as it is (still a lower bound, and enough to prune)."""
    if node[0] > node[3]:
        return np.inf
    gx = max(node[0] - shi0, slo0 - node[3], 0.0)
    gy = max(node[1] - shi1, slo1 - node[4], 0.0)
    gz = max(node[2] - shi2, slo2 - node[5], 0.0)
    coarse = math.sqrt(gx * gx + gy * gy + gz * gz) - BOUND_SLACK
    if coarse > 0.0 and coarse >= best:
        return coarse
    hx, hy, hz = 0.5 * (node[3] - node[0]), 0.5 * (node[4] - node[1]), 0.5 * (node[5] - node[2])
    cx, cy, cz = node[0] + hx, node[1] + hy, node[2] + hz
    d2 = local_segment_box_sq(
        (ax - cx, ay - cy, az - cz), (bx - ax, by - ay, bz - az), (hx, hy, hz)
    )
    d = math.sqrt(d2) - BOUND_SLACK
    if d > 0.0:
        return d
    return -node[6]


def row_boxes(kind: int, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bounding boxes ``lo``, ``hi`` (N, 3) and depths (N,) of packed obstacle rows of one
    kind (0 sphere ``[c, r]``, 1 capsule ``[a, b, r]``, 2 box ``[c, R (9), h]``: the layout
    of :func:`planner.geometry.pack_obstacles`)."""
    if kind == 0:
        r = rows[:, 3:4]
        return rows[:, :3] - r, rows[:, :3] + r, rows[:, 3].copy()
    if kind == 1:
        r = rows[:, 6:7]
        lo = np.minimum(rows[:, :3], rows[:, 3:6]) - r
        hi = np.maximum(rows[:, :3], rows[:, 3:6]) + r
        return lo, hi, rows[:, 6].copy()
    rot = rows[:, 3:12].reshape(-1, 3, 3)
    h = rows[:, 12:15]
    ext = np.einsum("nij,nj->ni", np.abs(rot), h)  # half extents of the rotated box
    return rows[:, :3] - ext, rows[:, :3] + ext, h.min(axis=1)


def _morton(points: np.ndarray) -> np.ndarray:
    """30-bit Morton codes of points (N, 3) quantised over their own bounding box."""
    lo = points.min(axis=0)
    span = np.maximum(points.max(axis=0) - lo, 1e-300)
    cells = (1 << _MORTON_BITS) - 1
    q = np.clip(((points - lo) / span * cells).astype(np.int64), 0, cells)
    code = np.zeros(len(points), dtype=np.int64)
    for bit in range(_MORTON_BITS):
        for axis in range(3):
            code |= ((q[:, axis] >> bit) & 1) << (3 * bit + axis)
    return code


@njit(cache=True)
def _fill_nodes(lo, hi, rho, n_leaves, nodes):  # pragma: no cover - compiled
    """Node rows of the implicit tree, leaves first, then every parent from its children."""
    n = lo.shape[0]
    first = n_leaves - 1
    for k in range(n_leaves):
        row = nodes[first + k]
        for j in range(3):
            row[j] = np.inf
            row[3 + j] = -np.inf
        row[6] = -np.inf
        for i in range(k * LEAF, min((k + 1) * LEAF, n)):
            for j in range(3):
                row[j] = min(row[j], lo[i, j])
                row[3 + j] = max(row[3 + j], hi[i, j])
            row[6] = max(row[6], rho[i])
    for i in range(first - 1, -1, -1):
        a, b = nodes[2 * i + 1], nodes[2 * i + 2]
        for j in range(3):
            nodes[i, j] = min(a[j], b[j])
            nodes[i, 3 + j] = max(a[3 + j], b[3 + j])
        nodes[i, 6] = max(a[6], b[6])


def build_tree(kind: int, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows of one obstacle kind reordered along the Morton curve, and the node rows of
    their tree (layout in the module docstring): ``(rows (N, k), nodes (2 M - 1, 7))``;
    ``nodes`` has no row when there is no obstacle."""
    n = len(rows)
    if n == 0:
        return rows, np.empty((0, 7))
    lo, hi, rho = row_boxes(kind, rows)
    if n <= TREE_FROM:
        # one leaf, looped in any order: no Morton codes (they cost ~30 numpy calls, the
        # better part of packing five spheres, which every plan in a small scene does)
        root = np.concatenate([lo.min(axis=0), hi.max(axis=0), [rho.max()]])
        return np.ascontiguousarray(rows), root[None, :]
    order = np.argsort(_morton(0.5 * (lo + hi)), kind="stable")
    rows = np.ascontiguousarray(rows[order])
    n_leaves = 1 if n <= TREE_FROM else 1 << math.ceil(math.log2(math.ceil(n / LEAF)))
    nodes = np.empty((2 * n_leaves - 1, 7))
    _fill_nodes(
        np.ascontiguousarray(lo[order]),
        np.ascontiguousarray(hi[order]),
        rho[order],
        n_leaves,
        nodes,
    )
    return rows, nodes


# ------------------------------------------------------------------------------ the grid
#: Sphere rows (balls and cloud points) of at least ``GRID_FROM`` and at most ``GRID_TO``
#: get a uniform grid besides their tree (:func:`build_grid`), walked first by
#: :func:`planner.geometry.segment_min_distance`. Why: between the two the balls are
#: usually strewn through the space the links sweep (1,000 small spheres in a shell round
#: the robot); then every link has several within reach and the tree's boxes, each holding
#: balls far apart, cannot prune (its walk cost 1.2-1.5x the plain loop there), while the
#: cells round a link hold the few balls that matter. Above ``GRID_TO`` rows a cloud lies on
#: surfaces, mostly far from a link, which the tree prunes in bulk (33-290x the loop).
GRID_FROM = 256
GRID_TO = 8192
#: Most cells of a grid (the cell edge grows to keep within it).
GRID_CELLS = 1 << 18
#: Least cell edge, m.
_GRID_MIN_EDGE = 0.02
#: Layout of a grid (one float array, :func:`build_grid`): a header of ``GRID_HEADER``
#: values, origin (3), edge, cells per axis (3), the largest ball radius; then the
#: ``n_cells + 1`` offsets of each cell's rows; then the row numbers, cell by cell.
GRID_HEADER = 8


def build_grid(rows: np.ndarray) -> np.ndarray:
    """A uniform grid over sphere rows ``[c, r]`` (N, 4), each row in the cell of its
    centre, as one float array (layout at :data:`GRID_HEADER`; integers below 2^53 are
    exact in it); an empty array when the count is outside ``GRID_FROM .. GRID_TO``.

    The edge is the mean spacing of the balls over their bounding box (one a cell on
    average), at least 2 cm, and grown until the grid has at most :data:`GRID_CELLS`
    cells."""
    n = len(rows)
    if not GRID_FROM <= n <= GRID_TO:
        return np.empty(0)
    c = rows[:, :3]
    lo = c.min(axis=0)
    span = np.maximum(c.max(axis=0) - lo, 1e-9)
    volume = float(np.prod(np.maximum(span, _GRID_MIN_EDGE)))
    edge = max(_GRID_MIN_EDGE, (volume / n) ** (1 / 3))
    while True:
        dims = np.floor(span / edge).astype(np.int64) + 1
        if int(np.prod(dims)) <= GRID_CELLS:
            break
        edge *= 1.25
    cell = np.minimum(np.floor((c - lo) / edge).astype(np.int64), dims - 1)
    flat = (cell[:, 0] * dims[1] + cell[:, 1]) * dims[2] + cell[:, 2]
    order = np.argsort(flat, kind="stable")
    counts = np.bincount(flat, minlength=int(np.prod(dims)))
    offsets = np.concatenate([[0], np.cumsum(counts)])
    header = [*lo, edge, *dims, float(rows[:, 3].max())]
    return np.concatenate(
        [np.asarray(header, dtype=float), offsets.astype(float), order.astype(float)]
    )
