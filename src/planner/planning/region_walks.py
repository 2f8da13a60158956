"""Region walks: how the design's region map guides a change of working mode.

The region map (:mod:`planner.analysis.regions`, the obstacle-free (theta2, theta3) map of
the proofs, :data:`planner.planning.proofs.PROOF_RESOLUTION` cells) splits each working mode
into regions (connected sets of valid cells) and joins two regions of adjacent modes where
it has transit cells between them. With the map (``options.region_map``) the mode-change
search (:mod:`planner.planning.mode_change`) goes first along the map's *region walks*
(:func:`region_walks`: chains of regions joined by the map's transits, from the start's
region to a goal's; a mode may come back in another of its regions, which a mode walk
cannot say), each step's transit postures taken from the map's transit cells next to its two
regions (:func:`map_transits`: cells of the flip where the two other measures keep their
signs with margin, moved onto the surface; :func:`near_regions`) and its crossings kept only
when q_in lies in the step's first region and q_out in its second. Where the map cannot
place the start or the goals, the mode walks it cannot realise are left out
(:func:`walk_possible`) and the rest guided the same way without regions.
"""

from __future__ import annotations

import numpy as np

from planner.analysis import regions as region_maps
from planner.caching import cached
from planner.design import Design
from planner.kinematics import WORKING_MODES, forward_batch
from planner.planning.mode_graph import FLIP_NAMES, flipped_sign

__all__ = [
    "REGION_DETOUR",
    "REGION_WALKS",
    "cached_map_transits",
    "map_transits",
    "near_regions",
    "region_walks",
    "theta1_along",
    "walk_possible",
]

#: Region walks (:func:`region_walks`) tried by the guided round: at most this many, with
#: up to :data:`REGION_DETOUR` transits more than the shortest.
REGION_WALKS = 16
REGION_DETOUR = 2


def cached_map_transits(
    rmap: region_maps.RegionMap, asm: str, before: str, after: str
) -> np.ndarray:
    """:func:`map_transits`, computed once per map and flip (a copy: callers edit theta1)."""
    return _map_transits(rmap, asm, before, after).copy()


@cached("region_walks.transits")
def _map_transits(rmap: region_maps.RegionMap, asm: str, before: str, after: str) -> np.ndarray:
    """:func:`map_transits` per (map, assembly mode, before, after): a map is hashed and
    compared by identity, and the key holds it, so a new map is never mistaken for an old
    one."""
    return map_transits(rmap, asm, before, after)


def walk_possible(
    rmap: region_maps.RegionMap,
    asm: str,
    seq: tuple[str, ...],
    q_start: np.ndarray,
    q_goals: np.ndarray,
) -> bool:
    """False only when the region map shows that no path follows the mode walk ``seq``:
    no chain of regions r_0 (holding ``q_start``, mode seq[0]), r_1, ... (mode seq[i]), each
    joined to the next by a transit of the map, ends in a region of mode seq[-1] holding a
    goal candidate of ``q_goals`` (K, 3). Each segment of a plan stays in one region of its
    mode and each crossing joins two regions the map joins (the argument of
    :func:`planner.analysis.regions.prove_disconnected`), so such a walk cannot succeed."""
    adj: dict[int, set[int]] = {}
    for t in rmap.transits:
        adj.setdefault(t.a, set()).add(t.b)
        adj.setdefault(t.b, set()).add(t.a)
    here = {r.id for r in region_maps.regions_at(rmap, q_start, asm) if r.working_mode == seq[0]}
    if not here:
        return True  # the map cannot place the start: it decides nothing
    for mode in seq[1:]:
        here = {b for a in here for b in adj.get(a, ()) if rmap.regions[b].working_mode == mode}
    ends = {
        r.id
        for g in np.atleast_2d(q_goals)
        for r in region_maps.regions_at(rmap, g, asm)
        if r.working_mode == seq[-1]
    }
    return bool(here & ends) or not ends


def region_walks(
    rmap: region_maps.RegionMap,
    asm: str,
    start_mode: str,
    q_start: np.ndarray,
    targets: dict[str, np.ndarray],
    *,
    detour: int = REGION_DETOUR,
    limit: int = REGION_WALKS,
) -> list[tuple[int, ...]]:
    """Chains of region ids r_0, ..., r_k of the map's transit graph: r_0 a region of
    ``start_mode`` holding ``q_start``, r_k a region of a mode of ``targets`` (mode -> (K, 3)
    goal candidates) holding one of its candidates, each region joined to the next by a
    transit of the map (so consecutive modes differ by one sign), no region twice; the
    fewest transits first, up to ``detour`` more than the fewest, at most ``limit`` walks.
    Empty when the map cannot place the start or any goal, or joins none of them.

    Why regions, not modes: the regions of one working mode are split (literal joint limits,
    parallel singularities), so the only chain from a start to its goal may be long (on the
    design 0.3/0.3/0.4 a goal one sign away, --+ to ---, is reached only through five
    transits, --+ -> +-+ -> +++ -> ++- -> +-- -> ---, beyond
    :data:`planner.planning.mode_graph.MAX_DETOUR`) or may come back to a mode in another of
    its regions, which :func:`planner.planning.mode_graph.mode_sequences` (no mode twice)
    cannot express; and a step between two given regions takes its crossings from where
    those two meet, not from anywhere on the surface (a crossing into the wrong region of
    the next mode dooms the rest of the walk)."""
    adj: dict[int, set[int]] = {}
    for t in rmap.transits:
        adj.setdefault(t.a, set()).add(t.b)
        adj.setdefault(t.b, set()).add(t.a)
    starts = sorted(
        r.id for r in region_maps.regions_at(rmap, q_start, asm) if r.working_mode == start_mode
    )
    ends = {
        r.id
        for mode, goals in targets.items()
        for g in np.atleast_2d(goals)
        for r in region_maps.regions_at(rmap, g, asm)
        if r.working_mode == mode
    }
    # transits from every region to the nearest end (breadth first from the ends)
    dist = dict.fromkeys(ends, 0)
    frontier = sorted(ends)
    while frontier:
        nxt = []
        for a in frontier:
            for b in sorted(adj.get(a, ())):
                if b not in dist:
                    dist[b] = dist[a] + 1
                    nxt.append(b)
        frontier = nxt
    reachable = [dist[s] for s in starts if s in dist]
    if not reachable:
        return []
    fewest = max(1, min(reachable))
    out: list[tuple[int, ...]] = []

    def extend(path: list[int], length: int) -> None:
        if len(out) >= limit:
            return
        if len(path) - 1 == length:
            if path[-1] in ends:
                out.append(tuple(path))
            return
        for b in sorted(adj.get(path[-1], ())):
            if b not in path and len(path) + dist.get(b, length + 1) <= length:
                extend([*path, b], length)

    for length in range(fewest, fewest + detour + 1):
        for s in starts:
            extend([s], length)
    return out


def near_regions(
    rmap: region_maps.RegionMap, asm: str, regions: tuple[int, int], q: np.ndarray
) -> np.ndarray:
    """Which transit postures q (M, 3) lie within reach of a crossing (``max_step`` of
    :func:`planner.transits.crossing_through`, 0.5 rad, in cells) of both regions' cells: the
    candidates of a step between those two regions (the mode-change search then checks the
    crossing's ends exactly against the regions)."""
    from scipy import ndimage

    from planner.kinematics import ASSEMBLY_MODES

    ai = ASSEMBLY_MODES.index(asm)
    reach = int(np.ceil(0.5 / min(rmap.h2, rmap.h3))) + 1
    lo = rmap.design.joint_min
    k2 = np.clip(np.floor((q[:, 1] - lo[1]) / rmap.h2).astype(int), 0, rmap.n - 1)
    k3 = np.clip(np.floor((q[:, 2] - lo[2]) / rmap.h3).astype(int), 0, rmap.n - 1)
    keep = np.ones(len(q), dtype=bool)
    for rid in regions:
        r = rmap.regions[rid]
        mask = rmap.labels[ai, WORKING_MODES.index(r.working_mode)] == r.label
        near = ndimage.maximum_filter(mask, size=2 * reach + 1)
        keep &= near[k3, k2]
    return keep


def map_transits(rmap: region_maps.RegionMap, asm: str, before: str, after: str) -> np.ndarray:
    """Transit postures (M, 3) (theta1 0) from the region map: the cells of the flip
    before -> after (``RegionMap.transit_cells``) where the two other signed measures are
    >= ``serial_min`` over the whole cell, each cell centre moved onto the surface where
    the flipped measure vanishes (Newton steps on (theta2, theta3)). Empty when the map has
    no such cell; the caller checks the non-serial rules and builds the crossings."""
    from planner.kinematics import ASSEMBLY_MODES
    from planner.transits import serial_measure

    j = flipped_sign(before, after)
    ai = ASSEMBLY_MODES.index(asm)
    s_min = rmap.margins.serial_min
    mask = rmap.transit_cells[ai, j] > 0
    for k in range(3):
        if k != j:
            if before[k] == "+":
                mask &= rmap.measure_low[ai, k] >= s_min
            else:
                mask &= rmap.measure_high[ai, k] <= -s_min
    k3, k2 = np.nonzero(mask)
    if len(k3) == 0:
        return np.empty((0, 3))
    q = np.stack([np.zeros(len(k3)), rmap.theta2[k2], rmap.theta3[k3]], axis=1)
    flipped, h = FLIP_NAMES[j], 1e-7
    for _ in range(4):
        stencil = np.concatenate([q, q + np.array([0, h, 0]), q + np.array([0, 0, h])])
        f = serial_measure(rmap.design, stencil, asm, flipped).reshape(3, -1)
        grad = (f[1:] - f[0]) / h
        norm2 = (grad**2).sum(axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            step = (f[0] / norm2)[:, None] * grad.T
        ok = np.all(np.isfinite(step), axis=1)
        q, step = q[ok], step[ok]
        k3, k2 = k3[ok], k2[ok]
        q[:, 1:] -= step
    if len(q) == 0:
        return np.empty((0, 3))
    fb = forward_batch(rmap.design, q, asm)
    f = fb.serial_measures[:, j]
    keep = np.isfinite(f) & fb.ok
    for k in range(3):  # the moved posture keeps the other two signs with the margin
        if k != j:
            sign = 1.0 if before[k] == "+" else -1.0
            with np.errstate(invalid="ignore"):
                keep &= sign * fb.serial_measures[:, k] >= s_min
    reach = 1.5 * max(rmap.h2, rmap.h3)
    near = (np.abs(q[:, 1] - rmap.theta2[k2]) <= reach) & (
        np.abs(q[:, 2] - rmap.theta3[k3]) <= reach
    )
    lo, hi = rmap.design.joint_min, rmap.design.joint_max
    inside = (q[:, 1] >= lo[1]) & (q[:, 1] <= hi[1]) & (q[:, 2] >= lo[2]) & (q[:, 2] <= hi[2])
    return q[keep & (np.abs(f) < 1e-9) & near & inside]


def theta1_along(
    q: np.ndarray, q_from: np.ndarray, q_goal: np.ndarray, design: Design
) -> np.ndarray:
    """Transit postures ``q`` with theta1 set where the straight line q_from -> q_goal is
    nearest in (theta2, theta3) (no serial measure depends on theta1, so the postures stay
    on their surface), within theta1's limits."""
    d = q_goal[1:] - q_from[1:]
    dd = float(d @ d)
    t = np.clip((q[:, 1:] - q_from[1:]) @ d / dd, 0.0, 1.0) if dd > 0 else np.zeros(len(q))
    out = q.copy()
    out[:, 0] = np.clip(
        q_from[0] + t * (q_goal[0] - q_from[0]), design.joint_min[0], design.joint_max[0]
    )
    return out
