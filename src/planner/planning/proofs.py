"""Proven infeasibility: the region map's answers that no valid path exists, asked before
(or between) the searches of :func:`planner.planning.plan`.

*Without obstacles' help* (:func:`disprove_with_map`): the start and every goal candidate the
request allows lie in different components of the design's obstacle-free region map
(:func:`planner.analysis.regions.prove_disconnected`; :data:`PROOF_RESOLUTION` cells, cached
per process, built only while :data:`PROOF_MIN_BUDGET_S` of the budget remains,
:func:`proof_region_map`); if so the answer is ``no_path`` at once with
``diagnostics.proven_infeasible`` and a message naming the regions. Obstacles only remove
postures, so the proof holds with them.

*With obstacles* (:func:`disprove_with_obstacles`): a wall of obstacles needs theta1 too, so
:func:`planner.analysis.obstacle_regions.prove_disconnected_with_obstacles` proves the start
cut off on the 3-D grid (a few to hundreds of milliseconds, so the dispatcher asks it only
for a plan whose first try found nothing). Its bounds read the obstacles through their trees
(:mod:`planner.spatial_index`), so it is asked whatever their number: a cloud of 100,000
points costs tens of milliseconds more than none.

Each answer is :func:`planner.planning.result.proven_no_path`; None where the map cannot
prove it (a path may exist).
"""

from __future__ import annotations

import time

import numpy as np

from planner.analysis import obstacle_regions
from planner.analysis import regions as region_maps
from planner.design import Design
from planner.geometry import Obstacle
from planner.planning.problem import JointPosture, PlanOptions
from planner.planning.result import PlanResult, proven_no_path
from planner.validity import Margins

__all__ = [
    "PROOF_MIN_BUDGET_S",
    "PROOF_RESOLUTION",
    "disprove_with_map",
    "disprove_with_obstacles",
    "proof_region_map",
]

#: Cells per axis of the region map the planner consults (:mod:`planner.analysis.regions`).
#: 128 builds in about 25 ms on a loaded 2-core machine (256: 60-90 ms) and is as sound;
#: a finer map only proves more (fewer undecided cells).
PROOF_RESOLUTION = 128
#: A map not yet in the cache is built only when at least this much of the budget remains,
#: s (a cached map is consulted whatever the budget: a look-up costs microseconds).
PROOF_MIN_BUDGET_S = 0.1


def proof_region_map(
    design: Design, margins: Margins, options: PlanOptions, deadline: float
) -> region_maps.RegionMap | None:
    """The design's obstacle-free region map at :data:`PROOF_RESOLUTION` for a proof, when it
    is cheap now: cached, or built while at least :data:`PROOF_MIN_BUDGET_S` remains before
    ``deadline`` (a :func:`time.monotonic` value); None otherwise, or when
    ``options.region_map`` is off."""
    if not options.region_map:
        return None
    rmap = region_maps.cached_region_map(design, margins, PROOF_RESOLUTION)
    if rmap is None and deadline - time.monotonic() >= PROOF_MIN_BUDGET_S:
        rmap = region_maps.region_map(design, margins, PROOF_RESOLUTION)
    return rmap


def disprove_with_map(
    rmap: region_maps.RegionMap | None, start: JointPosture, goals: np.ndarray, t0: float
) -> PlanResult | None:
    """``no_path`` with ``diagnostics.proven_infeasible`` when the region map ``rmap`` proves
    that no valid path joins ``start`` to any of the goal candidates ``goals`` (K, 3) (every
    candidate the request allows; valid postures); None when it cannot (or there is no map,
    or no goal). ``t0``: the request's start (a :func:`time.monotonic` value).

    The argument is :func:`planner.analysis.regions.prove_disconnected`'s: the map is
    obstacle-free, and obstacles only remove postures, so its proof holds with them. The
    answer names the regions of the start and of the goals, no search run."""
    if rmap is None or len(goals) == 0:
        return None
    if not region_maps.prove_disconnected(rmap, start.q, goals, start.assembly_mode):
        return None
    return proven_no_path(_disproof_message(rmap, start, goals), t0)


#: Obstacle objects (a sphere, box or capsule is one, a point cloud one as a whole) above
#: which the 3-D proof is not asked: its flood tests every object against every cell and
#: cannot be stopped at a deadline; with the 1,000 small spheres of ``benchmarks/planning.py
#: --fair`` it took 2.7 s per level (a 1 s request answered after 2-6 s). Many small
#: obstacles rarely close every path the proof's bounds could show; the search decides there.
#: A cloud is one object: its points are proven against as a whole (a 10,000-point wall is
#: proven, ``tests/scenes/test_cloud_proofs.py``).
OBSTACLE_PROOF_MAX_OBJECTS = 200


def disprove_with_obstacles(
    design: Design,
    margins: Margins,
    obstacles: tuple[Obstacle, ...],
    start: JointPosture,
    goals: np.ndarray,
    *,
    searched_s: float,
    t0: float,
) -> PlanResult | None:
    """``no_path`` with ``diagnostics.proven_infeasible`` when the obstacles close every
    path from the start to the goal candidates ``goals`` (K, 3) (every candidate the
    request allows), proven on the 3-D grid of
    :func:`planner.analysis.obstacle_regions.prove_disconnected_with_obstacles`; None
    when it cannot, and without trying for more than :data:`OBSTACLE_PROOF_MAX_OBJECTS`
    obstacles. ``searched_s``: how long the search ran before (for the message);
    ``t0``: the request's start."""
    if len(goals) == 0 or len(obstacles) > OBSTACLE_PROOF_MAX_OBJECTS:
        return None
    asm = start.assembly_mode
    proof = obstacle_regions.prove_disconnected_with_obstacles(
        design, margins, obstacles, start.q, goals, asm
    )
    if not proof.proven:
        return None
    n1, n3, n2 = proof.shape
    n_goals = len(np.atleast_2d(goals))
    which = "the goal" if n_goals == 1 else f"any of its {n_goals} goal candidates"
    return proven_no_path(
        f"no valid path exists (proven by the region map with obstacles, {n1} x {n3} x "
        f"{n2} cells over (theta1, theta3, theta2), after {searched_s * 1e3:.0f} ms of "
        f"search): in assembly mode {asm} the obstacles cut the start off from {which}: "
        f"the {proof.visited} cells reachable from the start hold no goal, and every path "
        "out of them crosses cells where a link surely comes closer to an obstacle than "
        "link_radius + clearance, or a posture breaks a rule (joint limits, kappa_max, "
        "serial_min)",
        t0,
    )


def _disproof_message(rmap: region_maps.RegionMap, start: JointPosture, goals: np.ndarray) -> str:
    """The ``no_path`` message of a proof: the regions (id, working mode, union-graph
    component) holding the start and the goal candidates."""
    asm = start.assembly_mode

    def names(q: np.ndarray) -> list[str]:
        return [
            f"region {r.id} (working mode {r.working_mode}, component {r.component})"
            for r in region_maps.regions_at(rmap, q, asm)
        ]

    at_start = names(start.q)
    at_goals = list(dict.fromkeys(n for g in np.atleast_2d(goals) for n in names(g)))
    shown = ", ".join(at_goals[:4]) + (
        f" and {len(at_goals) - 4} more" if len(at_goals) > 4 else ""
    )
    n_goals = len(np.atleast_2d(goals))
    which = "the goal lies in" if n_goals == 1 else f"its {n_goals} goal candidates lie in"
    return (
        f"no valid path exists (proven by the region map, {rmap.n} x {rmap.n} cells, no "
        f"search run): in assembly mode {asm} the start lies in {', '.join(at_start)}, "
        f"{which} {shown}; no chain of regions and serial transits joins them, so every "
        "path between them crosses a posture that breaks a rule (joint limits, kappa_max, "
        "serial_min)"
    )
