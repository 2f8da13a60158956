"""The obstacle trees of planner.spatial_index: the bound of every node never above the true
signed distance of the obstacles below it (random sets, and adversarial clouds whose points
lie on the surfaces of capsules around the query segments), and the tree query equal to the
minimum over every obstacle taken one by one and, for spheres and clouds, to numpy's closed
form."""

from __future__ import annotations

import numpy as np
import pytest

from planner.geometry import (
    Box,
    Capsule,
    Points,
    Sphere,
    pack_obstacles,
    segment_box_distance,
    segment_obstacle_distance,
)
from planner.spatial_index import LEAF, node_lower_bound


def _point_segment(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of points x (N, 3) to the segment a-b, numpy's closed form."""
    ab = b - a
    t = np.clip((x - a) @ ab / max(float(ab @ ab), 1e-300), 0.0, 1.0)
    return np.linalg.norm(a + t[:, None] * ab - x, axis=1)


def _random_set(rng: np.random.Generator, n_spheres: int, n_capsules: int, n_boxes: int):
    obs: list = []
    for _ in range(n_spheres):
        obs.append(Sphere(rng.uniform(-0.8, 0.8, 3), rng.uniform(0.005, 0.1)))
    for _ in range(n_capsules):
        a = rng.uniform(-0.8, 0.8, 3)
        obs.append(Capsule(a, a + rng.normal(0, 0.1, 3), rng.uniform(0.005, 0.05)))
    for _ in range(n_boxes):
        obs.append(Box(rng.uniform(-0.8, 0.8, 3), rng.uniform(0.01, 0.3, 3), rng.normal(size=4)))
    return obs


def _capsule_surface_cloud(rng, a, b, rho, n):
    """n points on the surface of the capsule of radius rho around segment a-b (on its
    cylinder and on its end caps): each is exactly rho from the segment."""
    ab = b - a
    e = ab / np.linalg.norm(ab)
    t = rng.uniform(-0.2, 1.2, n)
    v = rng.normal(size=(n, 3))
    core = a + np.clip(t, 0, 1)[:, None] * ab
    # on the cylinder: directions normal to the axis; beyond the ends: any direction outward
    inside = (t > 0) & (t < 1)
    v[inside] -= (v[inside] @ e)[:, None] * e
    v[~inside & (t <= 0)] -= np.maximum(v[~inside & (t <= 0)] @ e, 0)[:, None] * e
    v[~inside & (t >= 1)] -= np.minimum(v[~inside & (t >= 1)] @ e, 0)[:, None] * e
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return core + rho * v


def _leaf_ranges(n_rows: int, nodes: np.ndarray) -> list[tuple[int, int]]:
    """Rows below every node of an implicit tree (its leaves' row ranges, joined)."""
    first = (len(nodes) + 1) // 2 - 1
    out: list[tuple[int, int]] = [(0, 0)] * len(nodes)
    for i in range(len(nodes) - 1, -1, -1):
        if i >= first:
            k = i - first
            out[i] = (min(k * LEAF, n_rows), min((k + 1) * LEAF, n_rows))
        else:
            out[i] = (out[2 * i + 1][0], out[2 * i + 2][1])
    return out


def _row_distances(kind: int, rows: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """True signed distance of segment a-b to each packed row (spheres: numpy's closed form;
    capsules: segment_obstacle_distance of that one capsule, and boxes: the box routine, as
    the library calls them, both tested against sampling in tests/core/test_geometry.py)."""
    if kind == 0:
        return _point_segment(rows[:, :3], a, b) - rows[:, 3]
    if kind == 1:
        a2, b2 = a[None], b[None]
        return np.array(
            [segment_obstacle_distance(a2, b2, [Capsule(r[:3], r[3:6], r[6])])[0] for r in rows]
        )
    return np.array([segment_box_distance(*a, *b, r) for r in rows])


#: The bound's own source run by Python: the product calls it only from compiled code (the
#: tree walk), so a call from Python would compile a signature nothing else uses.
_node_lower_bound = node_lower_bound.py_func


def _check_bounds(packed, a: np.ndarray, b: np.ndarray) -> int:
    """Assert every node's bound <= the least true distance below it; the nodes checked."""
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    checked = 0
    for kind, rows, nodes in (
        (0, packed.spheres, packed.sphere_nodes),
        (1, packed.capsules, packed.capsule_nodes),
        (2, packed.boxes, packed.box_nodes),
    ):
        if len(rows) == 0:
            continue
        true = _row_distances(kind, rows, a, b)
        for i, (r0, r1) in enumerate(_leaf_ranges(len(rows), nodes)):
            # best = +inf: the exact bound, never the early coarse answer
            lb = _node_lower_bound(nodes[i], *a, *b, *lo, *hi, np.inf)
            if r0 == r1:
                assert lb == np.inf
                continue
            assert lb <= true[r0:r1].min() + 1e-12, (kind, i, lb, true[r0:r1].min())
            checked += 1
    return checked


@pytest.mark.parametrize("seed", range(4))
def test_node_bounds_never_exceed_the_true_distance(seed):
    rng = np.random.default_rng(seed)
    obs = _random_set(rng, 1100, 1100, 1100)  # above TREE_FROM of each kind: three trees
    packed = pack_obstacles(obs)
    assert min(len(packed.sphere_nodes), len(packed.capsule_nodes), len(packed.box_nodes)) > 1
    checked = 0
    for _ in range(4):
        a = rng.uniform(-0.8, 0.8, 3)
        checked += _check_bounds(packed, a, a + rng.normal(0, 0.3, 3))
    assert checked > 1000


@pytest.mark.parametrize("seed", range(3))
def test_bounds_hold_for_points_on_the_capsule_surface(seed):
    """Adversarial clouds: points exactly ``rho`` from the query segment (the surface of its
    capsule), with cloud radii below, at and above rho, so that the true distances are
    slightly positive, zero and negative (the segment inside the points' balls)."""
    rng = np.random.default_rng(100 + seed)
    a = rng.uniform(-0.3, 0.3, 3)
    b = a + rng.normal(0, 0.3, 3)
    rho = 0.02
    pts = _capsule_surface_cloud(rng, a, b, rho, 3000)
    np.testing.assert_allclose(_point_segment(pts, a, b), rho, atol=1e-12)
    for radius in (rho - 1e-9, rho, rho + 1e-9, 0.5 * rho, 2 * rho):
        packed = pack_obstacles([Points(pts, radius)])
        assert _check_bounds(packed, a, b) > 100
        got = segment_obstacle_distance(a[None], b[None], packed)[0]
        assert abs(got - (rho - radius)) < 1e-12


@pytest.mark.parametrize("seed", range(3))
def test_tree_query_equals_the_minimum_over_every_obstacle(seed):
    rng = np.random.default_rng(200 + seed)
    cloud = Points(rng.uniform(-0.6, 0.6, (5000, 3)), 0.004)
    obs = [*_random_set(rng, 300, 30, 30), cloud]
    a = rng.uniform(-0.8, 0.8, (40, 3))
    b = a + rng.normal(0, 0.3, (40, 3))
    got = segment_obstacle_distance(a, b, obs)
    one_by_one = np.min([segment_obstacle_distance(a, b, [ob]) for ob in obs], axis=0)
    np.testing.assert_array_equal(got, one_by_one)
    # spheres and the cloud by numpy's closed form, a route independent of the kernels
    balls = np.vstack(
        [
            np.array([[*o.center, o.radius] for o in obs if isinstance(o, Sphere)]),
            np.column_stack([cloud.points, np.full(len(cloud.points), cloud.radius)]),
        ]
    )
    for i in range(len(a)):
        ref = np.min(_point_segment(balls[:, :3], a[i], b[i]) - balls[:, 3])
        only_balls = segment_obstacle_distance(
            a[i : i + 1], b[i : i + 1], [o for o in obs if isinstance(o, Sphere | Points)]
        )[0]
        assert abs(only_balls - ref) < 1e-12


def test_small_sets_and_empty_kinds():
    """Below one leaf the query is the plain loop; a kind without rows has no node."""
    packed = pack_obstacles([Sphere([0.3, 0, 0], 0.05)])
    assert packed.sphere_nodes.shape == (1, 7)
    assert packed.capsule_nodes.shape == (0, 7)
    d = segment_obstacle_distance([[0, 0, 0]], [[0, 0.1, 0]], packed)
    assert abs(d[0] - 0.25) < 1e-12
    assert segment_obstacle_distance([[0, 0, 0]], [[0, 1, 0]], [])[0] == np.inf


@pytest.mark.parametrize(
    ("points", "radius", "field", "words"),
    [
        (np.empty((0, 3)), 0.01, "points", "at least one point"),
        ([[0, 0, np.nan]], 0.01, "points", "finite"),
        ([[0, 0, 0, 0]], 0.01, "points", "shape"),
        ([[0, 0, 0]], 0.0, "radius", "> 0"),
        ([[0, 0, 0]], -1.0, "radius", "> 0"),
    ],
)
def test_bad_clouds_name_the_field(points, radius, field, words):
    from planner.exceptions import InputError

    with pytest.raises(InputError, match=words) as err:
        Points(points, radius)
    assert err.value.field == field


def _min_distance(ax, ay, az, bx, by, bz, *args) -> float:
    """:func:`planner.geometry.segment_min_distance` of one segment, packed obstacles and
    (best, threshold, relax), through the compiled loop that
    :func:`~planner.geometry.segment_obstacle_distance` calls, with its argument types (the
    inner function is compiled code's only; called from Python it would compile alone)."""
    from planner._kernels import read_only
    from planner.geometry.distance import _segments_distance

    *packed, best, t, relax = args
    out = np.empty(1)
    a, b = read_only([[ax, ay, az]]), read_only([[bx, by, bz]])
    _segments_distance(a, b, *packed, read_only([best, t, relax]), out)
    return float(out[0])


@pytest.mark.parametrize("seed", range(2))
def test_the_relaxed_walk_keeps_its_guarantees(seed):
    """segment_min_distance relaxed (relax 0.5 from a threshold t): the rule D >= t decided
    exactly (L < t exactly when D < t; below t, L is the distance to some obstacle, so
    D <= L), and above t a lower bound of D that keeps half the margin: L - t >= (D - t) / 2."""
    rng = np.random.default_rng(300 + seed)
    cloud = Points(rng.uniform(-0.6, 0.6, (6000, 3)), 0.004)
    packed = pack_obstacles([cloud, *_random_set(rng, 1200, 0, 0)])
    below = above = 0
    for _ in range(300):
        a = rng.uniform(-0.8, 0.8, 3)
        b = a + rng.normal(0, 0.3, 3)
        exact = _min_distance(*a, *b, *packed, np.inf, 0.0, 0.0)
        for t in (exact - 0.01, exact + 0.01, 0.02, 0.1):
            got = _min_distance(*a, *b, *packed, np.inf, t, 0.5)
            if exact < t:
                assert exact <= got < t
                below += 1
            else:
                assert t <= got <= exact + 1e-12 and got - t >= 0.5 * (exact - t) - 1e-12
                above += 1
    assert below > 100 and above > 100


@pytest.mark.parametrize("seed", range(2))
def test_the_grid_query_equals_numpy_over_strewn_spheres(seed):
    """1,000 small balls in a shell round the robot (benchmarks/scenes.py): the sphere rows
    get a grid, and the query through it equals numpy's closed form, exact (segments long
    and short, and points: the proofs' queries), and relaxed it keeps its guarantees."""
    from planner.spatial_index import GRID_TO

    rng = np.random.default_rng(400 + seed)
    c = rng.uniform(-0.75, 0.75, (4000, 3))
    c = c[(np.linalg.norm(c, axis=1) > 0.35) & (np.linalg.norm(c, axis=1) < 0.75)][:1000]
    r = rng.uniform(0.005, 0.01, len(c))
    packed = pack_obstacles([Sphere(ci, ri) for ci, ri in zip(c, r, strict=True)])
    assert len(packed.sphere_grid) > 0
    below = above = 0
    for k in range(400):
        a = rng.uniform(-0.8, 0.8, 3)
        b = a if k % 5 == 0 else a + rng.normal(0, (0.02, 0.3)[k % 2], 3)
        ref = np.min(_point_segment(c, a, b) - r)
        exact = _min_distance(*a, *b, *packed, np.inf, 0.0, 0.0)
        assert abs(exact - ref) < 1e-12
        # exact below a finite bound (a running minimum's: path_extremes), within two
        # cells or beyond: the least distance where it is below, else a value >= the bound
        for upper in (ref + 0.004, ref - 0.004, 0.05, 0.4):
            got = _min_distance(*a, *b, *packed, upper, 0.0, 0.0)
            assert abs(got - ref) < 1e-12 if ref < upper else got >= upper
        t = 0.03
        got = _min_distance(*a, *b, *packed, t + 0.25, t, 0.5)
        if ref < t:
            assert ref - 1e-12 <= got < t
            below += 1
        else:
            assert t <= got <= ref + 1e-12 and got - t >= 0.5 * (min(ref, t + 0.25) - t) - 1e-12
            above += 1
    assert below > 50 and above > 50
    many = pack_obstacles([Points(rng.uniform(-1, 1, (GRID_TO + 1, 3)), 0.01)])
    assert len(many.sphere_grid) == 0  # a large cloud keeps its tree alone
