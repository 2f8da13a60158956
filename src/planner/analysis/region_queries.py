"""Questions asked of a region map (:mod:`planner.analysis.regions`): which cell holds a
posture (:func:`locate`), which regions hold it (:func:`regions_at`), and whether the map
proves that no valid path joins two postures (:func:`prove_disconnected`, the argument in
its docstring). A room of its own beside the map's construction; the map's module answers
these names too.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from planner.exceptions import InputError
from planner.kinematics import ASSEMBLY_MODES

if TYPE_CHECKING:
    from planner.analysis.regions import Region, RegionMap

__all__ = ["locate", "prove_disconnected", "regions_at"]


def locate(rmap: RegionMap, q: np.ndarray) -> tuple[int, int] | None:
    """(k3, k2) of a closed cell holding posture q (3,) rad, or None when (theta2, theta3)
    lie outside the joint box (theta1 is ignored: no rule but its limit depends on it).

    A posture on a cell edge lies in two or four closed cells; the one returned is any of
    them (each holds it, which is all the proofs need)."""
    return _locate(rmap, _posture(q))


def _posture(q: np.ndarray) -> tuple[float, float, float]:
    """Posture q (3,) rad as three finite floats (InputError otherwise)."""
    arr = np.asarray(q, dtype=float).reshape(-1)
    if arr.shape != (3,):
        raise InputError(f"q must be 3 finite numbers, got {arr!r}")
    q0, q1, q2 = arr.tolist()
    if not (math.isfinite(q0) and math.isfinite(q1) and math.isfinite(q2)):
        raise InputError(f"q must be 3 finite numbers, got {arr!r}")
    return q0, q1, q2


def _locate(rmap: RegionMap, q: tuple[float, float, float]) -> tuple[int, int] | None:
    """:func:`locate` of a posture checked by :func:`_posture`."""
    lo, hi = rmap.design.joint_min, rmap.design.joint_max
    if not (lo[1] <= q[1] <= hi[1] and lo[2] <= q[2] <= hi[2]):
        return None
    k2 = min(max(math.floor((q[1] - lo[1]) / rmap.h2), 0), rmap.n - 1)
    k3 = min(max(math.floor((q[2] - lo[2]) / rmap.h3), 0), rmap.n - 1)
    return k3, k2


def _components_at(rmap: RegionMap, q: np.ndarray, ai: int) -> set[int] | None:
    """Union-graph components of every region whose cells hold q (None: q outside the box
    or theta1 outside its limits)."""
    qf = _posture(q)
    cell = _locate(rmap, qf)
    d = rmap.design
    if cell is None or not d.joint_min[0] <= qf[0] <= d.joint_max[0]:
        return None
    k3, k2 = cell
    labs = rmap.labels[ai, :, k3, k2]
    return {
        rmap.regions[int(rmap.region_index[ai, mi, lab])].component
        for mi, lab in enumerate(labs.tolist())
        if lab > 0
    }


def regions_at(rmap: RegionMap, q: np.ndarray, assembly_mode: str) -> tuple[Region, ...]:
    """Every region of ``assembly_mode`` whose cells hold posture q (3,) rad, in working-mode
    order: one or a few (an undecided cell belongs to the over-approximation of several
    modes); empty outside the joint box (theta1 included) or where every mode's cell is
    surely invalid."""
    if assembly_mode not in ASSEMBLY_MODES:
        raise InputError(f"assembly_mode must be '+' or '-', got {assembly_mode!r}")
    qf = _posture(q)
    cell = _locate(rmap, qf)
    d = rmap.design
    if cell is None or not d.joint_min[0] <= qf[0] <= d.joint_max[0]:
        return ()
    ai = ASSEMBLY_MODES.index(assembly_mode)
    labs = rmap.labels[ai, :, cell[0], cell[1]].tolist()
    return tuple(
        rmap.regions[int(rmap.region_index[ai, mi, lab])] for mi, lab in enumerate(labs) if lab
    )


def prove_disconnected(
    rmap: RegionMap, start_q: np.ndarray, goal_q: np.ndarray, assembly_mode: str
) -> bool:
    """True only when no valid path (mode changes through serial transits included) joins
    ``start_q`` to ``goal_q`` in ``assembly_mode``, proven by the region map.

    Parameters
    ----------
    rmap : RegionMap
        The map of the plan's design and margins (obstacle-free).
    start_q : shape (3,), rad
    goal_q : shape (3,) or (K, 3), rad: one goal posture or every candidate posture of a
        goal (e.g. the inverse kinematics solutions of a Cartesian target); True only when
        every candidate is proven unreachable.
    assembly_mode : '+' | '-'

    Returns
    -------
    bool
        True: proven, no path exists. False: the map cannot prove it (a path may exist, or
        the start or a goal is outside the joint box, or lies in no region at all, i.e. is
        invalid, which the planner reports as ``invalid_start`` / ``invalid_goal``).

    Notes
    -----
    The argument. A plan is a continuous path q(t) in the joint box in one assembly mode,
    made of pieces valid in one working mode M (every rule: the set V_M) joined by transits,
    along which the non-serial rules hold and the two measures not being flipped keep their
    signs with margin ``serial_min`` (the set B of that flip, which contains V_M and V_M').
    So the path's (theta2, theta3) stays in the union of the closed sets V_M and B (theta1
    plays no part without obstacles; obstacles only remove postures, so a proof holds with
    them too). Every posture of V_M lies in a closed cell that is not surely invalid in M
    (a surely invalid cell holds no valid posture), hence inside the union of the closed
    cells of one region, and the same holds for B and its over-approximated components.
    A connected piece of the path inside V_M cannot leave its region's cells, since closed
    cells of two different 8-connected components share no point; it passes from V_M to a
    B, or from one B to another, only at a posture in both sets, i.e. (two transit sets meet
    only inside a V) inside V_M, where the region's cells and the B component's cells
    overlap, which is exactly how :func:`region_map` joins them. So the path stays inside
    the regions of one component of the union graph: if no region holding the start shares a
    component with a region holding a goal, any path would have to leave those cells, i.e.
    cross a cell that is surely invalid, which no valid posture is in. Undecided cells count
    as passable, so the proof is never claimed where the map cannot decide.
    """
    if assembly_mode not in ASSEMBLY_MODES:
        raise InputError(f"assembly_mode must be '+' or '-', got {assembly_mode!r}")
    ai = ASSEMBLY_MODES.index(assembly_mode)
    start = _components_at(rmap, start_q, ai)
    if not start:
        return False
    goals = np.atleast_2d(np.asarray(goal_q, dtype=float))
    if goals.ndim != 2 or goals.shape[1] != 3 or len(goals) == 0:
        raise InputError(f"goal_q must have shape (3,) or (K, 3), got {np.shape(goal_q)}")
    for g in goals:
        comps = _components_at(rmap, g, ai)
        if not comps or comps & start:
            return False
    return True
