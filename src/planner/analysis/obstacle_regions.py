"""Region maps with obstacles: proofs that no path passes a wall, on a grid of
(theta1, theta2, theta3) cells.

Why a third axis
----------------
The obstacle-free map of :mod:`planner.analysis.regions` is 2-D because no rule but theta1's
joint limit depends on theta1. Obstacles break that: whether a link touches a wall depends on
the angle of the loop's plane. A wall that the arm cannot pass while its plane turns through
it (a plate the links cannot all slip past) is invisible to the 2-D map. This module adds
theta1 as a third axis, per request, only for the proof; the 2-D map still carries every
other rule.

Cells and what blocks one
-------------------------
The grid has n x n cells over the (theta2, theta3) joint box (the cells of the obstacle-free
map at :data:`RESOLUTION`, whose labels and serial-measure bounds it reuses) times ``n1``
closed cells over theta1's joint range, ``n1`` chosen so that a theta1 cell is at most
the level's width (a thin plate needs thin theta1 cells: the links sweep through it
as the plane turns). A cell is *blocked* when every posture of the closed cell breaks the
clearance rule (a link closer than ``link_radius + clearance`` to an obstacle), shown by one
of these bounds, none of which needs a path inside the cell:

* a proximal link (A-C, or B-D): its far end C moves by at most L1 (a1 + a2) over the cell
  (a1, a2 the half-widths in theta1 and theta2: C is at most L1 from the axis AB and turns
  through at most a1 about it; in the plane it turns through a2 about A) and A is fixed, so
  the link's distance to an obstacle exceeds the centre's by at most L1 (a1 + a2). A-C depends
  on (theta1, theta2) only and B-D on (theta1, theta3): two small tables.
* the apex P and the midpoints of the distal links C-P, D-P: over the postures of the 2-D
  cell inside the kappa(A) band (the only ones that can be valid) they lie in planar
  rectangles of the loop's plane, bounded by interval arithmetic on the closed form
  P = (C + D) / 2 + s g(|CD|) J (D - C), g(d) = sqrt(L2^2 / d^2 - 1/4) (the same as in
  :mod:`planner.analysis.regions`: C, D and D - C move by at most L1 a2, L1 a3,
  L1 (a2 + a3); g is decreasing and is taken on the part of the cell's |CD| interval inside
  the band). A point of a link being closer than the limit makes the link so. Every
  obstacle is convex, so its signed distance is convex and its largest value over a
  rectangle is at a corner; turning the plane by at most a1 moves a point at distance |w|
  from the axis by at most |w| a1. A cell is blocked when, for one obstacle, the largest
  corner distance plus that spread is below the limit, or when the distance from the
  rectangle's centre to the nearest obstacle plus half its diagonal plus the spread is
  (the distance to a union of convex sets is 1-Lipschitz: this is the bound that a wall of
  a cloud's small balls, none of which holds a whole rectangle, is proven by).

Every bound reads the obstacles through their trees (:mod:`planner.spatial_index`), so the
proof is asked whatever the number of obstacles (measured on a loaded 2-core machine, queries
it cannot prove: 40-50 ms against the 10,000-point cloud of ``benchmarks/scenes.py``, 70-90 ms
against its 100,000-point cloud).

Computed distances carry a slack: the limit is lowered by 1 um (the signed depth inside a box
or capsule comes from a line search accurate to far less) and half-widths are inflated by a
relative 1e-9.

The argument
------------
A plan in one assembly mode is a continuous path whose postures are valid in a working mode
or lie on a transit (every non-serial rule holds there, clearance included). Its
(theta2, theta3) trace stays inside the cells of the regions of one component of the 2-D
union graph and of the transit sets joining them (:func:`planner.analysis.regions.
prove_disconnected`); a transit posture that is in no mode's region has a serial measure of
modulus below ``serial_min`` (else the posture would be valid in one of the two modes), so it
lies in a cell whose measure bounds allow that. The *mask* keeps the 2-D cells of the regions
of the start's components and every cell where some serial measure may be that small. Every
posture of the path then lies only in closed 3-D cells whose 2-D cell is in the mask, and in
no blocked cell (a blocked cell holds no posture with the clearance rule kept). Two closed
cells intersect exactly when they are 26-neighbours, so the path stays in one 26-connected
component of the passable cells (mask, not blocked). A breadth-first flood from the start's
cell that meets no goal cell therefore proves that no valid path joins them. Undecided cells
are passable: nothing is claimed where a bound cannot decide.

What it does not prove: a passage narrower than the bounds resolve (a gap between
obstacles, a plate the arm may slip past near the axis) stays open, and the search then
decides; joint limits and kappa(A) walls are the 2-D map's proof.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planner.analysis import _obstacle_kernels as K
from planner.analysis import regions as R
from planner.analysis.apex_bounds import REL_SLACK as _REL_SLACK
from planner.analysis.apex_bounds import point_sets
from planner.analysis.goal_cells import GoalBall, grid_cells
from planner.design import Design
from planner.exceptions import InputError
from planner.geometry import Obstacle, PackedObstacles, pack_obstacles
from planner.kinematics import ASSEMBLY_MODES, WORKING_MODES
from planner.validity import Margins

__all__ = [
    "BLOCKED",
    "LEVELS",
    "OUTSIDE",
    "PASSABLE",
    "ObstacleProof",
    "cell_states",
    "prove_disconnected_with_obstacles",
    "proximal_tables",
    "theta1_grid",
]

#: The grids tried in turn, coarse first (a coarse proof is cheap; a fine one resolves
#: narrower walls): (cells per axis of (theta2, theta3), the obstacle-free map at this
#: resolution; widest theta1 cell in rad, n1 = ceil(range / width), 8 .. 256 cells).
LEVELS: tuple[tuple[int, float], ...] = ((32, 0.08), (64, 0.04))
#: Goal cells of a goal ball that order the flood (:func:`_prove_on`), at most about.
_GUIDE_CELLS = 32
#: Lowered limit, m: computed signed depths are accurate to far less.
_DIST_SLACK = 1e-6


@dataclass(frozen=True, slots=True)
class ObstacleProof:
    """The outcome of :func:`prove_disconnected_with_obstacles`.

    Attributes
    ----------
    proven : True when no valid path joins the start to any goal.
    shape : (n1, n, n) cells over (theta1, theta3, theta2).
    visited : passable cells the flood met (the start's component when proven).
    """

    proven: bool
    shape: tuple[int, int, int]
    visited: int


def theta1_grid(design: Design, width: float) -> tuple[np.ndarray, float]:
    """Centres (n1,) and width of the theta1 cells: n1 = ceil(range / width), 8 .. 256."""
    lo, hi = float(design.joint_min[0]), float(design.joint_max[0])
    n1 = min(max(math.ceil((hi - lo) / width), 8), 256)
    h1 = (hi - lo) / n1
    return lo + h1 * (np.arange(n1) + 0.5), h1


def proximal_tables(
    design: Design,
    margins: Margins,
    obstacles: Sequence[Obstacle],
    theta1: np.ndarray,
    h1: float,
    rmap: R.RegionMap,
) -> tuple[np.ndarray, np.ndarray]:
    """(blocked_a (n1, n) over (theta1, theta2), blocked_b (n1, n) over (theta1, theta3)):
    the proximal link A-C (B-D) breaks the clearance rule at every posture of the cell."""
    packed = pack_obstacles(obstacles)
    limit = design.link_radius + margins.clearance - _DIST_SLACK
    a1 = 0.5 * h1 * (1.0 + _REL_SLACK)
    out = []
    for base_u, theta, h in (
        (-0.5 * design.L0, rmap.theta2, rmap.h2),
        (0.5 * design.L0, rmap.theta3, rmap.h3),
    ):
        table = np.empty((len(theta1), len(theta)), dtype=np.bool_)
        K.proximal_blocked(
            base_u,
            design.L1,
            theta1,
            a1,
            theta,
            0.5 * h * (1.0 + _REL_SLACK),
            *packed,
            limit,
            table,
        )
        out.append(table)
    return out[0], out[1]


def _mask(rmap: R.RegionMap, ai: int, components: set[int]) -> np.ndarray:
    """(n, n) bool [k3, k2]: the 2-D cells a path from a start in ``components`` may use."""
    mask = np.zeros((rmap.n, rmap.n), dtype=np.bool_)
    for mi in range(len(WORKING_MODES)):
        labs = rmap.labels[ai, mi]
        ids = rmap.region_index[ai, mi]
        keep = np.array(
            [
                lab > 0 and rmap.regions[int(ids[lab])].component in components
                for lab in range(len(ids))
            ],
            dtype=np.bool_,
        )
        mask |= keep[labs]
    s = rmap.margins.serial_min
    lo, hi = rmap.measure_low[ai], rmap.measure_high[ai]
    with np.errstate(invalid="ignore"):
        small = np.any((lo <= s) & (hi >= -s), axis=0)  # NaN: no posture in the band
    return mask | small


def _cell(theta1: np.ndarray, h1: float, rmap: R.RegionMap, q: np.ndarray) -> tuple | None:
    lo1 = theta1[0] - 0.5 * h1
    if not lo1 <= q[0] <= theta1[-1] + 0.5 * h1:
        return None
    k = R.locate(rmap, q)
    if k is None:
        return None
    i1 = min(max(math.floor((q[0] - lo1) / h1), 0), len(theta1) - 1)
    return (i1, k[0], k[1])


def prove_disconnected_with_obstacles(
    design: Design,
    margins: Margins,
    obstacles: Sequence[Obstacle],
    start_q: np.ndarray,
    goal_q: np.ndarray,
    assembly_mode: str,
    *,
    levels: Sequence[tuple[int, float]] = LEVELS,
    goal_ball: GoalBall | None = None,
) -> ObstacleProof:
    """Whether no valid path (mode changes through serial transits included) joins
    ``start_q`` to any of ``goal_q`` (3,) or (K, 3) in ``assembly_mode`` among
    ``obstacles``, proven on a 3-D grid of :data:`LEVELS` (the argument is the module's
    docstring); the grids are tried coarse first, up to the first proof.

    ``goal_ball``: every goal a tolerance request allows; the proof then covers every cell
    that may hold one of them (:func:`planner.analysis.goal_cells.grid_cells`) as well as
    ``goal_q`` (which may then be empty, shape (0, 3)).

    ``proven`` is False where no grid can prove it (a path may exist; or the start or a
    goal lies outside the joint box or in a cell that no valid posture can be in).
    """
    if assembly_mode not in ASSEMBLY_MODES:
        raise InputError(f"assembly_mode must be '+' or '-', got {assembly_mode!r}")
    start_q = np.asarray(start_q, dtype=float).reshape(3)
    goals = np.atleast_2d(np.asarray(goal_q, dtype=float))
    if goals.size == 0 and goal_ball is not None:
        goals = np.empty((0, 3))
    if goals.ndim != 2 or goals.shape[1] != 3 or (len(goals) == 0 and goal_ball is None):
        raise InputError(f"goal_q must have shape (3,) or (K, 3), got {np.shape(goal_q)}")
    answer = ObstacleProof(False, (0, 0, 0), 0)
    for n, width in levels:
        answer = _prove_on(
            design, margins, obstacles, start_q, goals, assembly_mode, n, width, goal_ball
        )
        if answer.proven:
            break
    return answer


@dataclass(frozen=True, slots=True, eq=False)
class _Grid:
    """One level's grid for one request (see :func:`passable_cells`)."""

    rmap: R.RegionMap
    theta1: np.ndarray
    h1: float
    mask: np.ndarray
    blocked_a: np.ndarray
    blocked_b: np.ndarray
    sets: np.ndarray
    limit: float


def _grid(design, margins, obstacles, assembly_mode, components, n, width) -> _Grid:
    rmap = R.region_map(design, margins, n)
    theta1, h1 = theta1_grid(design, width)
    ai = ASSEMBLY_MODES.index(assembly_mode)
    return _Grid(
        rmap,
        theta1,
        h1,
        _mask(rmap, ai, components),
        *proximal_tables(design, margins, obstacles, theta1, h1, rmap),
        point_sets(design, margins, rmap, assembly_mode),
        design.link_radius + margins.clearance - _DIST_SLACK,
    )


def _passable(grid: _Grid, packed: PackedObstacles, cell) -> bool:
    i = cell[0]
    a1 = 0.5 * grid.h1 * (1.0 + _REL_SLACK)
    return bool(
        K.cell_passable(
            grid.mask,
            grid.blocked_a,
            grid.blocked_b,
            grid.sets,
            math.cos(grid.theta1[i]),
            math.sin(grid.theta1[i]),
            a1,
            *packed,
            grid.limit,
            *cell,
        )
    )


#: Cell codes of :func:`cell_states`.
OUTSIDE, BLOCKED, PASSABLE = 0, 1, 2


def cell_states(
    design: Design,
    margins: Margins,
    obstacles: Sequence[Obstacle],
    start_q: np.ndarray,
    assembly_mode: str,
    n: int,
    width: float,
) -> tuple[np.ndarray, np.ndarray, R.RegionMap]:
    """For tests and figures: every cell of the grid a proof from ``start_q`` uses at one
    level, evaluated (the flood evaluates only those it meets). Returns (states (n1, n, n)
    int8 [i1, k3, k2]: :data:`OUTSIDE` the mask, :data:`BLOCKED`, :data:`PASSABLE`;
    theta1 cell centres; the obstacle-free map of the (theta2, theta3) cells)."""
    rmap = R.region_map(design, margins, n)
    comps = {r.component for r in R.regions_at(rmap, np.asarray(start_q, float), assembly_mode)}
    grid = _grid(design, margins, obstacles, assembly_mode, comps, n, width)
    out = np.empty((len(grid.theta1), n, n), dtype=np.int8)
    K.all_states(
        grid.mask,
        grid.blocked_a,
        grid.blocked_b,
        grid.sets,
        grid.theta1,
        0.5 * grid.h1 * (1.0 + _REL_SLACK),
        *pack_obstacles(obstacles),
        grid.limit,
        out,
    )
    return out, grid.theta1, rmap


def _prove_on(
    design, margins, obstacles, start_q, goals, assembly_mode, n, width, goal_ball=None
) -> ObstacleProof:
    """The proof on one level's grid."""
    rmap = R.region_map(design, margins, n)
    theta1, h1 = theta1_grid(design, width)
    shape = (len(theta1), n, n)
    no = ObstacleProof(False, shape, 0)
    start_regions = R.regions_at(rmap, start_q, assembly_mode)
    start_cell = _cell(theta1, h1, rmap, start_q)
    if not start_regions or start_cell is None:
        return no
    components = {r.component for r in start_regions}
    grid = _grid(design, margins, obstacles, assembly_mode, components, n, width)
    packed = pack_obstacles(obstacles)
    targets = []
    for g in goals:
        if not {r.component for r in R.regions_at(rmap, g, assembly_mode)} & components:
            continue  # the obstacle-free map keeps this goal apart already
        cell = _cell(theta1, h1, rmap, g)
        if cell is None or not _passable(grid, packed, cell):
            return no
        targets.append(cell)
    goal = np.zeros(shape, dtype=np.bool_)
    for cell in targets:
        goal[cell] = True
    if goal_ball is not None:
        goal |= grid_cells(goal_ball, rmap, assembly_mode, components, theta1, h1)
    if not goal.any():
        return ObstacleProof(True, shape, 0)
    # the flood dives towards a few goal cells first (the order only; ``goal`` decides)
    cells = np.argwhere(goal)
    guide = np.vstack(
        [
            np.asarray(targets, dtype=np.int64).reshape(-1, 3),
            cells[:: max(1, len(cells) // _GUIDE_CELLS)],
        ]
    )
    visits = np.zeros(1, dtype=np.int64)
    reached = K.flood_reaches(
        grid.mask,
        grid.blocked_a,
        grid.blocked_b,
        grid.sets,
        theta1,
        0.5 * h1 * (1.0 + _REL_SLACK),
        *packed,
        grid.limit,
        np.asarray(start_cell, dtype=np.int64),
        goal,
        guide.astype(np.int64),
        visits,
    )
    return ObstacleProof(reached == 0, shape, int(visits[0]))
