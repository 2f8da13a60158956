"""Shared factories of the validity and planning tests: an independent reference of the
validity rules (from planner.kinematics and dense point sampling, not the validity kernels),
scenes, and wire conversion for the independent plan checker (``tests/plan_checker.py``)."""

from __future__ import annotations

import numpy as np
from plan_checker import PlanCheck, check_plan
from scipy import ndimage

from planner.analysis import regions as R
from planner.design import Design
from planner.geometry import Box, Capsule, Points, Sphere, segment_obstacle_distance
from planner.kinematics import WORKING_MODES, conditioning, forward_batch, link_points
from planner.validity import Margins, ValidityChecker

LINKS = ((0, 2), (1, 3), (2, 4), (3, 4))  # AC, BD, CP, DP in link_points order A, B, C, D, P


def rotation_matrix(quat: np.ndarray) -> np.ndarray:
    # independent route: quaternion -> matrix through the rotation of the basis vectors
    w, v = quat[0], quat[1:]
    cols = []
    for e in np.eye(3):
        t = 2 * np.cross(v, e)
        cols.append(e + w * t + np.cross(v, t))
    return np.stack(cols, axis=1)


def point_distance(x: np.ndarray, ob) -> np.ndarray:
    """Signed distance of points (M, 3) to an obstacle, from the definitions (the box frame
    from :func:`rotation_matrix`, not the library's own rotation)."""
    if isinstance(ob, Sphere):
        return np.linalg.norm(x - ob.center, axis=1) - ob.radius
    if isinstance(ob, Points):
        from scipy.spatial import cKDTree

        return cKDTree(ob.points).query(x)[0] - ob.radius
    if isinstance(ob, Capsule):
        ab = ob.b - ob.a
        t = np.clip((x - ob.a) @ ab / (ab @ ab), 0, 1)
        return np.linalg.norm(ob.a + t[:, None] * ab - x, axis=1) - ob.radius
    local = (x - ob.center) @ rotation_matrix(ob.quaternion)
    q = np.abs(local) - ob.size / 2
    return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)


def reference_measures(
    design: Design, q: np.ndarray, assembly_mode: str, mode: str, obstacles, k=400
):
    """(ok, kappa_A, signed serial min, clearance) of postures q (N, 3) from kinematics and
    link sampling every 1/k of each link (k = 0: exact segment distances of planner.geometry,
    itself tested against sampling)."""
    fb = forward_batch(design, q, assembly_mode)
    c = conditioning(design, fb.q, fb.passive, fb.w)
    signs = np.array([1.0 if ch == "+" else -1.0 for ch in mode])
    serial = np.min(fb.serial_measures * signs, axis=1)
    return fb.ok, c.kappa_A, serial, _links_clearance(design, fb, obstacles, LINKS, k)


def reference_clearance(
    design: Design, q: np.ndarray, assembly_mode: str, obstacles, links, k=0
) -> np.ndarray:
    """The least clearance (m) of some of the links (pairs of ``link_points`` indices, e.g.
    ``LINKS[:2]`` the proximal AC and BD) at postures q (N, 3), as :func:`reference_measures`
    measures it; NaN where the loop does not close."""
    fb = forward_batch(design, q, assembly_mode)
    clear = _links_clearance(design, fb, obstacles, links, k)
    return np.where(fb.ok, clear, np.nan)


def _links_clearance(design: Design, fb, obstacles, links, k) -> np.ndarray:
    pts = link_points(design, fb.q, fb.passive)
    n = len(fb.q)
    clear = np.full(n, np.inf)
    if k == 0:
        for i, j in links:
            good = fb.ok
            d = np.full(n, np.nan)
            d[good] = segment_obstacle_distance(pts[good, i], pts[good, j], obstacles)
            clear = np.minimum(clear, d - design.link_radius)
        return clear
    s = np.linspace(0, 1, k + 1)
    for i, j in links:
        x = pts[:, i, None, :] + s[None, :, None] * (pts[:, j] - pts[:, i])[:, None, :]
        for ob in obstacles:
            d = point_distance(x.reshape(-1, 3), ob).reshape(n, -1).min(axis=1)
            clear = np.minimum(clear, d - design.link_radius)
    return clear


def wire_obstacle(ob) -> dict:
    if isinstance(ob, Points):
        return {"type": "points", "points": ob.points.tolist(), "radius": ob.radius}
    if isinstance(ob, Sphere):
        return {"type": "sphere", "center": ob.center.tolist(), "radius": ob.radius}
    if isinstance(ob, Capsule):
        return {"type": "capsule", "a": ob.a.tolist(), "b": ob.b.tolist(), "radius": ob.radius}
    return {
        "type": "box",
        "center": ob.center.tolist(),
        "size": ob.size.tolist(),
        "quaternion": ob.quaternion.tolist(),
    }


def wire_design(d: Design) -> dict:
    return {
        "L0": d.L0,
        "L1": d.L1,
        "L2": d.L2,
        "link_radius": d.link_radius,
        "joint_min": list(d.joint_min),
        "joint_max": list(d.joint_max),
    }


def plan_request(design, start, goal_wire: dict, margins, obstacles) -> dict:
    """The /v1/plan request (wire JSON) of a library plan: design, start, goal, margins and
    obstacles written out in full, so that the checker needs none of the library's defaults."""
    return {
        "design": wire_design(design),
        "start": {"q": start.q.tolist(), "assembly_mode": start.assembly_mode},
        "goal": goal_wire,
        "margins": {
            "kappa_max": margins.kappa_max,
            "serial_min": margins.serial_min,
            "clearance": margins.clearance,
        },
        "obstacles": [wire_obstacle(o) for o in obstacles],
    }


def plan_answer(result) -> dict:
    """The wire answer of a library :class:`~planner.planning.PlanResult` (no trajectory), as
    the service would send it: :func:`planner.wire.plan_response` dumped to JSON types."""
    from planner.wire import plan_response

    return plan_response(result).model_dump(mode="json")


def check_library_plan(design, start, goal_wire: dict, margins, obstacles, response: dict):
    """Re-check a library plan (its wire answer, :func:`plan_answer`) with the independent checker of
    ``tests/plan_checker.py``; returns its :class:`~plan_checker.PlanCheck` (``ok``, and the
    broken rules in ``str()``)."""
    report: PlanCheck = check_plan(
        plan_request(design, start, goal_wire, margins, obstacles), response
    )
    return report


def dense_grid_components(design: Design, margins: Margins, asm: str, grid: int):
    """The independent flood of the proofs' tests: 4-connected components of the valid grid
    postures of each working mode on a ``grid`` x ``grid`` (theta2, theta3) grid over the
    joint box, from the validity checker alone. Returns (theta2 (grid,), theta3 (grid,),
    labels (8, grid, grid) [mode, theta3 row, theta2 column], 0 = invalid)."""
    t2 = np.linspace(design.joint_min[1], design.joint_max[1], grid)
    t3 = np.linspace(design.joint_min[2], design.joint_max[2], grid)
    g3, g2 = np.meshgrid(t3, t2, indexing="ij")
    q = np.stack([np.zeros(g2.size), g2.ravel(), g3.ravel()], axis=1)
    labels = np.zeros((8, grid, grid), dtype=np.int32)
    for mi, mode in enumerate(WORKING_MODES):
        valid = ValidityChecker(design, margins, (), asm, mode).is_valid(q).reshape(grid, grid)
        labels[mi] = ndimage.label(valid)[0]  # default structure: 4-connected
    return t2, t3, labels


#: The general design cut by a box of joint limits into two components in assembly mode '-'.
CUT = Design(0.3, 0.3, 0.4, joint_min=(-3.14, -0.49, -2.81), joint_max=(3.14, 0.51, -1.72))


def cut_ends(resolution: int) -> tuple[np.ndarray, np.ndarray]:
    """A surely valid cell centre in each of CUT's two big components of assembly mode '-'
    (its region map at ``resolution``)."""
    rmap = R.region_map(CUT, n=resolution)
    big = [r for r in rmap.regions if r.assembly_mode == "-" and r.valid_cells > 200]
    ends = []
    for comp in sorted({r.component for r in big}):
        region = next(r for r in big if r.component == comp)
        mi = WORKING_MODES.index(region.working_mode)
        k3, k2 = np.nonzero((rmap.labels[1, mi] == region.label) & (rmap.status[1, mi] == R.VALID))
        k = len(k3) // 2
        ends.append(np.array([0.3, rmap.theta2[k2[k]], rmap.theta3[k3[k]]]))
    assert len(ends) == 2
    return ends[0], ends[1]


def seeded_scene(rng: np.random.Generator, most: int = 6) -> list:
    """2 to ``most`` spheres (radius 0.05-0.2 m) and boxes (edges 0.02-0.6 m, random
    orientation) centred in [-0.7, 0.7]^3: the seeded scenes of the false-proof tests."""
    obs = []
    for _ in range(rng.integers(2, most + 1)):
        c = rng.uniform(-0.7, 0.7, 3)
        if rng.uniform() < 0.5:
            obs.append(Sphere(c, rng.uniform(0.05, 0.2)))
        else:
            quat = rng.normal(size=4)
            obs.append(Box(c, rng.uniform(0.02, 0.6, 3), quat / np.linalg.norm(quat)))
    return obs
