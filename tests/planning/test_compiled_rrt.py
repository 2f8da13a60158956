"""The compiled RRT-Connect (planner.planning.compiled_rrt): its paths are valid by an
independent dense check, it is reproducible, its nearest-neighbour grid agrees with a brute
force scan, and the planners it does not serve still go to OMPL."""

from __future__ import annotations

import numpy as np
import pytest

from planner import Design
from planner.geometry import Sphere
from planner.planning import PlanOptions, compiled_rrt
from planner.planning.compiled_rrt import _BUCKETS, _insert, _nearest
from planner.validity import N_MEASURES, Margins, ValidityChecker, densify

START, GOAL = np.array([0.2, 1.0, 2.0]), np.array([1.0, 1.0, 2.0])


@pytest.fixture(scope="module")
def blocked() -> ValidityChecker:
    """The warm-up's scene: a sphere between start and goal (the straight motion fails)."""
    chk = ValidityChecker(Design.default(), Margins(), [Sphere([0.623, -0.013, -0.426], 0.08)])
    chk = chk.with_mode("++-")
    assert chk.is_valid_one(*START) and chk.is_valid_one(*GOAL)
    assert not chk.motion_valid(START, GOAL)
    return chk


def test_path_is_valid_by_a_dense_independent_check(blocked: ValidityChecker) -> None:
    out = compiled_rrt.rrt_connect(blocked, START, GOAL, PlanOptions(seed=3), 2.0)
    assert out is not None and out.exact and out.waypoints is not None
    w = out.waypoints
    assert np.allclose(w[0], START) and np.allclose(w[-1], GOAL)
    assert len(w) >= 3  # the straight motion is blocked
    # every posture every 0.5 mrad valid, by the full per-state report (not the certificate)
    assert blocked.check_states(densify(w, 5e-4)).valid.all()
    assert blocked.check_path(w).valid


def test_reproducible_with_a_seed_and_varies_without(blocked: ValidityChecker) -> None:
    runs = [
        compiled_rrt.rrt_connect(blocked, START, GOAL, PlanOptions(seed=s), 2.0) for s in (5, 5, 6)
    ]
    paths = [r.waypoints for r in runs if r is not None]
    assert len(paths) == 3
    assert paths[0].shape == paths[1].shape and np.array_equal(paths[0], paths[1])
    assert paths[2].shape != paths[0].shape or not np.array_equal(paths[0], paths[2])


def test_no_path_when_the_goal_is_walled_off() -> None:
    """A goal whose every neighbourhood is blocked: the search ends at its budget, no path."""
    design = Design.default()
    chk = ValidityChecker(design, Margins(), [], "+", "++-")
    # a goal outside the region (invalid) cannot be connected: every motion to it fails
    bad = np.array([1.0, 1.0, 4.0])
    assert not chk.is_valid_one(*bad)
    out = compiled_rrt.rrt_connect(chk, START, bad, PlanOptions(seed=1), 0.05)
    assert out is not None and out.waypoints is None and out.ompl_status == "Timeout"


def test_nearest_grid_matches_a_brute_force_scan() -> None:
    rng = np.random.default_rng(4)
    lo, hi = np.array([-2.0, -np.pi, -np.pi]), np.array([2.0, np.pi, np.pi])
    width = (hi - lo) / _BUCKETS
    inv = 1.0 / width
    n = 400
    nodes = np.empty((1, n, 3))
    meas = np.empty((1, n, N_MEASURES))
    parent = np.empty((1, n), dtype=np.int64)
    nxt = np.empty((1, n), dtype=np.int64)
    head = np.full((1, _BUCKETS, _BUCKETS, _BUCKETS), -1, dtype=np.int64)
    count = np.zeros(1, dtype=np.int64)
    # clustered nodes, so that many queries fall far from every node
    pts = np.clip(rng.normal([1.0, 2.0, -2.0], 0.4, (n, 3)), lo, hi)
    for p in pts:
        _insert(0, p, np.zeros(N_MEASURES), -1, nodes, meas, parent, count, head, nxt, lo, inv)
    for q in rng.uniform(lo, hi, (300, 3)):
        got = _nearest(0, q, nodes, count, head, nxt, lo, inv, width)
        want = int(np.argmin(np.sum((pts - q) ** 2, axis=1)))
        assert np.isclose(np.sum((pts[got] - q) ** 2), np.sum((pts[want] - q) ** 2))


def test_simplify_gives_the_plain_greedy_paths() -> None:
    """The simplification's shortcuts (its second reduction leaves out the pairs of old
    vertices the first tried; a motion is first probed where a neighbouring one broke a
    rule; each vertex measured once) give the paths of the plain route: a greedy reduction
    in Python that certifies every pair with certify_motion, the same random shortcuts, the
    plain reduction again. On raw searches' paths among small spheres, where most long
    motions are refused."""
    from planner.planning.compiled_rrt import _seed, _shortcut, _simplify
    from planner.validity import MIN_CERTIFIED_STEP, certify_motion

    design = Design.default()
    rng = np.random.default_rng(8)
    spheres = [Sphere(c, 0.02) for c in rng.uniform(-0.8, 0.8, (400, 3))]
    chk = ValidityChecker(design, Margins(), spheres, "+", "+-+")
    prm, packed, step = chk.params, tuple(chk.packed), chk.coarse_step

    def joined(qa: np.ndarray, qb: np.ndarray) -> bool:
        return certify_motion(qa, qb, prm, *packed, step, MIN_CERTIFIED_STEP, False)[0] == 0

    def plain_reduce(path: np.ndarray) -> np.ndarray:
        keep, i = [0], 0
        while i < len(path) - 1:
            j = len(path) - 1
            while j > i + 1 and not joined(path[i], path[j]):
                j -= 1
            keep.append(j)
            i = j
        return path[keep]

    ends = rng.uniform([-2.5, 1.0, 0.2], [2.5, 3.0, 2.0], (300, 3))
    ends = ends[chk.is_valid(ends)]
    compared = changed = 0
    for k in range(0, len(ends) - 1, 2):
        out = compiled_rrt.rrt_connect(
            chk, ends[k], ends[k + 1], PlanOptions(seed=k + 1, simplify=False), 0.5
        )
        if out is None or out.waypoints is None or len(out.waypoints) < 4:
            continue
        path = out.waypoints
        _seed(k)
        known = np.zeros(len(path), dtype=np.bool_)
        gain = compiled_rrt.SHORTCUT_MIN_GAIN
        got = _simplify(path, known, 2, 8, gain, prm, packed, step)
        _seed(k)
        plain = plain_reduce(path)
        plain, _ = _shortcut(plain, 2 * len(plain) + 8, gain, prm, packed, step)
        plain = plain_reduce(plain)
        assert got.shape == plain.shape and np.array_equal(got, plain)
        # no shortcut gains its whole path's length: with that least gain none is taken
        _seed(k)
        same, _ = _shortcut(path, 2 * len(path) + 8, 1.0, prm, packed, step)
        np.testing.assert_array_equal(same, path)
        compared += 1
        changed += len(got) < len(path)
        if compared == 8:
            break
    assert compared == 8 and changed >= 5


def test_scene_range_short_in_clutter() -> None:
    design = Design.default()
    few = ValidityChecker(design, Margins(), [Sphere([0.6, 0.0, -0.4], 0.05)], "+", "++-")
    rng = np.random.default_rng(1)
    many = [Sphere(c, 0.005) for c in rng.uniform(-0.7, 0.7, (compiled_rrt.CLUTTER_ROWS, 3))]
    crowded = ValidityChecker(design, Margins(), many, "+", "++-")
    free = ValidityChecker(design, Margins(), [], "+", "++-")
    assert compiled_rrt.scene_range(free) == 1.0
    assert compiled_rrt.scene_range(few) == 0.6
    assert compiled_rrt.scene_range(crowded) == 0.25


def test_other_planners_and_goal_sets_go_to_ompl(blocked: ValidityChecker) -> None:
    """OMPL answers planners other than rrtconnect and goal sets; its paths are certified."""
    out = compiled_rrt.search(blocked, START, GOAL, PlanOptions(name="prmstar", seed=1), 0.2)
    assert out.exact and out.waypoints is not None
    assert blocked.check_path(out.waypoints).valid
    goals = np.stack([GOAL, GOAL + np.array([0.05, 0.0, 0.0])])
    out = compiled_rrt.search(blocked, START, goals, PlanOptions(seed=1), 1.0)
    assert out.exact and out.waypoints is not None
