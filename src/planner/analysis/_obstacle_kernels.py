"""The numba kernels of :mod:`planner.analysis.obstacle_regions`: which cells of the
(theta1, theta2, theta3) grid surely break the clearance rule, and the flood fill that
proves a start cut off from its goals.

The bounds and the argument are explained in :mod:`planner.analysis.obstacle_regions`; here
are the loops. Obstacles come packed (:func:`planner.geometry.pack_obstacles`). Every
obstacle is convex, so its signed distance is a convex function of the point: its largest
value over a box (here a planar rectangle) is at a corner.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from planner.analysis.heap import heap_pop, heap_push
from planner.geometry import box_sdf, point_segment_distance, segment_min_distance
from planner.spatial_index import BOUND_SLACK, LEAF

__all__ = ["all_states", "cell_passable", "corners_inside", "flood_reaches", "proximal_blocked"]


@njit(cache=True)
def proximal_blocked(
    base_u,
    L1,
    theta1,
    a1,
    theta,
    a,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    limit,
    out,
):  # pragma: no cover - compiled
    """``out[i, k]`` = the proximal link from (``base_u``, 0) to (base_u + L1 cos theta_k,
    L1 sin theta_k) in the loop's plane, turned by theta1 about AB, is closer than ``limit``
    (link radius + clearance, less the slack) to some obstacle for every (theta1, theta) of
    the closed cell theta1_i +- a1, theta_k +- a.

    The link's ends move by at most L1 (a1 + a) over the cell (its far end is at most L1 from
    the axis and turns through at most a1 about it; in the plane it turns through at most
    a about its fixed end), so its distance to an obstacle, the least signed distance of its
    points, grows by at most that much: the cell is blocked when the centre's distance plus
    L1 (a1 + a) is still below ``limit``."""
    reach = L1 * (a1 + a)
    for i in range(theta1.shape[0]):
        c1, s1 = math.cos(theta1[i]), math.sin(theta1[i])
        for k in range(theta.shape[0]):
            eu = base_u + L1 * math.cos(theta[k])
            ew = L1 * math.sin(theta[k])
            # decided exactly against the bound that matters; a relaxed walk of the trees
            # (planner.geometry.segment_min_distance) and a cheap broad phase skip the rest
            dist = segment_min_distance(
                0.0,
                base_u,
                0.0,
                ew * c1,
                eu,
                -ew * s1,
                spheres,
                capsules,
                boxes,
                sphere_nodes,
                capsule_nodes,
                box_nodes,
                sphere_grid,
                limit - reach,
                limit - reach,
                0.5,
            )
            out[i, k] = dist < limit - reach


@njit(cache=True, inline="always")
def _point_sdf(kind, row, x, y, z):  # pragma: no cover - compiled
    """Signed distance from a point to one packed obstacle row (kind 0 sphere, 1 capsule,
    2 box)."""
    if kind == 0:
        return point_segment_distance(row[0], row[1], row[2], x, y, z, x, y, z) - row[3]
    if kind == 1:
        return (
            point_segment_distance(x, y, z, row[0], row[1], row[2], row[3], row[4], row[5]) - row[6]
        )
    return box_sdf(x, y, z, row)


@njit(cache=True, inline="always")
def _rectangle_inside(kind, row, c1, s1, u0, u1, w0, w1, spread, limit):  # pragma: no cover
    """Whether every point of the planar rectangle [u0, u1] x [w0, w1] of the loop's plane at
    theta1 (cos c1, sin s1), each moved by up to ``spread``, is closer than ``limit`` to the
    obstacle: the signed distance is convex, so its largest value on the rectangle is at a
    corner, and moving a point by ``spread`` changes it by at most that."""
    # the centre is the corners' mean: its value is at most their largest (a cheap reject)
    uc, wc = 0.5 * (u0 + u1), 0.5 * (w0 + w1)
    if _point_sdf(kind, row, wc * c1, uc, -wc * s1) + spread >= limit:
        return False
    worst = -np.inf
    for u in (u0, u1):
        for w in (w0, w1):
            worst = max(worst, _point_sdf(kind, row, w * c1, u, -w * s1))
    return worst + spread < limit


@njit(cache=True, inline="always")
def _node_point_bound(node, x, y, z):  # pragma: no cover - compiled
    """A lower bound on the signed distance from point (x, y, z) to every obstacle below a
    tree node (:mod:`planner.spatial_index`): outside the node's box, the distance to the
    box (the obstacle lies inside it); anywhere, minus the node's depth. ``inf`` for an
    empty node."""
    if node[0] > node[3]:
        return np.inf
    gx = max(node[0] - x, x - node[3], 0.0)
    gy = max(node[1] - y, y - node[4], 0.0)
    gz = max(node[2] - z, z - node[5], 0.0)
    return max(math.sqrt(gx * gx + gy * gy + gz * gz) - BOUND_SLACK, -node[6])


@njit(cache=True)
def _inside_one(kind, rows, nodes, c1, s1, u0, u1, w0, w1, spread, limit):  # pragma: no cover
    """Whether one obstacle of one kind holds the rectangle within ``limit``
    (:func:`_rectangle_inside`), through the kind's tree: a node is skipped when the bound
    of :func:`_node_point_bound` at some corner, plus ``spread``, reaches ``limit`` (then
    that corner is at least that far from every obstacle below it)."""
    n = rows.shape[0]
    if n == 0:
        return False
    if nodes.shape[0] == 1:
        for i in range(n):
            if _rectangle_inside(kind, rows[i], c1, s1, u0, u1, w0, w1, spread, limit):
                return True
        return False
    xs = (w0 * c1, w0 * c1, w1 * c1, w1 * c1)
    ys = (u0, u1, u0, u1)
    zs = (-w0 * s1, -w0 * s1, -w1 * s1, -w1 * s1)
    first_leaf = (nodes.shape[0] + 1) // 2 - 1
    stack = np.empty(64, dtype=np.int64)
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        i = stack[top]
        node = nodes[i]
        worst = -np.inf
        for c in range(4):
            worst = max(worst, _node_point_bound(node, xs[c], ys[c], zs[c]))
        if worst + spread >= limit:
            continue
        if i >= first_leaf:
            k = i - first_leaf
            for r in range(k * LEAF, min((k + 1) * LEAF, n)):
                if _rectangle_inside(kind, rows[r], c1, s1, u0, u1, w0, w1, spread, limit):
                    return True
            continue
        stack[top] = 2 * i + 1
        stack[top + 1] = 2 * i + 2
        top += 2
    return False


@njit(cache=True)
def corners_inside(
    c1,
    s1,
    a1,
    boxes_uw,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    limit,
):  # pragma: no cover - compiled
    """Whether, for some of the planar point sets ``boxes_uw`` (M, 4): rows (u_lo, u_hi,
    w_lo, w_hi), every point of the set at every theta1 within ``a1`` of the angle (c1, s1)
    is closer than ``limit`` to the obstacles. Turning by at most a1 about AB moves a point
    at distance |w| from the axis by at most |w| a1 (the ``spread``). Two bounds, each
    sound alone:

    * the union (for many small obstacles, a cloud's points): the distance to the nearest
      obstacle is 1-Lipschitz in the point (a minimum of signed distances of convex sets,
      each 1-Lipschitz), so every point of the set, moved by the spread, is within the
      centre's distance plus half the rectangle's diagonal plus the spread; a rectangle
      too large for that is cut into pieces that each must hold (:func:`_union_inside`);
    * one obstacle (for large ones, a plate holding the whole set): its signed distance is
      convex, so its largest value on the rectangle is at a corner
      (:func:`_rectangle_inside`), found through the trees (:func:`_inside_one`).

    Both walk the obstacle trees, so the cost grows slowly with the number of obstacles."""
    for m in range(boxes_uw.shape[0]):
        u0, u1, w0, w1 = boxes_uw[m, 0], boxes_uw[m, 1], boxes_uw[m, 2], boxes_uw[m, 3]
        if not (u0 <= u1 and w0 <= w1):  # NaN: no posture of the cell there
            continue
        spread = max(abs(w0), abs(w1)) * a1
        if _inside_one(0, spheres, sphere_nodes, c1, s1, u0, u1, w0, w1, spread, limit):
            return True
        if _inside_one(1, capsules, capsule_nodes, c1, s1, u0, u1, w0, w1, spread, limit):
            return True
        if _inside_one(2, boxes, box_nodes, c1, s1, u0, u1, w0, w1, spread, limit):
            return True
        if _union_inside(
            c1,
            s1,
            a1,
            u0,
            u1,
            w0,
            w1,
            spheres,
            capsules,
            boxes,
            sphere_nodes,
            capsule_nodes,
            box_nodes,
            sphere_grid,
            limit,
        ):
            return True
    return False


#: Halvings per side of a rectangle in the union bound (:func:`_union_inside`): at most
#: 4 ** UNION_DEPTH pieces.
UNION_DEPTH = 3


@njit(cache=True)
def _union_inside(
    c1,
    s1,
    a1,
    u0,
    u1,
    w0,
    w1,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    limit,
):  # pragma: no cover
    """The union bound of :func:`corners_inside`: every point of the rectangle, moved by up
    to its spread, is closer than ``limit`` to some obstacle. A piece holds when its centre's
    distance D plus half its diagonal plus its spread is below ``limit`` (D is 1-Lipschitz);
    a piece that does not is cut in four, down to :data:`UNION_DEPTH` halvings, unless
    D + spread >= limit already (then no piece round the centre can hold: the bound
    cannot succeed there, and the rectangle is not claimed)."""
    stack = np.empty((4 * UNION_DEPTH + 4, 5))
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3], stack[0, 4] = u0, u1, w0, w1, 0.0
    top = 1
    while top > 0:
        top -= 1
        a, b, c, d, depth = (
            stack[top, 0],
            stack[top, 1],
            stack[top, 2],
            stack[top, 3],
            stack[top, 4],
        )
        spread = max(abs(c), abs(d)) * a1
        uc, wc = 0.5 * (a + b), 0.5 * (c + d)
        half = 0.5 * math.sqrt((b - a) ** 2 + (d - c) ** 2)
        x, y, z = wc * c1, uc, -wc * s1
        dist = segment_min_distance(
            x,
            y,
            z,
            x,
            y,
            z,
            spheres,
            capsules,
            boxes,
            sphere_nodes,
            capsule_nodes,
            box_nodes,
            sphere_grid,
            limit - spread,
            0.0,
            0.0,
        )
        if dist + half + spread < limit:
            continue
        if dist + spread >= limit or depth >= UNION_DEPTH:
            return False
        for i in range(2):
            for j in range(2):
                stack[top, 0] = a + 0.5 * i * (b - a)
                stack[top, 1] = a + 0.5 * (i + 1) * (b - a)
                stack[top, 2] = c + 0.5 * j * (d - c)
                stack[top, 3] = c + 0.5 * (j + 1) * (d - c)
                stack[top, 4] = depth + 1.0
                top += 1
    return True


@njit(cache=True)
def cell_passable(
    mask,
    blocked_a,
    blocked_b,
    point_sets,
    c1,
    s1,
    a1,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    limit,
    i,
    j,
    k,
):  # pragma: no cover - compiled
    """Whether cell (i1, k3, k2) = (i, j, k) may hold a posture of the flood (see
    :func:`flood_reaches`); theta1_i given by its cosine and sine."""
    if not mask[j, k] or blocked_a[i, k] or blocked_b[i, j]:
        return False
    return not corners_inside(
        c1,
        s1,
        a1,
        point_sets[j, k],
        spheres,
        capsules,
        boxes,
        sphere_nodes,
        capsule_nodes,
        box_nodes,
        sphere_grid,
        limit,
    )


@njit(cache=True)
def flood_reaches(
    mask,
    blocked_a,
    blocked_b,
    point_sets,
    theta1,
    a1,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    limit,
    start,
    goal,
    guide,
    visits,
):  # pragma: no cover - compiled
    """Flood of the passable cells from ``start`` (i1, k3, k2) through 26-neighbours, nearest
    to the cells of ``guide`` (G, 3) first; 1 as soon as a cell where ``goal`` (n1, n3, n2)
    bool is set is reached, 0 when the start's component holds none. ``guide`` only orders
    the flood (a few goal cells; its length costs time per cell pushed), ``goal`` decides.

    A cell (i1, k3, k2) is passable when ``mask[k3, k2]`` (the obstacle-free map allows it),
    neither proximal link is blocked (``blocked_a[i1, k2]``, ``blocked_b[i1, k3]``) and no
    point set of ``point_sets[k3, k2]`` (M, 4) lies inside an obstacle over the cell
    (:func:`corners_inside`, evaluated only for cells the flood meets). ``visits`` (one int)
    receives the number of passable cells met. Returns -1 when the start cell is not
    passable (the start is then invalid: nothing is proven). Two steps: the start's cell is
    met here, the flood from it is :func:`_spread`."""
    n1, n3, n2 = theta1.shape[0], mask.shape[0], mask.shape[1]
    # 0 unknown, 1 passable (queued), 2 not passable
    state = np.zeros((n1, n3, n2), dtype=np.uint8)
    cos1 = np.cos(theta1)
    sin1 = np.sin(theta1)
    # a binary heap of (distance in cells to the nearest goal, cell) (planner.analysis.heap):
    # the flood dives towards the goals first, so a connected query stops early; a proof
    # visits the whole component whatever the order. Each cell is pushed at most once, so
    # the heap never outgrows one entry per cell. A cell (i1, k3, k2) is packed into one
    # int64 as i1 << 40 | k3 << 20 | k2 (a grid has at most 256 theta1 cells and 2048 per
    # other axis, below 2^20): shifts and masks unpack it, where a flat index would cost
    # three divisions per pop.
    cap = n1 * n3 * n2
    keys = np.empty(cap, dtype=np.int32)
    cells = np.empty(cap, dtype=np.int64)
    size = 0
    i, j, k = start[0], start[1], start[2]
    if not cell_passable(
        mask,
        blocked_a,
        blocked_b,
        point_sets,
        cos1[i],
        sin1[i],
        a1,
        spheres,
        capsules,
        boxes,
        sphere_nodes,
        capsule_nodes,
        box_nodes,
        sphere_grid,
        limit,
        i,
        j,
        k,
    ):
        visits[0] = 0
        return -1
    state[i, j, k] = 1
    if goal[i, j, k]:
        visits[0] = 1
        return 1
    size = heap_push(keys, cells, size, _to_goals(guide, i, j, k), (i << 40) | (j << 20) | k)
    reached, met = _spread(
        mask,
        blocked_a,
        blocked_b,
        point_sets,
        cos1,
        sin1,
        a1,
        spheres,
        capsules,
        boxes,
        sphere_nodes,
        capsule_nodes,
        box_nodes,
        sphere_grid,
        limit,
        goal,
        guide,
        state,
        keys,
        cells,
        size,
    )
    visits[0] = met + 1
    return reached


@njit(cache=True)
def _spread(
    mask,
    blocked_a,
    blocked_b,
    point_sets,
    cos1,
    sin1,
    a1,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    limit,
    goal,
    guide,
    state,
    keys,
    cells,
    size,
):  # pragma: no cover - compiled
    """The flood step of :func:`flood_reaches`, from the heap (``keys``, ``cells`` of
    ``size`` entries) that holds the start: pop the cell nearest to the guide, meet its
    unknown 26-neighbours (``state`` 0 -> 1 passable and queued, or 2 not passable) until a
    goal is met or the heap is empty. Returns (1 if a goal was met else 0, passable cells
    met beyond the start)."""
    n1, n3, n2 = state.shape[0], state.shape[1], state.shape[2]
    met = 0
    while size > 0:
        flat, size = heap_pop(keys, cells, size)
        ci, cj, ck = flat >> 40, (flat >> 20) & 0xFFFFF, flat & 0xFFFFF
        for di in range(-1, 2):
            i = ci + di
            if i < 0 or i >= n1:
                continue
            for dj in range(-1, 2):
                j = cj + dj
                if j < 0 or j >= n3:
                    continue
                for dk in range(-1, 2):
                    k = ck + dk
                    if k < 0 or k >= n2 or state[i, j, k] != 0:
                        continue
                    if not cell_passable(
                        mask,
                        blocked_a,
                        blocked_b,
                        point_sets,
                        cos1[i],
                        sin1[i],
                        a1,
                        spheres,
                        capsules,
                        boxes,
                        sphere_nodes,
                        capsule_nodes,
                        box_nodes,
                        sphere_grid,
                        limit,
                        i,
                        j,
                        k,
                    ):
                        state[i, j, k] = 2
                        continue
                    state[i, j, k] = 1
                    met += 1
                    if goal[i, j, k]:
                        return 1, met
                    size = heap_push(
                        keys, cells, size, _to_goals(guide, i, j, k), (i << 40) | (j << 20) | k
                    )
    return 0, met


@njit(cache=True, inline="always")
def _to_goals(guide, i, j, k):  # pragma: no cover - compiled
    """Chebyshev distance in cells from (i, j, k) to the nearest cell of ``guide``."""
    best = 1 << 30
    for g in range(guide.shape[0]):
        d = max(abs(guide[g, 0] - i), max(abs(guide[g, 1] - j), abs(guide[g, 2] - k)))
        best = min(best, d)
    return best


@njit(cache=True)
def all_states(
    mask,
    blocked_a,
    blocked_b,
    point_sets,
    theta1,
    a1,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    limit,
    out,
):  # pragma: no cover - compiled
    """Every cell's state into ``out`` (n1, n, n) int8: 0 outside the mask, 1 blocked,
    2 passable (:func:`cell_passable`), for tests and figures."""
    for i in range(out.shape[0]):
        c1, s1 = math.cos(theta1[i]), math.sin(theta1[i])
        for j in range(out.shape[1]):
            for k in range(out.shape[2]):
                if not mask[j, k]:
                    out[i, j, k] = 0
                elif cell_passable(
                    mask,
                    blocked_a,
                    blocked_b,
                    point_sets,
                    c1,
                    s1,
                    a1,
                    spheres,
                    capsules,
                    boxes,
                    sphere_nodes,
                    capsule_nodes,
                    box_nodes,
                    sphere_grid,
                    limit,
                    i,
                    j,
                    k,
                ):
                    out[i, j, k] = 2
                else:
                    out[i, j, k] = 1
