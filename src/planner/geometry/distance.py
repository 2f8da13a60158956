"""The compiled distances between segments (the links' axes) and packed obstacles
(:mod:`planner.geometry`, "Why each routine is right"), and the library's segment distance
query :func:`segment_obstacle_distance`."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit

from planner._kernels import read_only
from planner.exceptions import InputError
from planner.geometry.packing import PackedObstacles, pack_obstacles
from planner.geometry.shapes import Obstacle
from planner.spatial_index import (
    BOUND_SLACK,
    GRID_HEADER,
    LEAF,
    local_segment_box_sq,
    node_lower_bound,
)

__all__ = [
    "LINE_SEARCH_TOL",
    "box_sdf",
    "point_segment_distance",
    "segment_box_distance",
    "segment_convex_distance",
    "segment_min_distance",
    "segment_obstacle_distance",
]

#: Relative bracket (fraction of the segment) at which the golden-section search stops.
LINE_SEARCH_TOL = 1e-10
#: First radius of a relaxed sphere-grid query (:func:`_spheres_min`), a multiple of its
#: threshold t (or a quarter cell, the larger). A scan at radius r answers a relaxed query
#: when the least distance found is at most t + (r - t) / (1 - relax): at r = t that is only
#: when the rule is broken, so every posture that keeps the rule (most of those a
#: certificate evaluates) paid a second, larger scan. From 1.5 t a clearance up to 2 t is
#: answered by the first scan. Measured (the product's ``plan``, each query's least CPU of
#: 4-5 passes; before -> after): the fair table's 1,000 spheres, query seed 23, p50 / p95
#: 1.13-1.19 / 8.7-8.9 -> 1.00 / 8.3 ms, seed 11 0.30-0.31 / 2.8-2.9 -> 0.33 / 2.3 ms;
#: 1,500 balls 1.26 / 8.2 -> 1.03 / 5.5 ms; 3,000 balls 0.46 / 10.3 -> 0.37 / 7.4 ms; 400
#: balls (a coarser grid, where a quarter cell is above 1.5 t already) 1.12-1.18 / 7.9-8.0
#: -> 1.20 / 8.3 ms, sums of the 30 queries 134-136 -> 135 ms. The same paths and verdicts
#: on the fair scenes' 80 queries each (their hashes).
RELAXED_FIRST_REACH = 1.5
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
# iterations so that _GOLDEN ** n <= LINE_SEARCH_TOL
_GOLDEN_ITERATIONS = math.ceil(math.log(LINE_SEARCH_TOL) / math.log(_GOLDEN))


@njit(cache=True, inline="always")
def point_segment_distance(px, py, pz, ax, ay, az, bx, by, bz):  # pragma: no cover - compiled
    """Distance from point p to segment a-b (closed form: clamp the projection)."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    vx, vy, vz = px - ax, py - ay, pz - az
    uu = ux * ux + uy * uy + uz * uz
    t = 0.0
    if uu > 0.0:
        t = (vx * ux + vy * uy + vz * uz) / uu
        t = min(max(t, 0.0), 1.0)
    dx, dy, dz = vx - t * ux, vy - t * uy, vz - t * uz
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True, inline="always")
def box_sdf(px, py, pz, box):  # pragma: no cover - compiled
    """Signed distance from a point to a packed box row (negative inside)."""
    dx, dy, dz = px - box[0], py - box[1], pz - box[2]
    # local = R^T d
    lx = box[3] * dx + box[6] * dy + box[9] * dz
    ly = box[4] * dx + box[7] * dy + box[10] * dz
    lz = box[5] * dx + box[8] * dy + box[11] * dz
    qx, qy, qz = abs(lx) - box[12], abs(ly) - box[13], abs(lz) - box[14]
    ox, oy, oz = max(qx, 0.0), max(qy, 0.0), max(qz, 0.0)
    return math.sqrt(ox * ox + oy * oy + oz * oz) + min(max(qx, max(qy, qz)), 0.0)


@njit(cache=True, inline="always")
def _seg_to_row(kind, t, ax, ay, az, bx, by, bz, row):  # pragma: no cover - compiled
    px, py, pz = ax + t * (bx - ax), ay + t * (by - ay), az + t * (bz - az)
    if kind == 1:
        return (
            point_segment_distance(px, py, pz, row[0], row[1], row[2], row[3], row[4], row[5])
            - row[6]
        )
    return box_sdf(px, py, pz, row)


@njit(cache=True)
def segment_convex_distance(kind, ax, ay, az, bx, by, bz, row):  # pragma: no cover - compiled
    """Signed distance from segment a-b to a capsule (kind 1) or box (kind 2) row: golden-
    section minimisation over the segment parameter of a convex function."""
    lo, hi = 0.0, 1.0
    x1 = hi - _GOLDEN * (hi - lo)
    x2 = lo + _GOLDEN * (hi - lo)
    f1 = _seg_to_row(kind, x1, ax, ay, az, bx, by, bz, row)
    f2 = _seg_to_row(kind, x2, ax, ay, az, bx, by, bz, row)
    for _ in range(_GOLDEN_ITERATIONS):
        if f1 <= f2:
            hi = x2
            x2, f2 = x1, f1
            x1 = hi - _GOLDEN * (hi - lo)
            f1 = _seg_to_row(kind, x1, ax, ay, az, bx, by, bz, row)
        else:
            lo = x1
            x1, f1 = x2, f2
            x2 = lo + _GOLDEN * (hi - lo)
            f2 = _seg_to_row(kind, x2, ax, ay, az, bx, by, bz, row)
    best = min(f1, f2)
    # the ends are candidates too (the bracket never evaluates them)
    best = min(best, _seg_to_row(kind, 0.0, ax, ay, az, bx, by, bz, row))
    return min(best, _seg_to_row(kind, 1.0, ax, ay, az, bx, by, bz, row))


@njit(cache=True)
def segment_box_distance(ax, ay, az, bx, by, bz, box):  # pragma: no cover - compiled
    """Signed distance from segment a-b to a packed box row, exactly when the segment stays
    outside the box.

    In the box frame the squared outside distance of the point at parameter t is
    ``sum_i max(|p_i(t)| - h_i, 0)^2``; between the parameters where some p_i(t) = +-h_i the
    active terms and their signs are fixed, so it is one quadratic per piece, minimised in
    closed form. When that minimum is 0 the segment touches or enters the box and the signed
    (negative) depth comes from :func:`segment_convex_distance`.
    """
    dx, dy, dz = ax - box[0], ay - box[1], az - box[2]
    ex, ey, ez = bx - ax, by - ay, bz - az
    # local = R^T d: column i of R (row-major at box[3:12]) dotted with d; scalars and
    # tuples only (no array allocation: this runs for every link and box of every posture)
    p = (
        box[3] * dx + box[6] * dy + box[9] * dz,
        box[4] * dx + box[7] * dy + box[10] * dz,
        box[5] * dx + box[8] * dy + box[11] * dz,
    )
    u = (
        box[3] * ex + box[6] * ey + box[9] * ez,
        box[4] * ex + box[7] * ey + box[10] * ez,
        box[5] * ex + box[8] * ey + box[11] * ez,
    )
    h = (box[12], box[13], box[14])
    best = local_segment_box_sq(p, u, h)
    if best > 1e-24:  # clear of the box by more than 1e-12 m (round-off leaves ~1e-34 on contact)
        return math.sqrt(best)
    return segment_convex_distance(2, ax, ay, az, bx, by, bz, box)


@njit(cache=True, inline="always")
def _rows_min(kind, rows, lo, hi, ax, ay, az, bx, by, bz, best, stop):  # pragma: no cover
    """:func:`segment_min_distance` over rows ``lo..hi`` of one kind (0 sphere, 1 capsule,
    2 box). Capsule and box pairs whose cheap lower bound (the distance from the segment
    midpoint minus half its length) already reaches ``best`` are skipped; the loop ends at
    the first distance below ``stop`` (-inf: never)."""
    mx, my, mz = 0.5 * (ax + bx), 0.5 * (ay + by), 0.5 * (az + bz)
    half = 0.5 * math.sqrt((bx - ax) ** 2 + (by - ay) ** 2 + (bz - az) ** 2)
    for i in range(lo, hi):
        r = rows[i]
        if kind == 0:
            d = point_segment_distance(r[0], r[1], r[2], ax, ay, az, bx, by, bz) - r[3]
        elif kind == 1:
            lb = point_segment_distance(mx, my, mz, r[0], r[1], r[2], r[3], r[4], r[5])
            if lb - r[6] - half >= best:
                continue
            d = segment_convex_distance(1, ax, ay, az, bx, by, bz, r)
        else:
            if box_sdf(mx, my, mz, r) - half >= best:
                continue
            d = segment_box_distance(ax, ay, az, bx, by, bz, r)
        if d < best:
            best = d
            if best < stop:
                return best
    return best


@njit(cache=True)
def _tree_min(
    kind, rows, nodes, ax, ay, az, bx, by, bz, best, relax_from, relax, stop
):  # pragma: no cover
    """:func:`segment_min_distance` over one kind's rows through its tree: depth first,
    nearer child first, a node skipped when its lower bound
    (:func:`planner.spatial_index.node_lower_bound`) reaches the best distance found, or,
    relaxed, comes within ``relax`` (best - relax_from) of it (then its bound joins the
    answer, which stays a lower bound: :func:`segment_min_distance`); the walk ends at the
    first distance below ``stop`` (-inf: never)."""
    n = rows.shape[0]
    if n == 0:
        return best
    if nodes.shape[0] == 1:  # one leaf: the loop itself
        return _rows_min(kind, rows, 0, n, ax, ay, az, bx, by, bz, best, stop)
    slo0, shi0 = min(ax, bx), max(ax, bx)
    slo1, shi1 = min(ay, by), max(ay, by)
    slo2, shi2 = min(az, bz), max(az, bz)
    first_leaf = (nodes.shape[0] + 1) // 2 - 1
    # (node, bound) pairs, the node as a float (exact below 2^53): one allocation per walk;
    # a path from the root holds at most two entries per level, 64 cover any tree
    stack = np.empty((64, 2))
    stack[0, 0] = 0.0
    stack[0, 1] = -np.inf
    top = 1
    floor = np.inf
    while top > 0:
        top -= 1
        i = int(stack[top, 0])
        lb = stack[top, 1]
        if lb >= best:
            continue
        if lb >= best - relax * max(best - relax_from, 0.0):
            floor = min(floor, lb)
            continue
        if i >= first_leaf:
            k = i - first_leaf
            best = _rows_min(
                kind, rows, k * LEAF, min((k + 1) * LEAF, n), ax, ay, az, bx, by, bz, best, stop
            )
            if best < stop:
                return best
            continue
        left, right = 2 * i + 1, 2 * i + 2
        lb_l = node_lower_bound(
            nodes[left], ax, ay, az, bx, by, bz, slo0, slo1, slo2, shi0, shi1, shi2, best
        )
        lb_r = node_lower_bound(
            nodes[right], ax, ay, az, bx, by, bz, slo0, slo1, slo2, shi0, shi1, shi2, best
        )
        if lb_l > lb_r:
            left, right = right, left
            lb_l, lb_r = lb_r, lb_l
        if lb_r < best:  # the farther child first: the nearer one is popped next
            stack[top, 0] = right
            stack[top, 1] = lb_r
            top += 1
        if lb_l < best:
            stack[top, 0] = left
            stack[top, 1] = lb_l
            top += 1
    return min(best, floor)


@njit(cache=True)
def _grid_scan(grid, spheres, ax, ay, az, bx, by, bz, rho, best):  # pragma: no cover
    """The least of ``best`` and the signed distances from segment a-b to the sphere rows of
    every cell of the grid (:func:`planner.spatial_index.build_grid`) whose centre is within
    ``rho`` plus half a cell diagonal of the segment: every row whose centre is within
    ``rho`` of it is among them. The cells are visited slab by slab along the segment's
    longest axis, each slab's range in the two others from the part of the segment that can
    be within ``rho`` of it."""
    h = grid[3]
    dims = (int(grid[4]), int(grid[5]), int(grid[6]))
    org = (grid[0], grid[1], grid[2])
    start = GRID_HEADER
    rows_at = start + dims[0] * dims[1] * dims[2] + 1
    a = (ax, ay, az)
    u = (bx - ax, by - ay, bz - az)
    m = 0
    if abs(u[1]) > abs(u[m]):
        m = 1
    if abs(u[2]) > abs(u[m]):
        m = 2
    j, k = (m + 1) % 3, (m + 2) % 3
    strides = (dims[1] * dims[2], dims[2], 1)
    reach = rho + 0.8660254037844387 * h + BOUND_SLACK  # half the diagonal: sqrt(3) / 2
    lo_m, hi_m = min(a[m], a[m] + u[m]), max(a[m], a[m] + u[m])
    i_lo = max(0, math.floor((lo_m - rho - org[m]) / h))
    i_hi = min(dims[m] - 1, math.floor((hi_m + rho - org[m]) / h))
    for i in range(i_lo, i_hi + 1):
        s_lo = org[m] + i * h - rho
        s_hi = org[m] + (i + 1) * h + rho
        if abs(u[m]) > 1e-300:
            t0, t1 = (s_lo - a[m]) / u[m], (s_hi - a[m]) / u[m]
            if t0 > t1:
                t0, t1 = t1, t0
            t0, t1 = max(t0, 0.0), min(t1, 1.0)
            if t0 > t1:
                continue
        else:
            t0, t1 = 0.0, 1.0
        pj0, pj1 = a[j] + t0 * u[j], a[j] + t1 * u[j]
        pk0, pk1 = a[k] + t0 * u[k], a[k] + t1 * u[k]
        j_lo = max(0, math.floor((min(pj0, pj1) - rho - org[j]) / h))
        j_hi = min(dims[j] - 1, math.floor((max(pj0, pj1) + rho - org[j]) / h))
        k_lo = max(0, math.floor((min(pk0, pk1) - rho - org[k]) / h))
        k_hi = min(dims[k] - 1, math.floor((max(pk0, pk1) + rho - org[k]) / h))
        cm = org[m] + (i + 0.5) * h
        for jj in range(j_lo, j_hi + 1):
            cj = org[j] + (jj + 0.5) * h
            for kk in range(k_lo, k_hi + 1):
                ck = org[k] + (kk + 0.5) * h
                if m == 0:
                    px, py, pz = cm, cj, ck
                elif m == 1:
                    px, py, pz = ck, cm, cj
                else:
                    px, py, pz = cj, ck, cm
                if point_segment_distance(px, py, pz, ax, ay, az, bx, by, bz) > reach:
                    continue
                flat = i * strides[m] + jj * strides[j] + kk * strides[k]
                for r in range(int(grid[start + flat]), int(grid[start + flat + 1])):
                    row = spheres[int(grid[rows_at + r])]
                    d = point_segment_distance(row[0], row[1], row[2], ax, ay, az, bx, by, bz)
                    d -= row[3]
                    if d < best:
                        best = d
    return best


@njit(cache=True)
def _spheres_min(
    spheres, nodes, grid, ax, ay, az, bx, by, bz, best, relax_from, relax, stop
):  # pragma: no cover
    """:func:`_tree_min` of the sphere rows, through their grid first when they have one: the
    cells within a radius r (plus the largest ball radius) of the segment hold every ball
    closer than r, so after their scan the least distance is known when it is at most r,
    and every other ball is at least r away. r starts at :data:`RELAXED_FIRST_REACH` times
    the threshold (relaxed; at least a quarter cell) or a quarter of a cell and doubles up
    to two cells; the answer is returned as soon as it
    meets :func:`segment_min_distance`'s contract (exact below r; relaxed, r itself once
    r - t >= (1 - relax) (best - t)), else the tree finishes the walk. Exact (``relax`` 0)
    with ``best`` already within two cells, r starts at ``best``. Among the 1,000 spheres
    (``benchmarks/planning.py --fair``, 40 plans per query seed, their diagnostics'
    ``path_extremes``, median per path, the same extremes to the bit) that took 141 -> 94 us
    on query seed 23 and 99 -> 59 us on seed 11."""
    if grid.shape[0] == 0:
        return _tree_min(0, spheres, nodes, ax, ay, az, bx, by, bz, best, relax_from, relax, stop)
    h, rmax = grid[3], grid[7]
    r = max(RELAXED_FIRST_REACH * relax_from, 0.25 * h) if relax > 0.0 else 0.25 * h
    if relax == 0.0 and r < best <= 2.0 * h:
        # exact below a bound within two cells (a running minimum's, path_extremes): one
        # scan at that radius answers (every ball closer than it is in its cells), where
        # the doubling would scan the nearer cells up to four times on its way there
        r = best
    while True:
        best = _grid_scan(grid, spheres, ax, ay, az, bx, by, bz, r + rmax, best)
        if best <= r:
            return best
        if (
            relax > 0.0
            and r >= relax_from
            and r - relax_from >= (1.0 - relax) * (best - relax_from)
        ):
            return r
        if r >= 2.0 * h:
            break
        r *= 2.0
    return _tree_min(0, spheres, nodes, ax, ay, az, bx, by, bz, best, relax_from, relax, stop)


@njit(cache=True, inline="always")
def segment_min_distance(
    ax,
    ay,
    az,
    bx,
    by,
    bz,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    upper,
    relax_from,
    relax,
):  # pragma: no cover
    """A lower bound L on the smallest signed distance D from segment a-b to every obstacle
    (the packed arrays of :class:`PackedObstacles`, in its order), or a value >= ``upper``
    when every obstacle is at least ``upper`` away.

    With ``relax`` = 0, L = D below ``upper`` (the trees only skip obstacles that cannot be
    closer than the best one found, :func:`_tree_min`). With ``relax`` in (0, 1), the walk
    stops at nodes whose bound is within ``relax (best - relax_from)`` of the best distance
    found, and L is the least of the distances found and of those bounds; then, with
    t = ``relax_from``: L <= D always; L = D when D < t; L >= t when D >= t; and
    L - t >= (1 - relax) (D - t). So a rule "D >= t" is decided exactly, and a margin above
    it is known to within that factor (proof: a node is skipped with a bound of at least
    f(best) = (1 - relax) best + relax t, f grows with best and best only falls, so every
    skipped bound is at least f of the final best, which is at least D).

    Relaxed, the walk also ends at the first obstacle found closer than t: the rule is then
    broken (D <= L < t), which is all a relaxed caller asks of such a segment, so below t
    the value is the distance to *some* obstacle closer than t, not the least one (an
    upper bound of D). In clutter most postures a planner samples break the rule, and the
    first close obstacle ends their check."""
    stop = relax_from if relax > 0.0 else -np.inf
    best = upper
    # a kind without rows is not called at all, one of a single leaf is looped here (this
    # function and the loop are inlined into their callers): a call passes its arrays,
    # whose reference counts cost more than a small kind's work (free space: 5-8x)
    if spheres.shape[0] > 0 and sphere_nodes.shape[0] == 1 and sphere_grid.shape[0] == 0:
        best = _rows_min(0, spheres, 0, spheres.shape[0], ax, ay, az, bx, by, bz, best, stop)
        if best < stop:
            return best
    elif spheres.shape[0] > 0:
        best = _spheres_min(
            spheres,
            sphere_nodes,
            sphere_grid,
            ax,
            ay,
            az,
            bx,
            by,
            bz,
            best,
            relax_from,
            relax,
            stop,
        )
        if best < stop:
            return best
    if capsules.shape[0] > 0 and capsule_nodes.shape[0] == 1:
        best = _rows_min(1, capsules, 0, capsules.shape[0], ax, ay, az, bx, by, bz, best, stop)
        if best < stop:
            return best
    elif capsules.shape[0] > 0:
        best = _tree_min(
            1, capsules, capsule_nodes, ax, ay, az, bx, by, bz, best, relax_from, relax, stop
        )
        if best < stop:
            return best
    if boxes.shape[0] > 0 and box_nodes.shape[0] == 1:
        best = _rows_min(2, boxes, 0, boxes.shape[0], ax, ay, az, bx, by, bz, best, stop)
    elif boxes.shape[0] > 0:
        best = _tree_min(2, boxes, box_nodes, ax, ay, az, bx, by, bz, best, relax_from, relax, stop)
    return best


@njit(cache=True)
def _segments_distance(
    a, b, spheres, capsules, boxes, sphere_nodes, capsule_nodes, box_nodes, sphere_grid, q, out
):  # pragma: no cover - compiled
    """``out[i]``: :func:`segment_min_distance` of segment ``a[i]``-``b[i]`` with ``q`` =
    (best, threshold, relax) (the exact distance: ``(inf, 0, 0)``)."""
    for i in range(a.shape[0]):
        out[i] = segment_min_distance(
            a[i, 0],
            a[i, 1],
            a[i, 2],
            b[i, 0],
            b[i, 1],
            b[i, 2],
            spheres,
            capsules,
            boxes,
            sphere_nodes,
            capsule_nodes,
            box_nodes,
            sphere_grid,
            q[0],
            q[1],
            q[2],
        )


def segment_obstacle_distance(
    a: np.ndarray, b: np.ndarray, obstacles: Sequence[Obstacle]
) -> np.ndarray:
    """Signed distance from N segments to the nearest of the obstacles.

    Parameters
    ----------
    a, b : array, shape (N, 3), m
        Segment ends.
    obstacles : sequence of Sphere, Box, Capsule, Points

    Returns
    -------
    array, shape (N,), m
        Distance between segment and obstacle surface, negative when the segment enters an
        obstacle (then minus the depth of its deepest point); ``inf`` without obstacles.
    """
    a = np.ascontiguousarray(np.atleast_2d(np.asarray(a, dtype=float)))
    b = np.ascontiguousarray(np.atleast_2d(np.asarray(b, dtype=float)))
    if a.shape != b.shape or a.shape[-1] != 3:
        raise InputError(f"a and b must both have shape (N, 3), got {a.shape} and {b.shape}")
    packed = obstacles if isinstance(obstacles, PackedObstacles) else pack_obstacles(obstacles)
    out = np.empty(a.shape[0])
    exact = read_only([np.inf, 0.0, 0.0])  # packed: read-only too
    _segments_distance(read_only(a), read_only(b), *packed, exact, out)
    return out
