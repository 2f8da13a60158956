"""RRT-Connect compiled on the product's own validity kernels: the default search of
``PlanOptions.name = "rrtconnect"``.

Why not OMPL's here: with OMPL's Python bindings every state check and every motion check is
a call from C++ into Python and back (in clutter about 70 % of a slow query was those calls:
``checkMotion`` 48 %, the state lambda 22 %; the certificate kernel itself 25 %). This module
runs the same algorithm as OMPL's ``RRTConnect`` (two trees, the one that grew last tries to
connect the other to its new node, extensions at most ``range`` long, Euclidean distance in
joint space) inside one numba function that calls the certificate kernel
(:func:`planner.validity.certify_motion`) directly: no Python between the
samples. The tree is searched for nearest neighbours through a uniform grid of buckets over
the joint box (a 3-D space: a linear scan of a bucket and its neighbours' shells).

What runs where (``docs/planning.md``, "What runs where"): the straight motion, this search,
its simplification (greedy vertex reduction, random shortcuts, vertex reduction again, every
accepted motion certified; :func:`simplify`), a walk along a path remembered in the scene
(:mod:`planner.planning.experience`, tried first where searching was hard before) and the
final re-certification of the path run in compiled code
called from :func:`planner.planning.single_mode.plan_in_region`; OMPL remains the planner of
record for every other ``PlanOptions.name`` (rrt, rrtstar, prmstar, bitstar, aorrtc,
lbkpiece) and for goal sets of several postures (:func:`plan_to_goal_set`, OMPL's
``GoalStates``), and is the fallback when this search stops at its node capacity.

Soundness is the certificate's: a motion enters a tree only when
:meth:`ValidityChecker.check_motion`'s compiled certificate accepts it (ends included), and
the planner re-certifies the returned path as it does OMPL's.

The search runs in chunks of iterations between which the deadline is checked (numba has no
clock): the first chunk has :data:`CHUNK` iterations, the next ones as many as the last chunk's
pace fits in :data:`CHUNK_S` (where one certificate costs a millisecond, a fixed count would
overrun a short budget); its random numbers come from numba's generator seeded with
``options.seed`` at the start of each search: results are reproducible.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np
from numba import njit

from planner.planning import experience, ompl_backend
from planner.planning.ompl_backend import SearchOutcome
from planner.planning.problem import PlanOptions
from planner.validity import (
    MIN_CERTIFIED_STEP,
    N_MEASURES,
    ValidityChecker,
    blocked_near,
    certify_between,
    certify_extension,
    certify_motion,
    measure_posture,
)

__all__ = [
    "CAPACITY",
    "CHUNK",
    "CLUTTER_RANGE",
    "CLUTTER_ROWS",
    "FREE_RANGE",
    "SPARSE_RANGE",
    "rrt_connect",
    "scene_range",
    "search",
    "simplify",
    "walk",
]

#: Iterations of the compiled loop before the first look at the deadline.
CHUNK = 32
#: Seconds of compiled loop aimed at between two looks at the deadline.
CHUNK_S = 0.002
#: Nodes per tree; a search that fills it stops (the caller falls back to OMPL).
CAPACITY = 1 << 15
#: Random shortcut tries of the simplification: a * (vertices after the first reduction) + b.
#: Measured in the narrow window (30 queries, mean): the shortcuts cost 7.3 ms at 4n + 16
#: (every success certifies a motion that grazes the plate, in fine pieces), 3.7 ms at
#: 2n + 8, for paths 4.00 and 4.16 rad long (median; 4.64 after the reduction alone).
SHORTCUT_TRIES = (2, 8)
#: Shortcut tries (as :data:`SHORTCUT_TRIES`) of the simplification of a path walked from
#: :mod:`planner.planning.experience` (its two joins and a remembered path, simplified
#: before). Measured in the narrow window (40 queries, CPU time of the whole plan, load 4-5):
#: none: p50 1.0 ms, but the paths that walk a remembered one 1.6x longer (7-9 rad);
#: n + 4: p50 1.55 ms, median length 4.46 rad; 2n + 8: 2.0 ms, 4.45 rad; without remembered
#: paths 3.6 ms, 4.50 rad.
RECALL_SHORTCUT_TRIES = (1, 4)
#: Least gain of a random shortcut, a share of the path's length: a shortcut that would
#: shorten the path by less is not certified. Half of the accepted shortcuts among the 1,000
#: spheres (query seed 23) gained under 0.17 % of their path and cost a certificate of ~80 us
#: each (a long motion in clutter). Measured on the fair scenes (40 queries, the product's
#: ``plan`` alone in one process, two runs each, CPU p50 / p95 ms, mean length rad; 0 -> 0.3 %):
#: 1,000 spheres seed 23 1.31-1.39 / 9.6-9.9, 1.635 -> 1.20-1.33 / 8.9-9.1, 1.643; seed 11
#: 0.35-0.39 / 3.6-3.8, 1.425 -> 0.35-0.38 / 2.9-3.1, 1.430; window seed 11 0.84-0.88 / 2.1,
#: 4.596 -> 0.74-0.79 / 2.2-2.4, 4.603; seed 23 0.85-0.86 / 2.0-2.1, 5.063 -> 0.77-0.78 / 2.0,
#: 5.066 (0.5 %: as fast, paths up to 0.7 % longer on average).
SHORTCUT_MIN_GAIN = 0.003
#: Clearance (m) that the simplification's new motions keep beyond ``margins.clearance``:
#: a shortcut may replace tree motions only where it stays this much clear of the margin, so
#: that a timed trajectory rounding the path's corners (which cut towards the obstacle they
#: turn around) is not pushed into the margin by a path that hugs it (the service's ruckig
#: plan of ``tests/test_plan_checker.py`` came within 0.9 mm of the margin without it).
SIMPLIFY_SLACK = 0.005
#: Share of the search's samples drawn near the scene's remembered paths, where it has some
#: (:func:`planner.planning.experience.guide`): a recall that found no join still knows
#: where earlier searches found the passage.
GUIDE_SHARE = 0.5
#: Standard deviation (rad, per joint) of a guided sample about its point of a remembered
#: path.
GUIDE_SPREAD = 0.05
#: Buckets per axis of the nearest-neighbour grid.
_BUCKETS = 16
#: Obstacle rows (spheres, points, capsules, boxes) from which :func:`scene_range` is short.
CLUTTER_ROWS = 50
#: :func:`scene_range` without obstacles, with fewer than :data:`CLUTTER_ROWS` rows, and in
#: clutter (rad).
FREE_RANGE, SPARSE_RANGE, CLUTTER_RANGE = 1.0, 0.6, 0.25
#: Up to this many nodes a tree is scanned whole for a nearest neighbour.
_SCAN = 48


def scene_range(checker: ValidityChecker) -> float:
    """The extension length (rad) chosen from the scene when ``options.range`` is None.

    :data:`FREE_RANGE` (1.0 rad) without obstacles (long extensions reach the goal in few
    steps), :data:`SPARSE_RANGE` (0.6 rad) with obstacles, :data:`CLUTTER_RANGE` (0.25 rad)
    from :data:`CLUTTER_ROWS` obstacle rows (the 1,000 small spheres, point clouds: every
    point is a row). Measured on the fair scenes (the compiled search alone, 30 queries each,
    AMD EPYC, load 3-7):

    ========== ================ ================ ================
    scene      range 0.25       range 0.5        range 1.0
    ========== ================ ================ ================
    1k spheres p50 0.42-0.54 ms  0.56 ms          3.82 ms
               p95 12.5-15.2 ms 24.2 ms          49.7 ms
    cloud 10k  p50 0.35-0.44 ms  0.38 ms          0.38 ms
               p95 1.1-7.5 ms   1.01 ms          1.52 ms
    narrow     p50 5.2-5.5 ms   3.61 ms          3.89 ms
    ========== ================ ================ ================

    In clutter, a long extension is mostly rejected deep inside (the certificate pays its
    coarse samples up to the first invalid one) and the trees grow slowly. With few
    obstacles, run J (docs/planning.md; the search and its simplification, CPU time per
    query, every query of the fair table that is not a straight motion, 6 seeds each, both
    query sets): narrow window p50 / p95 1.69 / 5.81 ms at 1.0, 1.50 / 4.26 at 0.6, 1.88 /
    4.39 at 0.5 (query seed 11); 2.28 / 12.6, 1.90 / 3.59, 2.01 / 4.19 (seed 23), the paths
    no longer; 5 spheres 0.31-0.45 ms at every range from 0.5 to 1.0. Among the 1,000
    spheres 0.3-0.4 were no better than 0.25 on both sets."""
    if not checker.obstacles:
        return FREE_RANGE
    return CLUTTER_RANGE if _in_clutter(checker) else SPARSE_RANGE


def _in_clutter(checker: ValidityChecker) -> bool:
    """Whether the scene has :data:`CLUTTER_ROWS` obstacle rows or more: the short range
    (:func:`scene_range`) and the memory's higher threshold (:func:`search`)."""
    return checker.packed.count >= CLUTTER_ROWS


@njit(cache=True)
def _seed(seed):  # pragma: no cover - compiled
    np.random.seed(seed)  # noqa: NPY002 (numba: the legacy API)


@njit(cache=True, inline="always")
def _bucket(q, lo, inv):  # pragma: no cover - compiled
    b0 = min(_BUCKETS - 1, max(0, int((q[0] - lo[0]) * inv[0])))
    b1 = min(_BUCKETS - 1, max(0, int((q[1] - lo[1]) * inv[1])))
    b2 = min(_BUCKETS - 1, max(0, int((q[2] - lo[2]) * inv[2])))
    return b0, b1, b2


@njit(cache=True)
def _insert(t, q, m, par, nodes, meas, parent, count, head, nxt, lo, inv):  # pragma: no cover
    """Add node q, its measures m (the certificate's, kept in ``meas`` for the motions that
    leave it), with parent ``par`` to tree t (its bucket list); returns its index."""
    i = count[t]
    nodes[t, i, 0], nodes[t, i, 1], nodes[t, i, 2] = q[0], q[1], q[2]
    meas[t, i] = m
    parent[t, i] = par
    b0, b1, b2 = _bucket(q, lo, inv)
    nxt[t, i] = head[t, b0, b1, b2]
    head[t, b0, b1, b2] = i
    count[t] = i + 1
    return i


@njit(cache=True)
def _nearest(t, q, nodes, count, head, nxt, lo, inv, width):  # pragma: no cover - compiled
    """Index of the node of tree t nearest to q (Euclidean): shells of buckets around q's
    bucket, growing until the best distance found is within the shell's reach."""
    best, bd = -1, np.inf
    if count[t] <= _SCAN:  # a small tree: a plain scan is cheaper than the shells
        for i in range(count[t]):
            d = (
                (nodes[t, i, 0] - q[0]) ** 2
                + (nodes[t, i, 1] - q[1]) ** 2
                + (nodes[t, i, 2] - q[2]) ** 2
            )
            if d < bd:
                best, bd = i, d
        return best
    c0, c1, c2 = _bucket(q, lo, inv)
    wmin = min(width[0], min(width[1], width[2]))
    for r in range(_BUCKETS):
        # nodes outside the shells 0..r-1 are at least (r - 1) * wmin away: stop when the
        # best is nearer than the closest a node in shell r can be
        if best >= 0 and bd <= ((r - 1) * wmin) ** 2 and r > 0:
            break
        for a in range(max(0, c0 - r), min(_BUCKETS, c0 + r + 1)):
            for b in range(max(0, c1 - r), min(_BUCKETS, c1 + r + 1)):
                for c in range(max(0, c2 - r), min(_BUCKETS, c2 + r + 1)):
                    if max(abs(a - c0), max(abs(b - c1), abs(c - c2))) != r:
                        continue
                    i = head[t, a, b, c]
                    while i >= 0:
                        d = (
                            (nodes[t, i, 0] - q[0]) ** 2
                            + (nodes[t, i, 1] - q[1]) ** 2
                            + (nodes[t, i, 2] - q[2]) ** 2
                        )
                        if d < bd:
                            best, bd = i, d
                        i = nxt[t, i]
    return best


@njit(cache=True)
def _grow(
    t, target, nodes, meas, parent, count, head, nxt, lo, inv, width, rng, prm, packed, step, mb
):  # pragma: no cover - compiled
    """OMPL's ``growTree``: extend tree t from its node nearest to ``target`` by at most
    ``rng``; returns (status, new node): 0 trapped, 1 advanced, 2 reached. ``mb`` is
    scratch for the new posture's measures."""
    near = _nearest(t, target, nodes, count, head, nxt, lo, inv, width)
    qa = nodes[t, near]
    d = math.sqrt((target[0] - qa[0]) ** 2 + (target[1] - qa[1]) ** 2 + (target[2] - qa[2]) ** 2)
    reach = d <= rng
    qb = target.copy() if reach else qa + (target - qa) * (rng / d)
    if count[t] >= nodes.shape[1]:
        return 0, -1
    s, c, b, sn, cn, bn, sg = packed
    ma = meas[t, near]
    r = certify_extension(
        qa.copy(), qb, ma, mb, prm, s, c, b, sn, cn, bn, sg, step, MIN_CERTIFIED_STEP
    )
    if r != 0:
        return 0, -1
    i = _insert(t, qb, mb, near, nodes, meas, parent, count, head, nxt, lo, inv)
    return (2 if reach else 1), i


@njit(cache=True, inline="always")
def _sample(target, lo, hi, guide):  # pragma: no cover - compiled
    """A random posture of the joint box into ``target``: with probability
    :data:`GUIDE_SHARE`, where ``guide`` holds remembered paths (rows, NaN rows between
    paths), a uniform point of one of their motions moved by a normal step of
    :data:`GUIDE_SPREAD` per joint (clipped to the box); else uniform in the box (the same
    draws as with no guide, so a search without one is unchanged)."""
    m = guide.shape[0]
    if m >= 2 and np.random.random() < GUIDE_SHARE:  # noqa: NPY002 (numba: the legacy API)
        i = np.random.randint(0, m - 1)  # noqa: NPY002 (numba: the legacy API)
        if np.isfinite(guide[i, 0]) and np.isfinite(guide[i + 1, 0]):
            u = np.random.random()  # noqa: NPY002 (numba: the legacy API)
            for k in range(3):
                v = guide[i, k] + u * (guide[i + 1, k] - guide[i, k])
                v += np.random.normal(0.0, GUIDE_SPREAD)  # noqa: NPY002 (numba: the legacy API)
                target[k] = min(hi[k], max(lo[k], v))
            return
    for k in range(3):
        target[k] = lo[k] + np.random.random() * (hi[k] - lo[k])  # noqa: NPY002 (numba: the legacy API)


@njit(cache=True)
def _run(
    nodes,
    meas,
    parent,
    count,
    head,
    nxt,
    lo,
    hi,
    width,
    rng,
    prm,
    packed,
    step,
    guide,
    iters,
    state,
    out,
):  # pragma: no cover - compiled
    """``iters`` iterations of RRT-Connect, its targets drawn by :func:`_sample`;
    ``state[0]`` the tree that grows next. Returns True with ``out`` = (node in tree 0, node
    in tree 1) when the trees met; ``state[1]`` = 1 when a tree is full."""
    inv = 1.0 / width
    target = np.empty(3)
    mb = np.empty(N_MEASURES)
    for _ in range(iters):
        t = state[0]
        o = 1 - t
        state[0] = o
        _sample(target, lo, hi, guide)
        st, i = _grow(
            t,
            target,
            nodes,
            meas,
            parent,
            count,
            head,
            nxt,
            lo,
            inv,
            width,
            rng,
            prm,
            packed,
            step,
            mb,
        )
        if count[t] >= nodes.shape[1]:
            state[1] = 1
            return False
        if st == 0:
            continue
        q_new = nodes[t, i].copy()
        while True:
            st2, j = _grow(
                o,
                q_new,
                nodes,
                meas,
                parent,
                count,
                head,
                nxt,
                lo,
                inv,
                width,
                rng,
                prm,
                packed,
                step,
                mb,
            )
            if st2 != 1:
                break
        if st2 == 2:
            if t == 0:
                out[0], out[1] = i, j
            else:
                out[0], out[1] = j, i
            return True
        if count[o] >= nodes.shape[1]:
            state[1] = 1
            return False
    return False


@njit(cache=True)
def _valid(qa, qb, prm, packed, step):  # pragma: no cover - compiled
    s, c, b, sn, cn, bn, sg = packed
    r, _ = certify_motion(qa, qb, prm, s, c, b, sn, cn, bn, sg, step, MIN_CERTIFIED_STEP, False)
    return r == 0


@njit(cache=True)
def _reduce(path, known, prm, packed, step):  # pragma: no cover - compiled
    """Greedy vertex reduction: from each kept vertex, the farthest later vertex joined to it
    by a certified motion (the next one always is: the path's own motion). A pair of
    vertices both marked in ``known`` is known not to be joined (:func:`_simplify`) and is
    not certified again; each vertex is measured once for all the motions tried from and to
    it (:func:`planner.validity.certify_between`); a motion is probed first where it passes
    nearest to the posture the last refused motion from the same vertex broke at
    (:func:`planner.validity.blocked_near`)."""
    n = path.shape[0]
    s, c, b, sn, cn, bn, sg = packed
    meas = np.empty((n, N_MEASURES))
    measured = np.zeros(n, dtype=np.bool_)
    keep = np.zeros(n, dtype=np.bool_)
    keep[0] = True
    hint = np.empty(3)
    probe = np.empty(N_MEASURES)
    i = 0
    while i < n - 1:
        j = n - 1
        hinted = False
        while j > i + 1:
            if not (known[i] and known[j]):
                qa, qb = path[i], path[j]
                if hinted and blocked_near(qa, qb, hint, prm, s, c, b, sn, cn, bn, sg, probe):
                    j -= 1
                    continue
                for v in (i, j):
                    if not measured[v]:
                        measure_posture(path[v], prm, s, c, b, sn, cn, bn, sg, meas[v])
                        measured[v] = True
                r, t = certify_between(
                    qa, qb, meas[i], meas[j], prm, s, c, b, sn, cn, bn, sg, step, MIN_CERTIFIED_STEP
                )
                if r == 0:
                    break
                for k in range(3):
                    hint[k] = qa[k] + t * (qb[k] - qa[k])
                hinted = True
            j -= 1
        keep[j] = True
        i = j
    return path[keep]


@njit(cache=True)
def _shortcut(path, tries, min_gain, prm, packed, step):  # pragma: no cover - compiled
    """Random shortcuts between two points on two different motions of the path (OMPL's
    ``shortcutPath`` idea): when the straight motion between them would shorten the path by
    at least ``min_gain`` of its length (:data:`SHORTCUT_MIN_GAIN`) and is certified, the
    path between them is replaced by it. Returns the path and, per vertex, whether it is one
    of the given path's (the shortcuts' new vertices are not)."""
    p = path.copy()
    old = np.ones(p.shape[0], dtype=np.bool_)
    for _ in range(tries):
        n = p.shape[0]
        if n < 3:
            break
        a = np.random.randint(0, n - 1)  # noqa: NPY002 (numba: the legacy API)
        b = np.random.randint(0, n - 1)  # noqa: NPY002 (numba: the legacy API)
        if a == b:
            continue
        if a > b:
            a, b = b, a
        ta, tb = np.random.random(), np.random.random()  # noqa: NPY002 (numba: the legacy API)
        qa = p[a] + ta * (p[a + 1] - p[a])
        qb = p[b] + tb * (p[b + 1] - p[b])
        old_len = np.sqrt(np.sum((p[a + 1] - qa) ** 2)) + np.sqrt(np.sum((qb - p[b]) ** 2))
        for k in range(a + 1, b):
            old_len += np.sqrt(np.sum((p[k + 1] - p[k]) ** 2))
        total = 0.0
        for k in range(n - 1):
            total += np.sqrt(np.sum((p[k + 1] - p[k]) ** 2))
        if np.sqrt(np.sum((qb - qa) ** 2)) >= old_len - max(1e-9, min_gain * total):
            continue
        if not _valid(qa.copy(), qb.copy(), prm, packed, step):
            continue
        m = a + 1 + 2 + (n - b - 1)
        q = np.empty((m, 3))
        q[: a + 1] = p[: a + 1]
        q[a + 1] = qa
        q[a + 2] = qb
        q[a + 3 :] = p[b + 1 :]
        kept = np.empty(m, dtype=np.bool_)
        kept[: a + 1] = old[: a + 1]
        kept[a + 1] = False
        kept[a + 2] = False
        kept[a + 3 :] = old[b + 1 :]
        p, old = q, kept
    return p, old


@njit(cache=True)
def _simplify(path, known, tries_a, tries_b, min_gain, prm, packed, step):  # pragma: no cover
    """:func:`simplify`'s work in one compiled call, ``known`` the vertices whose pairs the
    first reduction need not certify (:func:`_reduce`). The second reduction certifies only
    pairs with a shortcut's new vertex: two vertices of the first reduction's path that are
    not neighbours there were tried by it (from the earlier one, every later vertex beyond
    the one it kept) and not joined, the motion's certificate being deterministic; and a
    shortcut replaces a run of vertices by two new ones, so two old vertices are neighbours
    after the shortcuts only where they were before."""
    path = _reduce(path, known, prm, packed, step)
    count = tries_a * path.shape[0] + tries_b
    if count > 0:
        path, old = _shortcut(path, count, min_gain, prm, packed, step)
        path = _reduce(path, old, prm, packed, step)
    return path


def simplify(
    path: np.ndarray,
    checker: ValidityChecker,
    slack: np.ndarray,
    tries: tuple[int, int],
    *,
    reduced_inside: bool = False,
) -> np.ndarray:
    """The simplification of a found path (N, 3) rad, every new motion certified with the
    kernels' parameters ``slack`` (the checker's with :data:`SIMPLIFY_SLACK` more
    clearance): greedy vertex reduction, then ``tries[0] * n + tries[1]`` random shortcuts
    (n the vertices left; none when both are 0) and the reduction again (:func:`_simplify`).
    ``reduced_inside``: the path's vertices but its ends are a simplified path's (a walk:
    two joins onto a remembered path), whose last reduction with the same ``slack`` tried
    every pair of them that are not neighbours and joined none; the first reduction does
    not certify those pairs again (the same verdicts but where a pair's certificate would
    not be that of the reversed motion, which only keeps a vertex more: every kept motion
    is still certified)."""
    if len(path) <= 2:
        return path
    known = np.zeros(len(path), dtype=np.bool_)
    if reduced_inside:
        known[1:-1] = True
    packed, step = tuple(checker.packed), checker.coarse_step
    return _simplify(path, known, tries[0], tries[1], SHORTCUT_MIN_GAIN, slack, packed, step)


def _path(nodes: np.ndarray, parent: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """The waypoints root of tree 0 -> meeting node -> root of tree 1."""
    out = []
    for t in (0, 1):
        i, part = int(ends[t]), []
        while i >= 0:
            part.append(nodes[t, i].copy())
            i = int(parent[t, i])
        out.append(part[::-1] if t == 0 else part)
    assert np.array_equal(out[0][-1], out[1][0])  # the trees met on one posture
    return np.array(out[0] + out[1][1:])


def walk(
    checker: ValidityChecker, q_start: np.ndarray, q_goal: np.ndarray, options: PlanOptions
) -> SearchOutcome | None:
    """A path ``q_start`` -> ``q_goal`` (3,) rad along a path remembered in the checker's scene
    (:func:`planner.planning.experience.recall`), simplified with
    :data:`RECALL_SHORTCUT_TRIES`, every motion certified; None when the search is not the
    compiled ``rrtconnect`` with ``options.simplify`` (the raw search never walks), nothing is
    remembered, or no join holds. A walk is a path: the planner tries it before asking the
    region map's proofs (:func:`planner.planning.single_mode.plan_in_region`)."""
    if options.name != "rrtconnect" or not options.simplify:
        return None
    remembered = experience.recall(checker, q_start, q_goal)
    if remembered is None:
        return None
    path, slack = remembered
    _seed(options.seed)
    path = simplify(path, checker, slack, RECALL_SHORTCUT_TRIES, reduced_inside=True)
    return SearchOutcome(path, True, "Exact solution", True, certified=True)


def search(
    checker: ValidityChecker,
    q_start: np.ndarray,
    q_goal: np.ndarray,
    options: PlanOptions,
    time_budget_s: float,
    *,
    walked: bool = False,
) -> SearchOutcome:
    """The product's search (what the planner calls): :func:`rrt_connect` for
    ``options.name == "rrtconnect"`` and one goal posture, OMPL
    (:func:`planner.planning.ompl_backend.search`) for every other planner, for a goal set
    (K, 3) with K > 1, and for the rest of the budget when the compiled trees fill up.

    With ``options.simplify`` (the default), in a scene where a search was hard before, a
    remembered path is tried first (:func:`walk`; not again when the caller tried it:
    ``walked``); the compiled search's simplified path is offered to
    :func:`planner.planning.experience.remember`."""
    goals = np.asarray(q_goal, dtype=float).reshape(-1, 3)
    t0 = time.monotonic()
    if options.name == "rrtconnect" and len(goals) == 1:
        walked_path = None if walked else walk(checker, q_start, goals[0], options)
        if walked_path is not None:
            return walked_path
        out = rrt_connect(checker, q_start, goals[0], options, time_budget_s)
        if out is not None:
            if out.waypoints is not None and out.simplified:
                clutter = _in_clutter(checker)
                hard = experience.MIN_NODES if clutter else experience.SPARSE_MIN_NODES
                experience.remember(
                    checker, out.waypoints, SIMPLIFY_SLACK, nodes=out.nodes, min_nodes=hard
                )
            return out
    rest = time_budget_s - (time.monotonic() - t0)
    return ompl_backend.search(checker, q_start, q_goal, options, max(rest, 1e-3))


def rrt_connect(
    checker: ValidityChecker,
    q_start: np.ndarray,
    q_goal: np.ndarray,
    options: PlanOptions,
    time_budget_s: float,
) -> SearchOutcome | None:
    """RRT-Connect from ``q_start`` to ``q_goal`` (3,) rad in the checker's region, compiled;
    None when the trees filled their :data:`CAPACITY` (the caller then asks OMPL). The
    outcome's ``ompl_status`` is OMPL's vocabulary ("Exact solution" / "Timeout") so that
    messages read the same."""
    design = checker.design
    lo = np.asarray(design.joint_min, dtype=float)
    hi = np.asarray(design.joint_max, dtype=float)
    width = (hi - lo) / _BUCKETS
    rng = options.range if options.range is not None else scene_range(checker)
    nodes = np.empty((2, CAPACITY, 3))
    meas = np.empty((2, CAPACITY, N_MEASURES))  # the nodes' measures (certify_extension)
    parent = np.empty((2, CAPACITY), dtype=np.int64)
    nxt = np.empty((2, CAPACITY), dtype=np.int64)
    head = np.full((2, _BUCKETS, _BUCKETS, _BUCKETS), -1, dtype=np.int64)
    count = np.zeros(2, dtype=np.int64)
    inv = 1.0 / width
    prm, packed, step = checker.params, tuple(checker.packed), checker.coarse_step
    sph, cap, box, sph_n, cap_n, box_n, grid = packed
    for t, q in enumerate((q_start, q_goal)):  # the roots, measured for certify_extension
        root, m = np.array(q, dtype=float), np.empty(N_MEASURES)
        measure_posture(root, prm, sph, cap, box, sph_n, cap_n, box_n, grid, m)
        _insert(t, root, m, -1, nodes, meas, parent, count, head, nxt, lo, inv)
    state = np.zeros(2, dtype=np.int64)
    ends = np.zeros(2, dtype=np.int64)
    _seed(options.seed)
    # A process's first search loads the compiled kernels from numba's cache (a second or
    # more, cold): a call of no iteration pays that before the deadline starts, so that a
    # cold process finds the path a warm one finds (a first try's short budget is the
    # search's, not the loading's; tests/cli/test_cli_plan.py compares the two)
    # the remembered paths of the scene guide part of the samples (experience.guide)
    guide = experience.guide(checker) if options.simplify else np.empty((0, 3))

    def run(iters: int) -> bool:  # ``iters`` iterations of the compiled search
        return bool(
            _run(
                nodes,
                meas,
                parent,
                count,
                head,
                nxt,
                lo,
                hi,
                width,
                rng,
                prm,
                packed,
                step,
                guide,
                iters,
                state,
                ends,
            )
        )

    run(0)
    deadline = time.monotonic() + time_budget_s
    found = False
    iters = CHUNK
    while (now := time.monotonic()) < deadline:
        found = run(iters)
        spent = time.monotonic() - now
        iters = max(1, min(4096, int(iters * CHUNK_S / max(spent, 1e-6))))
        if found or state[1]:
            break
    grown = int(count.sum())
    if not found:
        return None if state[1] else SearchOutcome(None, False, "Timeout", False, nodes=grown)
    path = _path(nodes, parent, ends)
    simplified = False
    if options.simplify and len(path) > 2:
        margins = replace(checker.margins, clearance=checker.margins.clearance + SIMPLIFY_SLACK)
        path = simplify(path, checker, checker.with_margins(margins).params, SHORTCUT_TRIES)
        simplified = True
    # every motion of the path is certified: tree edges when they were grown (the meeting
    # node is the same posture in both trees), and every motion the simplification kept
    return SearchOutcome(path, True, "Exact solution", simplified, certified=True, nodes=grown)
