"""The corridor grid of the valid set and the search it guides (planner.planning.corridor).

Independent routes: the grid's marks against a plain loop over ``is_valid_one`` of every
cell centre; the weighted A* against scipy's Dijkstra on the same graph; every returned
path against the certified ``check_path``. The narrow scene is built here (a plate in z = 0
with a window, as in the benchmark, nothing imported from benchmarks/).
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from planner import Design, caching
from planner.geometry import Box
from planner.planning import JointPosture, PlanOptions, PlanStatus, corridor, plan, posture_mode
from planner.validity import Margins, ValidityChecker

NARROW = Design(0.5, 0.2, 0.6, joint_min=(-2.0, -np.pi, -np.pi), joint_max=(2.0, np.pi, np.pi))


def plate(window: bool = True, dy: float = 0.0) -> list[Box]:
    """A plate |z| <= 0.01, x in [0.05, 1.3], |y| <= 1.3, with a window x < 0.45, |y| < 0.3
    (closed when ``window`` is False); ``dy`` moves it along y."""
    x0, x1, y1, hx, hy, t = 0.05, 1.3, 1.3, 0.45, 0.3, 0.02
    if not window:
        return [Box([(x0 + x1) / 2, dy, 0.0], [x1 - x0, 2 * y1, t])]
    return [
        Box([(x0 + x1) / 2, dy - (hy + y1) / 2, 0.0], [x1 - x0, y1 - hy, t]),
        Box([(x0 + x1) / 2, dy + (hy + y1) / 2, 0.0], [x1 - x0, y1 - hy, t]),
        Box([(hx + x1) / 2, dy, 0.0], [x1 - hx, 2 * hy, t]),
    ]


@pytest.fixture(autouse=True)
def _fresh_cache():
    caching.clear("corridor")
    yield
    caching.clear("corridor")


def crossing_pairs(checker: ValidityChecker, grid, count: int, seed: int = 3):
    """Seeded (start, goal) pairs valid in ``checker``, theta1 > 0.3 to theta1 < -0.3 (the
    arm must pass the plate's plane), straight motion not valid, both ends in one component
    of ``grid``."""
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(NARROW.joint_min), np.asarray(NARROW.joint_max)
    q = rng.uniform(lo, hi, (6000, 3))
    q[:3000, 0] = rng.uniform(0.3, 1.8, 3000)
    q[3000:, 0] = rng.uniform(-1.8, -0.3, 3000)
    ok = checker.is_valid(q)
    lab = np.array([grid.labels[tuple(grid.cell_of(x))] for x in q])
    a = np.flatnonzero(ok[:3000] & (lab[:3000] > 0))
    b = 3000 + np.flatnonzero(ok[3000:] & (lab[3000:] > 0))
    out = []
    for i in a:
        same = b[lab[b] == lab[i]]
        for j in same[:3]:
            if not checker.motion_valid(q[i], q[j]):
                out.append((q[i], q[j]))
                break
        if len(out) == count:
            break
    return out


def test_marks_are_the_validity_of_the_cell_centres():
    """Every cell's mark equals ``is_valid_one`` of its centre (a plain loop), with the
    obstacles; unmarked columns of the obstacle-free pre-pass included."""
    checker = ValidityChecker(NARROW, Margins(), plate(), "+", "+-+")
    grid = corridor.corridor_grid(checker, (6, 14, 14))
    assert grid is not None and grid.valid.shape == (6, 14, 14)
    expected = np.zeros(grid.shape, dtype=bool)
    for idx in np.ndindex(*grid.shape):
        centre = NARROW.joint_min + grid.step * (np.array(idx) + 0.5)
        expected[idx] = checker.is_valid_one(*centre)
    assert expected.any() and not expected.all()
    np.testing.assert_array_equal(grid.valid, expected)
    # the obstacles matter: some column is valid at one theta1 and not at another
    assert (grid.valid.any(axis=0) & ~grid.valid.all(axis=0)).any()
    assert ((grid.labels > 0) == grid.valid).all()


def test_weighted_astar_is_within_its_factor_of_dijkstra():
    """The grid search against scipy's Dijkstra on the same 6-neighbour graph (edge cost the
    centre distance times the entered cell's weight): a path of marked face neighbours from
    source to target whose cost is at most ``greed`` times the least."""
    rng = np.random.default_rng(5)
    shape = (7, 9, 8)
    valid = rng.random(shape) < 0.7
    weight = 1.0 + rng.random(valid.size) * 3
    # read-only, as a grid's arrays are (corridor_path passes them so): the kernel's one
    # compiled signature, the warm-up's, not a second one for writable arrays
    valid.flags.writeable = weight.flags.writeable = False
    step = np.array([0.3, 0.2, 0.25])
    flat = np.flatnonzero(valid.ravel())
    idx = np.stack(np.unravel_index(np.arange(valid.size), shape), axis=1)
    rows, cols, costs = [], [], []
    for axis in range(3):
        nb = idx.copy()
        nb[:, axis] += 1
        inside = nb[:, axis] < shape[axis]
        a = np.flatnonzero(inside)
        b = np.ravel_multi_index(nb[inside].T, shape)
        for u, v in ((a, b), (b, a)):
            keep = valid.ravel()[u] & valid.ravel()[v]
            rows += [u[keep]]
            cols += [v[keep]]
            costs += [weight[v[keep]] * step[axis]]
    graph = coo_matrix(
        (np.concatenate(costs), (np.concatenate(rows), np.concatenate(cols))),
        shape=(valid.size, valid.size),
    ).tocsr()
    source = flat[0]
    dist = dijkstra(graph, indices=source)
    targets = [t for t in flat[1:] if np.isfinite(dist[t])][::7]
    assert len(targets) > 5
    for greed in (1.0, 3.0):
        for t in targets:
            path = corridor._astar(valid.ravel(), weight, *shape, step, source, t, greed)
            assert path[0] == source and path[-1] == t
            assert valid.ravel()[path].all()
            steps = np.abs(np.diff(idx[path], axis=0)).sum(axis=1)
            assert (steps == 1).all()  # face neighbours
            cost = sum(graph[u, v] for u, v in pairwise(path))
            assert cost <= greed * dist[t] * (1 + 1e-12) + 1e-12
            if greed == 1.0:
                assert cost == pytest.approx(dist[t])
    unreachable = [t for t in flat if not np.isfinite(dist[t])]
    if unreachable:
        path = corridor._astar(valid.ravel(), weight, *shape, step, source, unreachable[0], 3.0)
        assert len(path) == 0


def test_narrow_passage_is_planned_through_the_corridor_and_certified():
    """With the grid of the scene cached (a robot cell's second plan), queries whose straight
    motion fails are solved by the corridor, every motion certified."""
    obstacles = plate()
    checker = ValidityChecker(NARROW, Margins(), obstacles, "+", "+-+")
    grid = corridor.corridor_grid(checker)
    pairs = crossing_pairs(checker, grid, 3)
    assert len(pairs) == 3
    for q_start, q_goal in pairs:
        res = plan(
            NARROW,
            JointPosture(q_start, "+"),
            JointPosture(q_goal, "+"),
            obstacles=obstacles,
            options=PlanOptions(seed=1),
        )
        assert res.status is PlanStatus.SOLVED
        assert res.diagnostics.planner == "corridor"
        wp = res.path.waypoints
        np.testing.assert_array_equal(wp[0], q_start)
        np.testing.assert_array_equal(wp[-1], q_goal)
        assert checker.check_path(wp).valid
        assert all(checker.motion_valid(a, b) for a, b in pairwise(wp))
        # the path passes the plate's plane (theta1 changes sign) inside the window
        assert wp[:, 0].max() > 0 > wp[:, 0].min()


def test_corridor_path_alone_certifies_every_motion():
    """``corridor_path`` on its own: a path from start to goal whose motions are each
    certified, through cells of one component."""
    obstacles = plate()
    checker = ValidityChecker(NARROW, Margins(), obstacles, "+", "+-+")
    grid = corridor.corridor_grid(checker)
    (q_start, q_goal), *_ = crossing_pairs(checker, grid, 1, seed=8)
    out = corridor.corridor_path(
        checker, grid, q_start, q_goal, options=PlanOptions(), deadline=float("inf")
    )
    assert out.waypoints is not None and out.why == ""
    assert out.cells >= 2
    assert checker.check_path(out.waypoints).valid


def test_cut_off_goal_falls_back_and_answers_no_path_within_the_budget():
    """A closed plate: no posture of a w > 0 mode passes theta1 = 0, so start and goal lie in
    different components of the grid; without the region map the plain search then spends
    the budget and the answer is ``no_path`` without a path (never an uncertified one), the
    grid never taken for a proof; with the map, the proof with obstacles (its own bounds,
    not the grid's marks) answers ``proven_infeasible``."""
    open_checker = ValidityChecker(NARROW, Margins(), plate(), "+", "+-+")
    pairs = crossing_pairs(open_checker, corridor.corridor_grid(open_checker), 10)
    obstacles = plate(window=False)
    checker = ValidityChecker(NARROW, Margins(), obstacles, "+", "+-+")
    grid = corridor.corridor_grid(checker)
    q_start, q_goal = next(
        (a, b) for a, b in pairs if checker.is_valid_one(*a) and checker.is_valid_one(*b)
    )
    ls, lg = grid.labels[tuple(grid.cell_of(q_start))], grid.labels[tuple(grid.cell_of(q_goal))]
    assert ls > 0 and lg > 0 and ls != lg
    out = corridor.corridor_path(
        checker, grid, q_start, q_goal, options=PlanOptions(), deadline=float("inf")
    )
    assert out.waypoints is None and "no marked cell" in out.why
    budget = 0.3
    res = plan(
        NARROW,
        JointPosture(q_start, "+"),
        JointPosture(q_goal, "+"),
        obstacles=obstacles,
        options=PlanOptions(time_budget_s=budget, seed=2, region_map=False),
    )
    assert res.status is PlanStatus.NO_PATH
    assert res.path is None
    assert res.diagnostics.searches >= 1  # the plain search ran after the corridor
    assert not res.diagnostics.proven_infeasible  # the grid is a guide, never a proof
    # the budget bounds the search (loose: one OMPL call may overrun its own limit a little)
    assert res.diagnostics.planning_time_s < budget + 1.0
    proven = plan(
        NARROW,
        JointPosture(q_start, "+"),
        JointPosture(q_goal, "+"),
        obstacles=obstacles,
        options=PlanOptions(time_budget_s=budget, seed=2),
    )
    assert proven.status is PlanStatus.NO_PATH and proven.diagnostics.proven_infeasible
    assert proven.diagnostics.planner == "region_map"


def test_cache_hits_for_the_same_scene_and_misses_when_an_obstacle_moves():
    checker = ValidityChecker(NARROW, Margins(), plate(), "+", "+-+")
    assert corridor.cached_corridor_grid(checker, (4, 8, 8)) is None
    first = corridor.corridor_grid(checker, (4, 8, 8))
    assert corridor.corridor_grid(checker, (4, 8, 8)) is first
    again = ValidityChecker(NARROW, Margins(), plate(), "+", "+-+")  # equal, new objects
    assert corridor.cached_corridor_grid(again, (4, 8, 8)) is first
    moved = ValidityChecker(NARROW, Margins(), plate(dy=0.05), "+", "+-+")
    assert corridor.cached_corridor_grid(moved, (4, 8, 8)) is None
    other = corridor.corridor_grid(moved, (4, 8, 8))
    assert other is not first
    assert corridor.cached_corridor_grid(checker.with_mode("+++"), (4, 8, 8)) is None
    assert corridor.cached_corridor_grid(checker, (4, 8, 9)) is None
    caching.clear("corridor")
    assert corridor.cached_corridor_grid(checker, (4, 8, 8)) is None


def test_a_build_projected_over_its_time_is_not_kept():
    checker = ValidityChecker(NARROW, Margins(), plate(), "+", "+-+")
    assert corridor.corridor_grid(checker, max_time_s=1e-9) is None
    assert corridor.cached_corridor_grid(checker) is None


def test_corridor_off_is_the_plain_search():
    """``corridor=False`` (and the region map off, whose proof with obstacles would split the
    search in a first try and the rest): the plain OMPL search alone (no grid built), the
    same answer as before the corridor existed: seeded, reproducible, planner 'rrtconnect'."""
    obstacles = plate()
    checker = ValidityChecker(NARROW, Margins(), obstacles, "+", "+-+")
    grid = corridor.corridor_grid(checker)
    (q_start, q_goal), *_ = crossing_pairs(checker, grid, 1)
    caching.clear("corridor")
    runs = [
        plan(
            NARROW,
            JointPosture(q_start, "+"),
            JointPosture(q_goal, "+"),
            obstacles=obstacles,
            options=PlanOptions(seed=4, corridor=False, region_map=False),
        )
        for _ in range(2)
    ]
    for res in runs:
        assert res.status is PlanStatus.SOLVED
        assert res.diagnostics.planner == "rrtconnect"
        assert res.diagnostics.searches == 1
        assert checker.check_path(res.path.waypoints).valid
    np.testing.assert_array_equal(runs[0].path.waypoints, runs[1].path.waypoints)
    assert corridor.cached_corridor_grid(checker) is None


def test_no_obstacles_no_corridor():
    """Without obstacles the corridor is never consulted (the region map covers that case)."""
    start = JointPosture([0.0, 2.0, 1.0], "+")
    res = plan(
        Design.default(),
        start,
        JointPosture([1.2, 2.3, 1.3], "+"),
        options=PlanOptions(try_direct=False),
    )
    assert res.solved and res.diagnostics.planner == "rrtconnect"
    mode = posture_mode(Design.default(), start)
    free = ValidityChecker(Design.default(), Margins(), (), "+", mode)
    assert corridor.cached_corridor_grid(free) is None


def test_a_stopped_build_is_remembered_and_not_retried_with_a_far_smaller_time():
    checker = ValidityChecker(NARROW, Margins(), plate(), "+", "+-+")
    assert corridor.corridor_grid(checker, (8, 16, 16), max_time_s=1e-9) is None
    projected = corridor._TOO_COSTLY.get(corridor._cache_key(checker, (8, 16, 16)))
    assert projected is not None
    assert projected > 1e-9
    calls = []
    build = corridor._build
    try:
        corridor._build = lambda *a: calls.append(a) or build(*a)
        assert corridor.corridor_grid(checker, (8, 16, 16), max_time_s=projected / 3) is None
        assert not calls  # not tried again
        grid = corridor.corridor_grid(checker, (8, 16, 16))  # no time limit: built
    finally:
        corridor._build = build
    assert grid is not None and len(calls) == 1
    assert corridor.cached_corridor_grid(checker, (8, 16, 16)) is grid
