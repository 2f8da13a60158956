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
trees grew to at least :data:`MIN_NODES` nodes (:data:`SPARSE_MIN_NODES` with few obstacles,
where the search's range is shorter; a hard query: a search of a few dozen nodes, as in open
scenes, is cheaper than the joins and is not remembered, so the answers of easy scenes never
depend on what was planned before), at most :data:`MAX_PATHS` per scene, the
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

import math
import weakref
from dataclasses import dataclass, replace

import numpy as np
from numba import njit

from planner.caching import BoundedCache, bounded_cache
from planner.validity import (
    MIN_CERTIFIED_STEP,
    N_MEASURES,
    ValidityChecker,
    blocked_near,
    certify_between,
    measure_posture,
)

__all__ = [
    "MAX_DETOUR",
    "MAX_PATHS",
    "MAX_TESTS",
    "MIN_NODES",
    "SPARSE_MIN_NODES",
    "guide",
    "load_kernels",
    "recall",
    "remember",
]

#: Tree nodes (both trees) from which a search's path is remembered, in clutter (at least
#: ``compiled_rrt.CLUTTER_ROWS`` obstacle rows, where the search's range is 0.25 rad).
MIN_NODES = 64
#: The same with fewer obstacle rows, where the search's range is 0.6 rad
#: (``compiled_rrt.SPARSE_RANGE``): the same passage is found with fewer nodes than at the
#: 1.0 rad for which :data:`MIN_NODES` was chosen (the window's searches of query seed 11:
#: 8-80 nodes, none of its main mode past 64, against 5-119 at 1.0 rad), so at 64 nothing
#: was remembered and every query searched. Measured in the narrow window (fair table, CPU
#: p50 / p95, docs/planning.md run J): query seed 11 1.87 / 7.3 ms at 64, 1.54 / 2.68 at 32,
#: 1.35 / 2.96 at 40; seed 23 1.64 / 4.03, 1.71 / 3.73, 1.46 / 3.20.
SPARSE_MIN_NODES = 40
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
    the kernels' parameters with the simplification's slack (the joins'), the paths (each
    (M, 3) rad, read-only) and the same paths as one array for the compiled code: each
    path's rows followed by a NaN row (:func:`guide`'s and :func:`_recall_rows`'s form;
    built once, never written)."""

    packed: tuple[weakref.ref, ...]
    slack: np.ndarray
    paths: tuple[np.ndarray, ...]
    rows: np.ndarray


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


def remember(
    checker: ValidityChecker,
    path: np.ndarray,
    slack: float,
    *,
    nodes: int,
    min_nodes: int = MIN_NODES,
) -> None:
    """Keep ``path`` (M, 3) rad, every motion certified for ``checker``, for the checker's
    scene when its search grew ``nodes`` >= ``min_nodes`` tree nodes (:data:`MIN_NODES`, or
    :data:`SPARSE_MIN_NODES` for the search's caller in a sparse scene); ``slack`` (m): the
    extra clearance the joins of later recalls keep."""
    if not checker.obstacles or len(path) < 2:
        return
    if nodes < min_nodes:
        return
    old = _scene(checker)
    if old is None:
        refs = tuple(weakref.ref(a) for a in checker.packed)
        old = _Scene(refs, _slack_params(checker, slack), (), np.empty((0, 3)))
    kept = np.array(path, dtype=float)
    kept.flags.writeable = False
    paths = (*old.paths, kept)[-MAX_PATHS:]
    _CACHE.put(_key(checker), replace(old, paths=paths, rows=_rows(paths)))


def _slack_params(checker: ValidityChecker, slack: float) -> np.ndarray:
    """The checker's kernel parameters with ``slack`` (m) more clearance."""
    margins = replace(checker.margins, clearance=checker.margins.clearance + slack)
    return checker.with_margins(margins).params


def _rows(paths: tuple[np.ndarray, ...]) -> np.ndarray:
    """The paths as one array, each path's rows followed by a NaN row (:class:`_Scene`);
    writable (the one compiled signature of the search and the recall), never written."""
    gap = np.full((1, 3), np.nan)
    return np.ascontiguousarray(np.vstack([row for p in paths for row in (p, gap)]))


def load_kernels(checker: ValidityChecker, path: np.ndarray, slack: float) -> None:
    """Load (or compile) :func:`recall`'s compiled kernel with the array types of a real
    recall, ``path`` (M, 3) a certified path of the checker's scene, nothing remembered:
    the warm-up's step (:mod:`planner.warmup`), so that a process's first walk pays no
    loading."""
    q = np.array(path[0], dtype=float)
    _recall_rows(
        _rows((np.asarray(path, dtype=float),)),
        q,
        q.copy(),
        0.0,
        MAX_TESTS,
        _slack_params(checker, slack),
        tuple(checker.packed),
        checker.coarse_step,
    )


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
    q_start = np.array(q_start, dtype=float)
    q_goal = np.array(q_goal, dtype=float)
    reach = MAX_DETOUR * float(np.linalg.norm(q_goal - q_start))
    ends = _recall_rows(
        scene.rows,
        q_start,
        q_goal,
        reach,
        MAX_TESTS,
        scene.slack,
        tuple(checker.packed),
        checker.coarse_step,
    )
    i, j = int(ends[0]), int(ends[1])
    if i < 0:
        return None
    rows = scene.rows
    walk = rows[i : j + 1] if i <= j else rows[j : i + 1][::-1]
    out = np.vstack([q_start, walk, q_goal])
    keep = np.ones(len(out), dtype=bool)
    keep[1:] = np.any(np.diff(out, axis=0) != 0.0, axis=1)  # no motion of no length
    return out[keep], scene.slack


@njit(cache=True)
def _recall_rows(rows, q_start, q_goal, reach, max_tests, prm, packed, step):  # pragma: no cover
    """:func:`recall`'s choice, compiled (its Python loop over the candidates cost as much as
    the joins' certificates): the rows (entry, exit) of ``rows`` (:class:`_Scene`'s form)
    of the shortest candidate walk whose two joins are certified, or (-1, -1).

    The candidates are every pair of rows (i, j) of one path with the cost ``|start - i| +
    (length along the path between i and j) + |j - goal|`` at most ``reach``, tried in order
    of cost (ties in the order path, i, j: a stable sort); each join (the start's to a row,
    a row's to the goal) is certified once and its verdict kept for every candidate that
    uses it; at most ``max_tests`` joins are certified (a join refused at the posture nearest
    to where the last refused join of its end broke a rule counts as one, certificate
    skipped: :func:`planner.validity.blocked_near`)."""
    m = rows.shape[0]
    cum = np.zeros(m)  # length along its path up to each row
    ds = np.empty(m)
    dg = np.empty(m)
    first = np.empty(m, dtype=np.int64)  # the first row of each row's path
    start = 0
    for r in range(m):
        if np.isnan(rows[r, 0]):
            start = r + 1
            continue
        first[r] = start
        if r > start:
            step2 = 0.0
            for k in range(3):
                step2 += (rows[r, k] - rows[r - 1, k]) ** 2
            cum[r] = cum[r - 1] + math.sqrt(step2)
        a2 = 0.0
        b2 = 0.0
        for k in range(3):
            a2 += (rows[r, k] - q_start[k]) ** 2
            b2 += (rows[r, k] - q_goal[k]) ** 2
        ds[r] = math.sqrt(a2)
        dg[r] = math.sqrt(b2)
    n = 0  # pairs of rows of one path
    for r in range(m):
        if not np.isnan(rows[r, 0]):
            n += 2 * (r - first[r]) + 1  # row r with each earlier row of its path, both ways
    cost = np.empty(n)
    pair = np.empty((n, 2), dtype=np.int64)
    c = 0
    r = 0
    while r < m:  # path by path, i then j in order (the order of ties)
        if np.isnan(rows[r, 0]):
            r += 1
            continue
        end = r
        while end < m and not np.isnan(rows[end, 0]):
            end += 1
        for i in range(r, end):
            for j in range(r, end):
                v = ds[i] + abs(cum[j] - cum[i]) + dg[j]
                if v <= reach:
                    cost[c] = v
                    pair[c, 0], pair[c, 1] = i, j
                    c += 1
        r = end
    order = np.argsort(cost[:c], kind="mergesort")
    joins = np.zeros((2, m), dtype=np.int8)  # 0 not tried, 1 certified, 2 not
    s, cp, b, sn, cn, bn, sg = packed
    # each posture measured once for all its joins (certify_between); a join is probed
    # first near where the last refused join of the same end broke a rule (blocked_near)
    ends = np.empty((2, N_MEASURES))
    measure_posture(q_start, prm, s, cp, b, sn, cn, bn, sg, ends[0])
    measure_posture(q_goal, prm, s, cp, b, sn, cn, bn, sg, ends[1])
    meas = np.empty((m, N_MEASURES))
    measured = np.zeros(m, dtype=np.bool_)
    hint = np.empty((2, 3))
    hinted = np.zeros(2, dtype=np.bool_)
    probe = np.empty(N_MEASURES)
    tests = 0
    for o in order:
        i, j = pair[o, 0], pair[o, 1]
        held = True
        for end_ in range(2):
            v = i if end_ == 0 else j
            if joins[end_, v] == 0:
                if tests >= max_tests:
                    return np.array([-1, -1])
                tests += 1
                row = rows[v]  # a row of the writable rows (_rows): the start's array type
                if not measured[v]:
                    measure_posture(row, prm, s, cp, b, sn, cn, bn, sg, meas[v])
                    measured[v] = True
                qa = q_start if end_ == 0 else row
                qb = row if end_ == 0 else q_goal
                ma = ends[0] if end_ == 0 else meas[v]
                mb = meas[v] if end_ == 0 else ends[1]
                if hinted[end_] and blocked_near(
                    qa, qb, hint[end_], prm, s, cp, b, sn, cn, bn, sg, probe
                ):
                    joins[end_, v] = 2
                else:
                    r_, t = certify_between(
                        qa, qb, ma, mb, prm, s, cp, b, sn, cn, bn, sg, step, MIN_CERTIFIED_STEP
                    )
                    joins[end_, v] = 1 if r_ == 0 else 2
                    if r_ != 0:
                        for k in range(3):
                            hint[end_, k] = qa[k] + t * (qb[k] - qa[k])
                        hinted[end_] = True
            if joins[end_, v] != 1:
                held = False
                break
        if held:
            return np.array([i, j])
    return np.array([-1, -1])


def guide(checker: ValidityChecker) -> np.ndarray:
    """The remembered paths of the checker's scene as one (M, 3) array of their waypoints,
    each path's followed by NaN rows (a break between paths), for a search to sample near
    (:func:`planner.planning.compiled_rrt.rrt_connect`: where a recall found no join, the
    passage the earlier searches found is still there); (0, 3) when nothing is remembered."""
    scene = _scene(checker)
    if scene is None or not scene.paths:
        return np.empty((0, 3))
    return scene.rows
