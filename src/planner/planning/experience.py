"""Paths remembered per scene: a query in a scene where searching was hard walks a path
found there before, joined to its ends by two certified motions (issue 43).

Why: in a scene with a narrow passage every query pays a search to find the passage and a
simplification whose motions graze it (the benchmark's window: 1-2 ms of search and about
as much of simplification per query, where a certificate near the plate costs 0.1-0.3 ms).
The passage is the same for every query of the scene, so its certified paths are kept, as
OMPL's experience planners (Lightning, Thunder) keep theirs: a later query tries the joins
start -> a remembered posture and a remembered posture -> goal, shortest total first, and
walks the remembered path between them.

What is remembered: the simplified path of a compiled search (:mod:`compiled_rrt`) whose
trees grew to at least :data:`MIN_NODES` nodes (a hard query: a search of a few dozen nodes,
as in open scenes, is cheaper than the joins and is not remembered, so the answers of easy
scenes never depend on what was planned before), at most :data:`MAX_PATHS` per scene, the
oldest out first. The scene is the checker's design, margins, modes, serial rules and its
packed obstacle arrays (by identity: :func:`planner.geometry.pack_obstacles` gives the same
arrays for the same obstacles while its cache holds them; an entry is only used with the
very arrays it was made with). Kept through :mod:`planner.caching` (``experience.paths``).

Soundness: every motion of a remembered path was certified when it was found; the two joins
are certified now, with the simplification's slack (:data:`compiled_rrt.SIMPLIFY_SLACK`:
they are new motions that may graze what the path turns around). So the answer is
certified as a search's is; :func:`planner.planning.compiled_rrt.search` simplifies the walk
(:data:`planner.planning.compiled_rrt.RECALL_SHORTCUT_TRIES`), seeded by ``options.seed``.
Determinism: a process answers a query from its own history (what it remembered), like the
corridor grid's cache; a fresh process answers the same sequence of queries the same way (as
far as the rest of the planner does: the corridor's first try is timed, so under another load
another query of a sequence may be the one that searches, and what is remembered differs).
``PlanOptions.simplify=False`` (the raw search) never uses or fills it.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass, replace

import numpy as np

from planner.caching import BoundedCache, bounded_cache
from planner.validity import MIN_CERTIFIED_STEP, ValidityChecker, certify_motion

__all__ = ["MAX_DETOUR", "MAX_PATHS", "MAX_TESTS", "MIN_NODES", "guide", "recall", "remember"]

#: Tree nodes (both trees) from which a search's path is remembered.
MIN_NODES = 64
#: Remembered paths per scene (the oldest out first). Few: each adds its vertices to the
#: candidates, and the joins to the nearest of many paths mostly fail, spending the recall's
#: :data:`MAX_TESTS` (narrow window, 40 queries run four times in one process, CPU p50 per
#: round: 16 paths with every path of a hard scene kept: 1.5, 4.4, 4.7, 4.5 ms, walks
#: 16, 3, 1, 1 of 37; 4 paths of hard searches: 1.5, 1.9, 2.2, 2.2 ms, walks 16, 14, 13, 12;
#: no memory: 4.3, 3.9, 3.5, 3.2 ms).
MAX_PATHS = 4
#: Longest walk tried, as a multiple of the straight distance start -> goal (joint space):
#: a remembered path far from the query is not worth its joins' certificates (in clutter,
#: where a start's join often holds and a goal's does not, those cost more than a search).
#: Measured (40 queries, CPU time of the whole plan, load 4-5): in the narrow window 2.0
#: walked 9 remembered paths (p50 2.3 ms), 3.0 16 (p50 1.4 ms; none: 18, 1.5 ms); among
#: the 1,000 spheres, where no walk holds, p50 0.6-0.75 ms with or without memory.
MAX_DETOUR = 3.0
#: Most join motions certified per recall (a recall that needs more gives up: the search).
MAX_TESTS = 24


@dataclass(frozen=True, slots=True, eq=False)
class _Scene:
    """What is remembered of one scene: weak references to the packed obstacle arrays it
    was made with (their identity; the arrays are the obstacle cache's, not weighed here),
    the kernels' parameters with the simplification's slack (the joins'), and the paths
    (each (M, 3) rad)."""

    packed: tuple[weakref.ref, ...]
    slack: np.ndarray
    paths: tuple[np.ndarray, ...]


_CACHE: BoundedCache[_Scene] = bounded_cache("experience.paths")


def _key(checker: ValidityChecker) -> tuple:
    return (
        checker.design,
        checker.margins,
        checker.assembly_mode,
        checker.working_mode,
        checker.serial_rules,
        tuple(id(a) for a in checker.packed),
    )


def _scene(checker: ValidityChecker) -> _Scene | None:
    hit = _CACHE.get(_key(checker))
    if hit is None or any(r() is not a for r, a in zip(hit.packed, checker.packed, strict=True)):
        return None
    return hit


def remember(checker: ValidityChecker, path: np.ndarray, slack: float, *, nodes: int) -> None:
    """Keep ``path`` (M, 3) rad, every motion certified for ``checker``, for the checker's
    scene when its search grew ``nodes`` >= :data:`MIN_NODES` tree nodes; ``slack`` (m): the
    extra clearance the joins of later recalls keep."""
    if not checker.obstacles or len(path) < 2:
        return
    if nodes < MIN_NODES:
        return
    old = _scene(checker)
    if old is None:
        margins = replace(checker.margins, clearance=checker.margins.clearance + slack)
        refs = tuple(weakref.ref(a) for a in checker.packed)
        old = _Scene(refs, checker.with_margins(margins).params, ())
    kept = np.array(path, dtype=float)
    kept.flags.writeable = False
    _CACHE.put(_key(checker), replace(old, paths=(*old.paths, kept)[-MAX_PATHS:]))


def recall(
    checker: ValidityChecker, q_start: np.ndarray, q_goal: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """A path ``q_start`` -> ``q_goal`` (N, 3) rad along a remembered path of the checker's
    scene, every motion certified, with the kernels' parameters of the joins (the checker's
    with the slack, for the caller's simplification); or None (nothing remembered, or no
    join certified within :data:`MAX_TESTS` motions).

    The candidates are (path, entry vertex i, exit vertex j), walked forwards (i <= j) or
    backwards, by the length start -> P[i] -> along P -> P[j] -> goal; they are tried
    shortest first, each join certified once (a failed join fails every candidate that
    uses it)."""
    scene = _scene(checker)
    if scene is None:
        return None
    q_start = np.asarray(q_start, dtype=float)
    q_goal = np.asarray(q_goal, dtype=float)
    rows = []  # (cost, path, i, j)
    for p, path in enumerate(scene.paths):
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
        ds = np.linalg.norm(path - q_start, axis=1)
        dg = np.linalg.norm(path - q_goal, axis=1)
        cost = ds[:, None] + np.abs(cum[None, :] - cum[:, None]) + dg[None, :]
        i, j = np.indices(cost.shape)
        rows.append(np.stack([cost.ravel(), np.full(cost.size, p), i.ravel(), j.ravel()], 1))
    order = np.concatenate(rows)
    order = order[order[:, 0] <= MAX_DETOUR * float(np.linalg.norm(q_goal - q_start))]
    order = order[np.argsort(order[:, 0], kind="stable")]
    prm, packed, step = scene.slack, checker.packed, checker.coarse_step

    def test(q_a: np.ndarray, q_b: np.ndarray) -> bool:
        # writable copies: the remembered rows are read-only, and the certificate takes
        # writable postures (one compiled signature: planner._kernels.read_only's rule)
        a, b = np.array(q_a), np.array(q_b)
        return certify_motion(a, b, prm, *packed, step, MIN_CERTIFIED_STEP, False)[0] == 0

    joins: dict[tuple[int, int, int], bool] = {}  # (end 0 start / 1 goal, path, vertex)
    tests = 0
    for _, p, i, j in order:
        p, i, j = int(p), int(i), int(j)
        path = scene.paths[p]
        for end, v, q in ((0, i, q_start), (1, j, q_goal)):
            if (end, p, v) not in joins:
                if tests >= MAX_TESTS:
                    return None
                tests += 1
                joins[(end, p, v)] = bool(test(q, path[v]) if end == 0 else test(path[v], q))
            if not joins[(end, p, v)]:
                break
        else:
            walk = path[i : j + 1] if i <= j else path[j : i + 1][::-1]
            out = np.vstack([q_start, walk, q_goal])
            keep = np.ones(len(out), dtype=bool)
            keep[1:] = np.any(np.diff(out, axis=0) != 0.0, axis=1)  # no motion of no length
            return out[keep], scene.slack
    return None


def guide(checker: ValidityChecker) -> np.ndarray:
    """The remembered paths of the checker's scene as one (M, 3) array of their waypoints,
    each path's followed by NaN rows (a break between paths), for a search to sample near
    (:func:`planner.planning.compiled_rrt.rrt_connect`: where a recall found no join, the
    passage the earlier searches found is still there); (0, 3) when nothing is remembered."""
    scene = _scene(checker)
    if scene is None or not scene.paths:
        return np.empty((0, 3))
    gap = np.full((1, 3), np.nan)
    return np.ascontiguousarray(np.vstack([row for p in scene.paths for row in (p, gap)]))
