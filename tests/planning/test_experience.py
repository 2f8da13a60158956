"""Paths remembered per scene (planner.planning.experience): a recalled path is valid by an
independent dense check of every posture, only hard searches start a scene's memory, a
memory serves only the scene (arrays, modes) it was made in, and the search walks it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planner import Design, caching
from planner.geometry import Box
from planner.planning import PlanOptions, compiled_rrt, corridor, experience
from planner.validity import Margins, ValidityChecker, densify

NARROW = Design(0.5, 0.2, 0.6, joint_min=(-2.0, -np.pi, -np.pi), joint_max=(2.0, np.pi, np.pi))


def window(dy: float = 0.0) -> list[Box]:
    """The benchmark's narrow scene: a plate |z| <= 0.01, x in [0.05, 1.3], |y| <= 1.3 with
    a window x < 0.45, |y| < 0.3 (moved by ``dy`` along y)."""
    x0, x1, y1, hx, hy, t = 0.05, 1.3, 1.3, 0.45, 0.3, 0.02
    return [
        Box([(x0 + x1) / 2, dy - (hy + y1) / 2, 0.0], [x1 - x0, y1 - hy, t]),
        Box([(x0 + x1) / 2, dy + (hy + y1) / 2, 0.0], [x1 - x0, y1 - hy, t]),
        Box([(hx + x1) / 2, dy, 0.0], [x1 - hx, 2 * hy, t]),
    ]


@pytest.fixture(autouse=True)
def _fresh_memory():
    caching.clear("experience")
    yield
    caching.clear("experience")


@pytest.fixture(scope="module")
def scene() -> tuple[ValidityChecker, list[tuple[np.ndarray, np.ndarray]]]:
    """The window scene in mode +-+ and seeded pairs theta1 > 0.3 -> theta1 < -0.3 whose
    straight motion is not valid (the arm must pass the window), both ends in the one
    component of the corridor grid that holds most marked cells (the grid only picks them)."""
    checker = ValidityChecker(NARROW, Margins(), window(), "+", "+-+")
    grid = corridor.corridor_grid(checker)
    main = np.argmax(np.bincount(grid.labels.ravel())[1:]) + 1
    rng = np.random.default_rng(5)
    q = rng.uniform(NARROW.joint_min, NARROW.joint_max, (4000, 3))
    q[:2000, 0] = rng.uniform(0.3, 1.8, 2000)
    q[2000:, 0] = rng.uniform(-1.8, -0.3, 2000)
    ok = checker.is_valid(q) & np.array([grid.labels[tuple(grid.cell_of(x))] == main for x in q])
    a, b = q[:2000][ok[:2000]], q[2000:][ok[2000:]]
    pairs = [(s, g) for s, g in zip(a, b, strict=False) if not checker.motion_valid(s, g)]
    caching.clear("corridor")  # the grid only picked the pairs: no later plan finds it
    return checker, pairs[:12]


def _remember_one(checker: ValidityChecker, q_start, q_goal) -> np.ndarray:
    out = compiled_rrt.rrt_connect(checker, q_start, q_goal, PlanOptions(seed=2), 2.0)
    assert out is not None and out.waypoints is not None
    experience.remember(
        checker, out.waypoints, compiled_rrt.SIMPLIFY_SLACK, nodes=experience.MIN_NODES
    )
    return out.waypoints


def test_a_recalled_path_is_valid_by_a_dense_independent_check(scene) -> None:
    checker, pairs = scene
    _remember_one(checker, *pairs[0])
    hits = 0
    for q_start, q_goal in pairs[1:]:
        got = experience.recall(checker, q_start, q_goal)
        if got is None:
            continue
        hits += 1
        w, _ = got
        np.testing.assert_array_equal(w[0], q_start)
        np.testing.assert_array_equal(w[-1], q_goal)
        # every posture every 0.5 mrad valid by the per-posture report (not the certificate)
        assert checker.check_states(densify(w, 5e-4)).valid.all()
        assert w[:, 0].max() > 0 > w[:, 0].min()  # through the window
    assert hits >= 2


def test_an_easy_search_starts_no_memory(scene) -> None:
    checker, pairs = scene
    path = np.stack(pairs[0])  # any path: it is not kept
    experience.remember(checker, path, 0.005, nodes=experience.MIN_NODES - 1)
    assert experience.recall(checker, *pairs[0]) is None


def test_a_sparse_scene_remembers_from_fewer_nodes(scene) -> None:
    """With few obstacles (the window's three boxes, range 0.6 rad) a search of
    SPARSE_MIN_NODES to MIN_NODES nodes is hard enough to remember; one of fewer is not."""
    checker, pairs = scene
    assert checker.packed.count < compiled_rrt.CLUTTER_ROWS
    easy = compiled_rrt.search(checker, *pairs[0], PlanOptions(seed=2), 2.0)
    assert easy.nodes < experience.SPARSE_MIN_NODES
    assert experience.guide(checker).shape[0] == 0
    hard = compiled_rrt.search(checker, *pairs[0], PlanOptions(seed=1), 2.0)
    assert experience.SPARSE_MIN_NODES <= hard.nodes < experience.MIN_NODES
    kept = experience.guide(checker)
    np.testing.assert_array_equal(kept[:-1], hard.waypoints)  # its path, then a NaN row


def test_a_memory_serves_only_its_own_scene(scene) -> None:
    checker, pairs = scene
    q_start, q_goal = pairs[0]
    _remember_one(checker, q_start, q_goal)
    assert experience.recall(checker, q_start, q_goal) is not None
    moved = ValidityChecker(NARROW, Margins(), window(dy=0.05), "+", "+-+")
    assert experience.recall(moved, q_start, q_goal) is None
    assert experience.recall(checker.with_mode("+--"), q_start, q_goal) is None
    wider = checker.with_margins(Margins(clearance=0.02))
    assert experience.recall(wider, q_start, q_goal) is None


def test_the_search_walks_a_remembered_path_reproducibly(scene) -> None:
    checker, pairs = scene
    _remember_one(checker, *pairs[0])
    walked = []
    for q_start, q_goal in pairs[1:]:
        if experience.recall(checker, q_start, q_goal) is None:
            continue
        runs = [
            compiled_rrt.search(checker, q_start, q_goal, PlanOptions(seed=4), 1.0)
            for _ in range(2)
        ]
        for out in runs:
            assert out.waypoints is not None and out.certified and out.nodes == 0
            assert checker.check_path(out.waypoints).valid
        np.testing.assert_array_equal(runs[0].waypoints, runs[1].waypoints)
        # the raw search neither walks nor fills the memory
        raw = compiled_rrt.search(
            checker, q_start, q_goal, PlanOptions(seed=4, simplify=False), 1.0
        )
        assert raw.waypoints is not None and raw.nodes > 0
        walked.append(q_start)
    assert walked


def test_a_walks_simplification_skips_only_the_remembered_pairs(scene) -> None:
    """A walk's first reduction leaves out the pairs of the remembered path's vertices (its
    last reduction tried them and joined none): the walks' simplified paths are those of
    the simplification that certifies every pair."""
    checker, pairs = scene
    kept = _remember_one(checker, *pairs[0])
    tries = compiled_rrt.RECALL_SHORTCUT_TRIES

    def both(path: np.ndarray, slack: np.ndarray) -> list[np.ndarray]:
        out = []
        for reduced_inside in (True, False):
            compiled_rrt._seed(3)
            out.append(
                compiled_rrt.simplify(path, checker, slack, tries, reduced_inside=reduced_inside)
            )
        np.testing.assert_array_equal(out[0], out[1])
        return out

    compared = 0
    for q_start, q_goal in pairs[1:]:
        got = experience.recall(checker, q_start, q_goal)
        if got is None:
            continue
        path, slack = got
        assert len(path) >= 4  # two joins and at least two remembered vertices
        both(path, slack)
        compared += 1
    assert compared >= 2
    # joins that a reduction shortens (the ends on the remembered path's first and last
    # motions): the ends' pairs are still certified
    assert len(kept) >= 3
    ends = (kept[0] + kept[1]) / 2, (kept[-2] + kept[-1]) / 2
    path = np.vstack([ends[0], kept, ends[1]])
    out = both(path, experience._scene(checker).slack)[0]
    assert len(out) < len(path)
    np.testing.assert_array_equal(out[0], ends[0])
    assert not any(np.array_equal(v, kept[0]) for v in out)


def test_a_search_that_walks_nothing_samples_near_the_remembered_paths(scene) -> None:
    """Where no join to a remembered path holds, the search still draws part of its samples
    near the remembered paths (experience.guide): it finds the window with fewer nodes than
    the same seeded search without a memory, every path valid by the dense check."""
    checker, pairs = scene
    kept = _remember_one(checker, *pairs[0])
    guide = experience.guide(checker)
    np.testing.assert_array_equal(guide[: len(kept)], kept)
    assert np.isnan(guide[len(kept)]).all()  # a break after each path
    misses = [p for p in pairs[1:] if experience.recall(checker, *p) is None]
    misses += pairs[1:5]  # and some that could walk: the search itself is what is compared
    nodes = {True: 0, False: 0}
    for guided in (True, False):
        if not guided:
            caching.clear("experience")
        for q_start, q_goal in misses:
            out = compiled_rrt.rrt_connect(checker, q_start, q_goal, PlanOptions(seed=3), 2.0)
            assert out is not None and out.waypoints is not None
            assert checker.check_states(densify(out.waypoints, 5e-4)).valid.all()
            nodes[guided] += out.nodes
    assert nodes[True] < 0.7 * nodes[False], nodes


def test_a_walk_needs_no_compiled_signature_of_its_own(scene) -> None:
    """The walk certifies its joins with the search's array types (the remembered rows are
    read-only: a read-only posture made numba load or compile a second certificate, 20 ms
    for a process's first walk from the cache, seconds without it)."""
    from planner.validity import certify_motion

    checker, pairs = scene
    _remember_one(checker, *pairs[0])
    before = set(certify_motion.signatures)
    walked = [compiled_rrt.walk(checker, s, g, PlanOptions()) for s, g in pairs[1:]]
    assert any(w is not None for w in walked)
    assert set(certify_motion.signatures) == before


def _recall_reference(
    checker: ValidityChecker, q_start: np.ndarray, q_goal: np.ndarray
) -> np.ndarray | None:
    """The recall's rule written plainly in numpy (the module's first, Python version): the
    candidates (path, entry i, exit j) by start -> P[i] -> along P -> P[j] -> goal within
    MAX_DETOUR x the straight distance, shortest first (ties by path, i, j), each join
    certified once by the checker with the slack, at most MAX_TESTS joins."""
    scene = experience._scene(checker)
    if scene is None:
        return None
    rows = []
    for p, path in enumerate(scene.paths):
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
        ds = np.linalg.norm(path - q_start, axis=1)
        dg = np.linalg.norm(path - q_goal, axis=1)
        cost = ds[:, None] + np.abs(cum[None, :] - cum[:, None]) + dg[None, :]
        i, j = np.indices(cost.shape)
        rows.append(np.stack([cost.ravel(), np.full(cost.size, p), i.ravel(), j.ravel()], 1))
    order = np.concatenate(rows)
    order = order[order[:, 0] <= experience.MAX_DETOUR * float(np.linalg.norm(q_goal - q_start))]
    order = order[np.argsort(order[:, 0], kind="stable")]
    slack = replace(checker.margins, clearance=checker.margins.clearance + 0.005)
    joining = checker.with_margins(slack)
    joins: dict[tuple[int, int, int], bool] = {}
    for _, p, i, j in order:
        p, i, j = int(p), int(i), int(j)
        path = scene.paths[p]
        for end, v in ((0, i), (1, j)):
            if (end, p, v) not in joins:
                if len(joins) >= experience.MAX_TESTS:
                    return None
                a, b = (q_start, path[v]) if end == 0 else (path[v], q_goal)
                joins[(end, p, v)] = joining.motion_valid(a, b)
            if not joins[(end, p, v)]:
                break
        else:
            walk = path[i : j + 1] if i <= j else path[j : i + 1][::-1]
            out = np.vstack([q_start, walk, q_goal])
            return out[np.r_[True, np.any(np.diff(out, axis=0) != 0.0, axis=1)]]
    return None


def test_the_compiled_recall_chooses_as_the_plain_rule_does(scene, monkeypatch) -> None:
    """The compiled recall (experience._recall_rows) against the rule written plainly: the
    same walk or the same None for every pair, with one to four remembered paths, and with
    every budget of joins from 1 to 8 (and the module's): the walks found at exactly the
    budget's last test (the plain rule's answer changes from one budget to the next for some
    pair) tell a budget off by one."""
    checker, pairs = scene
    walks = misses = 0
    budget_decides = False
    for k in (0, 3, 6, 9):
        _remember_one(checker, *pairs[k])
        for q_start, q_goal in pairs:
            before = None
            for budget in (*range(1, 9), experience.MAX_TESTS):
                monkeypatch.setattr(experience, "MAX_TESTS", budget)
                got = experience.recall(checker, q_start, q_goal)
                want = _recall_reference(checker, q_start, q_goal)
                assert (got is None) == (want is None)
                if got is not None:
                    np.testing.assert_array_equal(got[0], want)
                walks += got is not None
                misses += got is None
                budget_decides |= before is not None and (want is None) != before
                before = want is None
    assert walks and misses and budget_decides  # both outcomes, and a budget that decides
