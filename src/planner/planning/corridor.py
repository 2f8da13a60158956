"""Narrow passages: a coarse 3-D grid of the valid set guides the search (issue 17).

Plain RRT-Connect struggles where the valid set of a mode narrows to a thin passage (the
benchmark's window scene: the whole arm must pass a window while its plane turns through
theta1 = 0). With obstacles the 2-D region map of :mod:`planner.analysis.regions` is not
enough, because collisions depend on theta1 too. This module builds the 3-D form:

1. :func:`corridor_grid`: cells over the joint box (theta1, theta2, theta3), each marked by
   the validity of its centre (:meth:`ValidityChecker.is_valid`, vectorised). Without
   obstacles every rule but theta1's limit depends on (theta2, theta3) only, so the
   obstacle-free checker is asked once per (theta2, theta3) column first, and only the
   columns valid there are evaluated with the obstacles along theta1. The marked cells are
   labelled by 6-connected components (face neighbours: fewer edges to relax than 26
   neighbours, and on the benchmark's narrow scene faster to search and never worse after
   shortcutting). The grid is kept in a small per-process LRU cache
   keyed by what the marks depend on (design, margins, obstacles, modes, serial rules,
   shape): the obstacles of a robot cell are static across requests, so the second plan in
   the same scene pays no build.
2. :func:`corridor_path`: a short path on the graph of marked cells (6 neighbours,
   weighted A*, edges the joint distance times a penalty near unmarked cells) from the start's cell to the goal's, each end
   attached to a marked cell nearby by a certified motion; waypoints start, cell centres,
   goal; then shortcut greedily with the certified motion test. A piece between two
   consecutive waypoints that cannot be certified is repaired by a small OMPL search
   between its two ends; when that fails too, there is no corridor path.

The grid is a heuristic guide, not a proof: a cell's mark says only that its centre is
valid, and two marked neighbours need not be joined by a valid motion (nor are unmarked
cells surely invalid). Nothing of the grid reaches the answer uncertified: every motion of a
returned path passed :meth:`ValidityChecker.motion_test`, and the planner re-certifies the
whole path with :meth:`ValidityChecker.check_path`. A grid that does not join start and goal
only means that the planner falls back to its plain search, never that no path exists.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy import ndimage

from planner.analysis.heap import heap_grow, heap_pop, heap_push
from planner.caching import BoundedCache, bounded_cache
from planner.geometry import packed_digest
from planner.planning import compiled_rrt
from planner.planning.problem import PlanOptions
from planner.validity import ValidityChecker

__all__ = [
    "DEFAULT_SHAPE",
    "CorridorGrid",
    "CorridorOutcome",
    "GuidedOutcome",
    "cached_corridor_grid",
    "corridor_grid",
    "corridor_path",
    "guided_search",
]

logger = logging.getLogger(__name__)

#: Cells per axis (theta1, theta2, theta3) of a corridor grid, picked on the benchmark's
#: narrow scene (docs/planning.md "Narrow passages"; 37 queries, measured while the search
#: was being tuned): 16 x 32 x 32 and 16 x 48 x 48 found no certified path for 10-11 of them,
#: 24 x 48 x 48 and 32 x 48 x 48 needed OMPL repairs, 32 x 64 x 64 none (its build, about
#: 40 k cells with obstacles, is paid once per scene and mode).
DEFAULT_SHAPE = (32, 64, 64)
#: Cells searched around a posture (Chebyshev radius) for a marked cell to attach it to.
ATTACH_RADIUS = 2
#: Nearest marked cells tried per end (by distance) for a certified attaching motion.
ATTACH_TRIES = 12
#: OMPL budget (s) of the plain search tried before a grid that is not cached is built.
FIRST_TRY_S = 0.02
#: Least budget (s) left for building a grid that is not cached (else the plain search).
BUILD_MIN_BUDGET_S = 0.1
#: Largest share of the budget left that building a grid may take (projected after its
#: first slice; a costlier build stops and the plain search gets the rest).
BUILD_SHARE = 0.4
#: Weight of the A* heuristic (1: shortest grid paths; more: fewer cells expanded, paths at
#: most this factor longer, which the shortcutting straightens anyway).
HEURISTIC_WEIGHT = 3.0
#: Extra cost factor of entering a cell next to an unmarked one (``1 + DEPTH_PENALTY /
#: depth**2``, depth in cells): near the border of the valid set the margins are thin and
#: certifying a motion there takes many pieces.
DEPTH_PENALTY = 4.0
#: OMPL budget (s) for repairing one piece of the corridor path that is not certified.
REPAIR_BUDGET_S = 0.005
#: Most pieces repaired per corridor path before giving up (the plain search follows).
MAX_REPAIRS = 4


@dataclass(frozen=True, slots=True, eq=False)
class CorridorGrid:
    """The marked cells of one checker's valid set (read-only arrays).

    Attributes
    ----------
    shape : cells per axis (n1, n2, n3).
    lo, step : (3,) rad: the joint box's lower corner and the cell edges; cell (i, j, k)
        has its centre at ``lo + step * ((i, j, k) + 0.5)``.
    valid : bool (n1, n2, n3): the centre is valid for the checker.
    labels : int32 (n1, n2, n3): 6-connected component of each marked cell (1, 2, ...), 0
        for unmarked cells.
    weight : float (n1 * n2 * n3,): the cost factor of entering each cell on a grid path,
        ``1 + DEPTH_PENALTY / depth**2`` with ``depth`` the chessboard distance (cells) to the
        nearest unmarked cell: grid paths keep to the middle of the valid set, where margins
        are wide and the motion certificate needs few pieces.
    build_time_s : s spent building the grid (not counted again on a cache hit).
    """

    shape: tuple[int, int, int]
    lo: np.ndarray
    step: np.ndarray
    valid: np.ndarray
    labels: np.ndarray
    weight: np.ndarray
    build_time_s: float

    def centres(self, cells: np.ndarray) -> np.ndarray:
        """Centres (N, 3), rad, of cells given as integer indices (N, 3)."""
        return self.lo + self.step * (np.asarray(cells, dtype=float) + 0.5)

    def cell_of(self, q: np.ndarray) -> np.ndarray:
        """Integer index (3,) of the cell holding posture ``q`` (3,), rad (clipped to the box)."""
        idx = np.floor((np.asarray(q, dtype=float) - self.lo) / self.step).astype(np.int64)
        return np.clip(idx, 0, np.asarray(self.shape) - 1)

    @property
    def nbytes(self) -> int:
        """Bytes of the grid's arrays."""
        return int(self.valid.nbytes + self.labels.nbytes + self.weight.nbytes)


@dataclass(frozen=True, slots=True)
class CorridorOutcome:
    """``waypoints`` (N, 3) rad, every motion certified, or None; ``cells``: cells of the
    grid path (0 when none was found); ``repairs``: OMPL repairs of pieces; ``why``: why
    there is no path, empty when there is one."""

    waypoints: np.ndarray | None
    cells: int
    repairs: int
    why: str


# ----------------------------------------------------------------------------- the grid
def corridor_grid(
    checker: ValidityChecker,
    shape: tuple[int, int, int] = DEFAULT_SHAPE,
    *,
    max_time_s: float | None = None,
) -> CorridorGrid | None:
    """The corridor grid of ``checker`` at ``shape`` cells (cached; see the module docstring).

    Parameters
    ----------
    checker : the valid set to mark (its design, margins, obstacles, modes, serial rules).
    shape : cells per axis (theta1, theta2, theta3), each >= 2.
    max_time_s : when given, the build stops and returns None (nothing cached) as soon as
        its projected time exceeds this: the cells with obstacles are marked a slice of
        theta1 at a time, and after each slice the whole is projected from them. The
        projection is remembered, and a later call whose ``max_time_s`` is less than half of
        it returns None at once (no repeated partial builds in a scene far too costly to
        grid; within a factor 2, as under a passing load, the build is tried again).

    Returns
    -------
    CorridorGrid or None
        The same object for the same (design, margins, obstacles, assembly mode, working
        mode, serial rules, shape) while it stays in the per-process LRU cache
        ``corridor.grids`` (at most 32 grids and its share of the cache budget,
        :mod:`planner.caching`: the least recently used go first).
    """
    key = _cache_key(checker, shape)
    hit = _CACHE.get(key)
    if hit is not None:
        return hit
    projected = _TOO_COSTLY.get(key)
    if max_time_s is not None and projected is not None and projected > 2 * max_time_s:
        return None  # a build stopped before was projected to take far longer
    grid = _build(checker, key[-1], max_time_s)
    if isinstance(grid, float):
        _TOO_COSTLY.put(key, grid)
        return None
    _CACHE.put(key, grid)
    return grid


def cached_corridor_grid(
    checker: ValidityChecker, shape: tuple[int, int, int] = DEFAULT_SHAPE
) -> CorridorGrid | None:
    """The grid :func:`corridor_grid` would return, if it is in this process's cache now;
    None otherwise (nothing is built)."""
    return _CACHE.get(_cache_key(checker, shape))


def _cache_key(checker: ValidityChecker, shape: tuple[int, int, int]) -> tuple:
    """What the marks depend on: the design with its joint limits, the margins, the obstacles
    (a digest of their packed rows with their shapes, :func:`planner.geometry.packed_digest`,
    computed once per packing), the modes, the serial rules and the shape."""
    obstacles = packed_digest(checker.packed)
    cells = tuple(int(n) for n in shape)
    if len(cells) != 3 or min(cells) < 2:
        raise ValueError(f"shape must be 3 cell counts >= 2, got {cells!r}")
    return (
        checker.design,
        checker.margins,
        obstacles,
        checker.assembly_mode,
        checker.working_mode,
        checker.serial_rules,
        cells,
    )


def _build(
    checker: ValidityChecker, shape: tuple[int, int, int], max_time_s: float | None
) -> CorridorGrid | float:
    """Mark and label the cells (the work of :func:`corridor_grid`, uncached); the projected
    time (s) instead when it exceeds ``max_time_s``."""
    t0 = time.monotonic()
    design = checker.design
    lo = np.asarray(design.joint_min, dtype=float)
    hi = np.asarray(design.joint_max, dtype=float)
    n = np.asarray(shape)
    step = (hi - lo) / n
    axes = [lo[i] + step[i] * (np.arange(n[i]) + 0.5) for i in range(3)]
    g2, g3 = np.meshgrid(axes[1], axes[2], indexing="ij")
    # obstacle-free first: every rule but theta1's limit depends on (theta2, theta3) only,
    # and every theta1 centre lies inside the limits
    free = ValidityChecker(
        design,
        checker.margins,
        (),
        checker.assembly_mode,
        checker.working_mode,
        serial_rules=checker.serial_rules,
    )
    q2 = np.stack([np.full(g2.size, axes[0][0]), g2.ravel(), g3.ravel()], axis=1)
    columns = np.flatnonzero(free.is_valid(q2))
    valid = np.zeros((n[0], n[1] * n[2]), dtype=bool)
    if len(columns) and checker.obstacles:
        q = np.empty((len(columns), 3))
        q[:, 1:] = q2[columns, 1:]
        for i in range(n[0]):
            q[:, 0] = axes[0][i]
            valid[i, columns] = checker.is_valid(q)
            projected = (time.monotonic() - t0) * n[0] / (i + 1)
            if max_time_s is not None and projected > max_time_s:
                logger.debug("corridor grid not built: projected %.3f s", projected)
                return projected
    elif len(columns):
        valid[:, columns] = True
    valid = valid.reshape(shape)
    labels, _ = ndimage.label(valid)
    labels = labels.astype(np.int32)
    depth = ndimage.distance_transform_cdt(valid, metric="chessboard")
    weight = (1.0 + DEPTH_PENALTY / np.maximum(depth, 1) ** 2).ravel()
    for a in (lo, step, valid, labels, weight):
        a.flags.writeable = False
    return CorridorGrid(shape, lo, step, valid, labels, weight, time.monotonic() - t0)


#: The per-process LRU cache of :func:`corridor_grid`: key -> grid (a grid of n cells holds
#: 5 n bytes: 0.7 MB at the default shape; its share: :data:`planner.caching.CACHES`).
_CACHE: BoundedCache[CorridorGrid] = bounded_cache("corridor.grids")
#: Keys whose build was stopped, with its projected time (s).
_TOO_COSTLY: BoundedCache[float] = bounded_cache("corridor.too_costly")


# ----------------------------------------------------------------------------- the search
def corridor_path(
    checker: ValidityChecker,
    grid: CorridorGrid,
    q_start: np.ndarray,
    q_goal: np.ndarray,
    *,
    options: PlanOptions,
    deadline: float,
) -> CorridorOutcome:
    """A certified path ``q_start`` -> ``q_goal`` (3,) rad guided by ``grid``, or None.

    Steps: attach each end to a marked cell nearby (Chebyshev radius :data:`ATTACH_RADIUS`,
    nearest first, by a certified motion; the goal's cell in the start's component); the
    short 6-neighbour path between the two cells on the marked cells (weighted A*, joint
    distance between centres times the entered cell's ``weight``); then greedy shortcutting from each
    anchor: the goal itself first, else the first waypoint reached by a certified motion
    halving the span towards the anchor (a failed test stops at its first invalid sample
    and costs little, a successful one certifies its whole motion: one success per anchor).
    A piece between two consecutive waypoints that cannot be certified is repaired by an OMPL
    search between its ends (:data:`REPAIR_BUDGET_S`, at most :data:`MAX_REPAIRS`), within
    ``deadline`` (``time.monotonic()`` value).

    Returns
    -------
    CorridorOutcome
        ``waypoints`` with every motion certified by :meth:`ValidityChecker.motion_test`, or
        None with ``why``.
    """
    test = checker.motion_test()
    q_start = np.array(q_start, dtype=float)
    q_goal = np.array(q_goal, dtype=float)
    ends = _attach(checker, grid, test, q_start, q_goal)
    if ends is None:
        return CorridorOutcome(None, 0, 0, "no marked cell joins start and goal")
    s, g = ends
    n1, n2, n3 = grid.shape
    flat = _astar(
        np.ascontiguousarray(grid.valid.ravel()),
        grid.weight,
        n1,
        n2,
        n3,
        np.array(grid.step, dtype=float),
        s[0] * n2 * n3 + s[1] * n3 + s[2],
        g[0] * n2 * n3 + g[1] * n3 + g[2],
        HEURISTIC_WEIGHT,
    )
    if len(flat) == 0:  # pragma: no cover - same component, so A* finds a path
        return CorridorOutcome(None, 0, 0, "no grid path")
    cells = np.stack(np.unravel_index(flat, grid.shape), axis=1)
    points = np.vstack([q_start, grid.centres(cells), q_goal])
    waypoints, repairs = _shortcut(checker, test, points, options, deadline)
    if waypoints is None:
        return CorridorOutcome(None, len(cells), repairs, "a corridor piece was not certified")
    return CorridorOutcome(waypoints, len(cells), repairs, "")


def _attach(
    checker: ValidityChecker, grid: CorridorGrid, test, q_start: np.ndarray, q_goal: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """Marked cells (3,) for start and goal, each joined to its posture by a certified
    motion and both in one component; None when none is found."""
    goal_cands = _near_cells(grid, q_goal)
    if not len(goal_cands) or not len(starts := _near_cells(grid, q_start)):
        return None
    goal_labels = grid.labels[tuple(goal_cands.T)]
    goal_ok: dict[int, bool] = {}
    tried_labels: set[int] = set()
    for s in starts[:ATTACH_TRIES]:
        label = int(grid.labels[tuple(s)])
        if label in tried_labels or not (goal_labels == label).any():
            continue
        if not test(q_start, grid.centres(s[None])[0]):
            continue
        tried_labels.add(label)
        for k in np.flatnonzero(goal_labels == label)[:ATTACH_TRIES]:
            if k not in goal_ok:
                goal_ok[k] = bool(test(grid.centres(goal_cands[k][None])[0], q_goal))
            if goal_ok[k]:
                return s, goal_cands[k]
    return None


def _near_cells(grid: CorridorGrid, q: np.ndarray) -> np.ndarray:
    """Marked cells (K, 3) within :data:`ATTACH_RADIUS` of the cell of ``q``, nearest centre
    first."""
    c = grid.cell_of(q)
    r = ATTACH_RADIUS
    lo = np.maximum(c - r, 0)
    hi = np.minimum(c + r + 1, np.asarray(grid.shape))
    block = grid.valid[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]]
    cells = np.argwhere(block) + lo
    if not len(cells):
        return cells
    d = np.linalg.norm(grid.centres(cells) - q, axis=1)
    return cells[np.argsort(d, kind="stable")]


def _shortcut(
    checker: ValidityChecker,
    test,
    points: np.ndarray,
    options: PlanOptions,
    deadline: float,
) -> tuple[np.ndarray | None, int]:
    """Greedy shortcutting of ``points`` (M + 1, 3) whose first and last motions are
    certified; every motion of the result is certified. (waypoints or None, repairs)."""
    m = len(points) - 1
    out = [points[0]]
    a = repairs = 0
    while a < m:
        if a + 1 == m or test(points[a], points[m]):
            out.append(points[m])
            break
        # halving down from the goal: failed tests stop at their first invalid sample and
        # cost little; a successful one certifies its whole motion, so keep the first
        best, span = 0, (m - a) // 2
        while span > 1 and not best:
            if test(points[a], points[a + span]):
                best = a + span
            span //= 2
        if not best and (a == 0 or test(points[a], points[a + 1])):
            best = a + 1  # (from the start, the attaching motion is certified)
        if best:
            out.append(points[best])
            a = best
            continue
        if repairs >= MAX_REPAIRS or time.monotonic() >= deadline:
            return None, repairs
        repairs += 1
        budget = min(REPAIR_BUDGET_S, deadline - time.monotonic())
        fix = compiled_rrt.search(checker, points[a], points[a + 1], options, budget)
        if fix.waypoints is None:
            return None, repairs
        out.extend(fix.waypoints[1:-1])
        out.append(points[a + 1])
        a += 1
    return np.array(out), repairs


@njit(cache=True, nogil=True)
def _astar(valid, weight, n1, n2, n3, step, source, target, greed):  # pragma: no cover - compiled
    """Cells (flat indices, source first) of a short 6-neighbour path between two marked
    cells of the flat mask ``valid`` (n1 * n2 * n3), edge costs the Euclidean distance of the
    centres (``step`` the cell edges, rad) times the entered cell's ``weight``; empty when
    none. A* with the Euclidean distance to the target times ``greed`` as its heuristic
    (weighted A*: a path at most that factor costlier than the least costly) and the binary
    heap of :mod:`planner.analysis.heap` (cost, cell)."""
    n = n1 * n2 * n3
    cost = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int64)
    done = np.zeros(n, dtype=np.bool_)
    ti, tj, tk = target // (n2 * n3), (target // n3) % n2, target % n3
    offsets = np.empty((6, 3), dtype=np.int64)
    lengths = np.empty(6)
    e = 0
    for di in range(-1, 2):
        for dj in range(-1, 2):
            for dk in range(-1, 2):
                if abs(di) + abs(dj) + abs(dk) == 1:
                    offsets[e, 0], offsets[e, 1], offsets[e, 2] = di, dj, dk
                    lengths[e] = np.sqrt(
                        (di * step[0]) ** 2 + (dj * step[1]) ** 2 + (dk * step[2]) ** 2
                    )
                    e += 1
    hkey = np.empty(4096)  # the heap of (cost + heuristic, cell), grown as it fills
    hval = np.empty(4096, dtype=np.int64)
    cost[source] = 0.0
    size = heap_push(hkey, hval, 0, 0.0, source)
    while size > 0:
        cell, size = heap_pop(hkey, hval, size)
        if done[cell]:
            continue
        done[cell] = True
        if cell == target:
            break
        ci, cj, ck = cell // (n2 * n3), (cell // n3) % n2, cell % n3
        for e in range(6):
            ni, nj, nk = ci + offsets[e, 0], cj + offsets[e, 1], ck + offsets[e, 2]
            if ni < 0 or ni >= n1 or nj < 0 or nj >= n2 or nk < 0 or nk >= n3:
                continue
            nb = (ni * n2 + nj) * n3 + nk
            if not valid[nb] or done[nb]:
                continue
            new = cost[cell] + weight[nb] * lengths[e]
            if new >= cost[nb]:
                continue
            cost[nb] = new
            parent[nb] = cell
            h = np.sqrt(
                ((ti - ni) * step[0]) ** 2 + ((tj - nj) * step[1]) ** 2 + ((tk - nk) * step[2]) ** 2
            )
            hkey, hval = heap_grow(hkey, hval, size)
            size = heap_push(hkey, hval, size, new + greed * h, nb)
    if not done[target]:
        return np.empty(0, dtype=np.int64)
    count = 1
    c = target
    while c != source:
        c = parent[c]
        count += 1
    out = np.empty(count, dtype=np.int64)
    c = target
    for k in range(count - 1, -1, -1):
        out[k] = c
        c = parent[c]
    return out


@dataclass(frozen=True, slots=True)
class GuidedOutcome:
    """What :func:`guided_search` did: ``waypoints`` (N, 3) rad or None; ``name``:
    'corridor' when it found them; ``searches``: OMPL searches run (repairs); ``ompl_status``
    (empty: the corridor runs no search of its own); ``certified``: every motion was
    certified here by the motion test (no OMPL repair)."""

    waypoints: np.ndarray | None
    name: str
    searches: int
    ompl_status: str
    certified: bool


def guided_search(
    checker: ValidityChecker,
    q_start: np.ndarray,
    q_goal: np.ndarray,
    options: PlanOptions,
    deadline: float,
    *,
    shape: tuple[int, int, int] = DEFAULT_SHAPE,
) -> GuidedOutcome:
    """The corridor's part of :func:`planner.planning.single_mode.plan_in_region` (with obstacles).

    Policy (measured on ``benchmarks/planning.py``, docs/planning.md "Narrow passages"): when
    the checker's grid is cached, the corridor is tried at once (a warm grid costs a look-up);
    otherwise the caller has run a plain OMPL search of :data:`FIRST_TRY_S` first (most
    queries of open scenes end there, and they must not pay a build), and the grid is built
    here if :data:`BUILD_MIN_BUDGET_S` of the budget remains and the build is projected to
    take at most :data:`BUILD_SHARE` of it (the build counts against the budget), and the
    corridor tried. A None ``waypoints`` leaves the plain search to the caller, with what
    remains of the budget.
    """
    grid = cached_corridor_grid(checker, shape)
    if grid is None:
        left = deadline - time.monotonic()
        if left < BUILD_MIN_BUDGET_S:
            return GuidedOutcome(None, "", 0, "", False)
        grid = corridor_grid(checker, shape, max_time_s=BUILD_SHARE * left)
        if grid is None:
            return GuidedOutcome(None, "", 0, "", False)
    out = corridor_path(checker, grid, q_start, q_goal, options=options, deadline=deadline)
    logger.debug("corridor: %d cells, %d repairs, %s", out.cells, out.repairs, out.why or "found")
    return GuidedOutcome(
        out.waypoints,
        "corridor" if out.waypoints is not None else "",
        out.repairs,
        "",
        out.waypoints is not None and out.repairs == 0,
    )
