"""The goal set of a tolerance request as cells of a region map, for proofs that cover every
goal the request allows.

A goal with ``tolerance`` allows a set of goals, not one: every posture that puts P within
the tolerance of the target point in an allowed working mode (a Cartesian target), or every
posture within the tolerance of the goal posture in joint space (a joint goal). A proof that
no valid path exists is a promise about the request as asked, so it must cover that whole set:
it is proven only when no cell that may hold a valid allowed goal is reachable from the start.

Which cells may hold a goal
---------------------------
Every test below keeps a cell when it cannot rule it out (an over-approximation of the goal
set), so a proof over these cells covers every allowed goal.

* *Point ball* (``kind = "point"``, centre p, radius r): over the postures of a 2-D cell in the
  kappa(A) band (the only ones that can be valid), P lies in a planar rectangle
  [u0, u1] x [w0, w1] of the loop's plane (:func:`planner.analysis.apex_bounds.point_sets`).
  theta1 turns that plane about AB: P = (w cos theta1, u, -w sin theta1), so the point of
  the plane (u, w) can come no closer to p than sqrt((u - p_y)^2 + (|w| - rho)^2), rho the
  distance of p from the axis AB (equality for a theta1 that points the plane at p). The
  2-D cell is kept when the least of that over the rectangle is <= r. A 3-D cell (theta1
  cell of centre c and half-width a1) is kept when the distance from p to the rectangle
  turned to c, less |w|max a1 (turning the plane by at most a1 moves a point at distance
  |w| from the axis by at most |w| a1), is <= r.
* *Joint ball* (``kind = "joint"``, centre g, radius r): the cell's box of joint values is kept
  when its Euclidean distance to g is <= r (theta1 left out in 2-D, where it is free).
* In both, a 2-D cell is kept for a working mode only when the mode is allowed and the cell
  lies in a region of that mode (not surely invalid): an allowed goal is a valid posture of
  an allowed mode.

Distances are compared with an absolute slack of 1e-9 m (or rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.analysis import regions as R
from planner.analysis.apex_bounds import point_sets
from planner.exceptions import InputError
from planner.kinematics import ASSEMBLY_MODES, WORKING_MODES

__all__ = ["GOAL_KINDS", "GoalBall", "grid_cells", "plane_cells", "prove_ball_disconnected"]

#: The kinds of goal ball: P within a distance of a point, or q within a distance of a posture.
GOAL_KINDS = ("point", "joint")
_SLACK = 1e-9


@dataclass(frozen=True, slots=True, eq=False)
class GoalBall:
    """Every goal a tolerance request allows.

    Attributes
    ----------
    kind : "point": postures that put P within ``radius`` m of ``centre`` (a Cartesian
        target); "joint": postures within ``radius`` rad (Euclidean) of ``centre``.
    centre : (3,) m or rad.
    radius : >= 0.
    working_modes : the working modes an allowed goal may be in (a Cartesian target's mode,
        or all eight for "any" and for a joint goal, whose mode is its own).
    """

    kind: str
    centre: np.ndarray
    radius: float
    working_modes: tuple[str, ...] = WORKING_MODES

    def __post_init__(self) -> None:
        if self.kind not in GOAL_KINDS:
            raise InputError(f"kind must be one of {GOAL_KINDS}, got {self.kind!r}")
        c = np.asarray(self.centre, dtype=float).reshape(-1)
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise InputError(f"centre must be 3 finite numbers, got {self.centre!r}")
        object.__setattr__(self, "centre", c)
        if not (math.isfinite(self.radius) and self.radius >= 0.0):
            raise InputError(f"radius must be a finite number >= 0, got {self.radius!r}")
        bad = [m for m in self.working_modes if m not in WORKING_MODES]
        if bad or not self.working_modes:
            raise InputError(f"working_modes must be among {WORKING_MODES}, got {bad or '()'}")


def _interval_gap(
    x: np.ndarray | float, lo: np.ndarray | float, hi: np.ndarray | float
) -> np.ndarray:
    """Distance from x to [lo, hi] (0 inside), elementwise."""
    return np.maximum(np.maximum(lo - x, x - hi), 0.0)


def _abs_interval(w0: np.ndarray, w1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """{|w| : w in [w0, w1]} as [lo, hi]."""
    lo = np.where((w0 <= 0.0) & (w1 >= 0.0), 0.0, np.minimum(np.abs(w0), np.abs(w1)))
    return lo, np.maximum(np.abs(w0), np.abs(w1))


def plane_cells(ball: GoalBall, rmap: R.RegionMap, assembly_mode: str) -> np.ndarray:
    """(8, n, n) bool [working mode, k3, k2]: the 2-D cells of ``rmap`` that may hold an
    allowed goal valid in that working mode (the module docstring says why)."""
    if assembly_mode not in ASSEMBLY_MODES:
        raise InputError(f"assembly_mode must be '+' or '-', got {assembly_mode!r}")
    ai = ASSEMBLY_MODES.index(assembly_mode)
    d = rmap.design
    r = ball.radius + _SLACK
    if ball.kind == "point":
        rect = point_sets(d, rmap.margins, rmap, assembly_mode)[..., 0, :]
        u0, u1, w0, w1 = (rect[..., i] for i in range(4))
        p = ball.centre
        rho = math.hypot(p[0], p[2])
        a_lo, a_hi = _abs_interval(w0, w1)
        with np.errstate(invalid="ignore"):
            near = np.hypot(_interval_gap(p[1], u0, u1), _interval_gap(rho, a_lo, a_hi)) <= r
        near &= ~np.isnan(u0)
    else:
        g = ball.centre
        t3, t2 = np.meshgrid(rmap.theta3, rmap.theta2, indexing="ij")
        g2 = _interval_gap(g[1], t2 - 0.5 * rmap.h2, t2 + 0.5 * rmap.h2)
        g3 = _interval_gap(g[2], t3 - 0.5 * rmap.h3, t3 + 0.5 * rmap.h3)
        g1 = float(_interval_gap(g[0], d.joint_min[0], d.joint_max[0]))
        near = np.sqrt(g1 * g1 + g2 * g2 + g3 * g3) <= r
    out = np.zeros((len(WORKING_MODES), rmap.n, rmap.n), dtype=np.bool_)
    for m in ball.working_modes:
        mi = WORKING_MODES.index(m)
        out[mi] = near & (rmap.labels[ai, mi] > 0)
    return out


def _cell_components(rmap: R.RegionMap, ai: int, cells: np.ndarray) -> np.ndarray:
    """(8, n, n) int: per working mode and cell, the union-graph component of the region
    labelled there (-1 where ``cells`` (8, n, n) is False)."""
    out = np.full(cells.shape, -1, dtype=np.int64)
    for mi in range(len(WORKING_MODES)):
        if not cells[mi].any():
            continue
        ids = rmap.region_index[ai, mi]  # label -> region id (-1: no region has the label)
        comp = np.array([rmap.regions[int(i)].component if i >= 0 else -1 for i in ids])
        comp[0] = -1  # label 0: surely invalid
        out[mi] = np.where(cells[mi], comp[rmap.labels[ai, mi]], -1)
    return out


def prove_ball_disconnected(
    rmap: R.RegionMap, start_q: np.ndarray, ball: GoalBall, assembly_mode: str
) -> bool:
    """True only when no valid path (mode changes included) joins ``start_q`` to any goal of
    ``ball`` in ``assembly_mode``: no cell of :func:`plane_cells` lies in a region of the
    start's union-graph components (the argument of
    :func:`planner.analysis.regions.prove_disconnected`, with the goal cells in place of
    the goal postures' cells). False where the start lies in no region."""
    ai = ASSEMBLY_MODES.index(assembly_mode)
    start = {r.component for r in R.regions_at(rmap, np.asarray(start_q, float), assembly_mode)}
    if not start:
        return False
    comps = _cell_components(rmap, ai, plane_cells(ball, rmap, assembly_mode))
    return not np.isin(comps, sorted(start)).any()


def grid_cells(
    ball: GoalBall,
    rmap: R.RegionMap,
    assembly_mode: str,
    components: set[int],
    theta1: np.ndarray,
    h1: float,
) -> np.ndarray:
    """(n1, n, n) bool [i1, k3, k2]: the cells of the 3-D grid (theta1 cells of centres
    ``theta1`` and width ``h1`` times the cells of ``rmap``) that may hold an allowed goal in
    a region of one of ``components`` (goals in other components are kept apart by the
    obstacle-free map already)."""
    ai = ASSEMBLY_MODES.index(assembly_mode)
    plane = plane_cells(ball, rmap, assembly_mode)
    comps = _cell_components(rmap, ai, plane)
    keep = np.asarray(np.isin(comps, sorted(components)).any(axis=0))  # (n, n)
    out = np.zeros((len(theta1), rmap.n, rmap.n), dtype=np.bool_)
    if not keep.any():
        return out
    r = ball.radius + _SLACK
    a1 = 0.5 * h1 * (1.0 + 1e-9)
    if ball.kind == "joint":
        g1 = _interval_gap(ball.centre[0], theta1 - a1, theta1 + a1)  # (n1,)
        t3, t2 = np.meshgrid(rmap.theta3, rmap.theta2, indexing="ij")
        g2 = _interval_gap(ball.centre[1], t2 - 0.5 * rmap.h2, t2 + 0.5 * rmap.h2)
        g3 = _interval_gap(ball.centre[2], t3 - 0.5 * rmap.h3, t3 + 0.5 * rmap.h3)
        dist = np.sqrt(g1[:, None, None] ** 2 + (g2 * g2 + g3 * g3)[None])
        return (dist <= r) & keep[None]
    rect = point_sets(rmap.design, rmap.margins, rmap, assembly_mode)[..., 0, :]
    k3s, k2s = np.nonzero(keep)
    u0, u1, w0, w1 = (rect[k3s, k2s, i] for i in range(4))
    wmax = np.maximum(np.abs(w0), np.abs(w1))
    p = ball.centre
    for i1, c in enumerate(theta1):
        # p in the plane turned to theta1 = c: e_w = (cos c, 0, -sin c), e_u = y, normal
        # e_n = (sin c, 0, cos c)
        pw = p[0] * math.cos(c) - p[2] * math.sin(c)
        pn = p[0] * math.sin(c) + p[2] * math.cos(c)
        d2 = np.hypot(_interval_gap(p[1], u0, u1), _interval_gap(pw, w0, w1))
        hit = np.hypot(d2, pn) - wmax * a1 <= r
        out[i1, k3s[hit], k2s[hit]] = True
    return out
