"""Obstacle distances against an independent route: dense point sampling of the segment with
numpy point-obstacle distances written from the definitions (as in tests/plan_checker.py)."""

from __future__ import annotations

import numpy as np
import pytest
from planning_factories import point_distance

from planner.exceptions import InputError
from planner.geometry import Box, Capsule, Sphere, pack_obstacles, segment_obstacle_distance
from planner.wire import obstacle_from_dict


def _sampled(a, b, ob, k=4001):
    s = np.linspace(0, 1, k)
    return np.array(
        [point_distance(a[i] + s[:, None] * (b[i] - a[i]), ob).min() for i in range(len(a))]
    )


def _random_obstacles(rng):
    return [
        Sphere(rng.uniform(-0.3, 0.3, 3), rng.uniform(0.0, 0.2)),
        Capsule(rng.uniform(-0.4, 0.4, 3), rng.uniform(-0.4, 0.4, 3), rng.uniform(0.0, 0.1)),
        Box(rng.uniform(-0.3, 0.3, 3), rng.uniform(0.05, 0.4, 3), rng.normal(size=4)),
    ]


@pytest.mark.parametrize("seed", range(4))
def test_segment_distances_match_dense_sampling(seed):
    rng = np.random.default_rng(seed)
    a = rng.uniform(-0.6, 0.6, (40, 3))
    b = rng.uniform(-0.6, 0.6, (40, 3))
    for ob in _random_obstacles(rng):
        exact = segment_obstacle_distance(a, b, [ob])
        sampled = _sampled(a, b, ob)
        # the sampled minimum is above the true one by at most half a sampling step
        step = np.linalg.norm(b - a, axis=1) / 4000
        assert np.all(exact <= sampled + 1e-9)
        assert np.all(sampled - exact <= step / 2 + 1e-9), type(ob).__name__


def test_distance_to_several_obstacles_is_the_nearest():
    rng = np.random.default_rng(5)
    obs = _random_obstacles(rng)
    a = rng.uniform(-0.6, 0.6, (20, 3))
    b = rng.uniform(-0.6, 0.6, (20, 3))
    each = np.stack([segment_obstacle_distance(a, b, [ob]) for ob in obs])
    np.testing.assert_allclose(segment_obstacle_distance(a, b, obs), each.min(axis=0), atol=1e-12)
    assert np.all(np.isinf(segment_obstacle_distance(a, b, [])))


def test_closed_forms():
    # segment along x at height 1 above a unit sphere at the origin: distance 0
    d = segment_obstacle_distance([[-1, 0, 2.0]], [[1, 0, 2.0]], [Sphere([0, 0, 0], 1.0)])
    assert d[0] == pytest.approx(1.0)
    # through a box rotated 45 deg about z: deepest point is the centre, depth = half of 0.2
    quat = [np.cos(np.pi / 8), 0, 0, np.sin(np.pi / 8)]
    d = segment_obstacle_distance(
        [[-1, 0, 0.0]], [[1, 0, 0.0]], [Box([0, 0, 0], [1, 1, 0.2], quat)]
    )
    assert d[0] == pytest.approx(-0.1)
    # skew capsule axes 0.5 apart
    d = segment_obstacle_distance(
        [[-1, 0, 0.0]], [[1, 0, 0.0]], [Capsule([0, -1, 0.5], [0, 1, 0.5], 0.1)]
    )
    assert d[0] == pytest.approx(0.4)


@pytest.mark.parametrize(
    ("data", "field"),
    [
        ({"type": "sphere", "center": [0, 0], "radius": 1}, "sphere.center"),
        ({"type": "sphere", "center": [0, 0, 0], "radius": -1}, "sphere.radius"),
        ({"type": "box", "center": [0, 0, 0], "size": [1, 0, 1]}, "box.size"),
        (
            {"type": "box", "center": [0, 0, 0], "size": [1, 1, 1], "quaternion": [0, 0, 0, 0]},
            "box.quaternion",
        ),
        ({"type": "capsule", "a": [0, 0, 0], "b": [0, 0, float("nan")], "radius": 1}, "capsule.b"),
        ({"type": "cone"}, "type"),
        ({"type": "sphere", "radius": 1}, "center"),
    ],
)
def test_bad_obstacles_name_the_field(data, field):
    with pytest.raises(InputError, match=field.replace(".", r"\.")):
        obstacle_from_dict(data)


def test_boxes_touching_and_grazing():
    """Segments ending on a face, parallel to a face, and along an edge of a rotated box."""
    box = Box([0.1, -0.2, 0.3], [0.4, 0.2, 0.6], [0.8, 0.3, -0.2, 0.4])
    r, c, h = box.rotation, box.center, box.size / 2
    local = np.array(
        [
            [[h[0] + 0.05, -1.0, 0.0], [h[0] + 0.05, 1.0, 0.0]],  # parallel to a face, 5 cm off
            [[h[0], 0.0, 0.0], [h[0] + 0.5, 0.0, 0.0]],  # starts on a face
            [[h[0] + 0.02, h[1] + 0.03, -1], [h[0] + 0.02, h[1] + 0.03, 1]],  # along an edge
            [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]],  # through the centre
        ]
    )
    a = local[:, 0] @ r.T + c
    b = local[:, 1] @ r.T + c
    d = segment_obstacle_distance(a, b, [box])
    np.testing.assert_allclose(d[:3], [0.05, 0.0, np.hypot(0.02, 0.03)], atol=1e-9)
    assert d[3] == pytest.approx(-min(h), abs=1e-9)


@pytest.mark.parametrize("n", [0, 3, 40])
def test_packings_found_by_identity_are_the_packings_of_those_very_objects(n):
    """``pack_obstacles`` remembers a list by the identity of its objects (a key of sampled
    ids, a hit confirmed object by object): the same objects again (in a list or a tuple)
    give the packing kept; a list that shares the sampled objects but holds another one
    between them, or the same objects in another order, is packed from its own rows (equal
    to the packing of fresh objects of the same content), and the first list keeps its own."""
    from planner import caching

    rng = np.random.default_rng(n)
    spheres = [Sphere(rng.uniform(-0.8, 0.8, 3), 0.02 + 0.001 * i) for i in range(n)]
    caching.clear("geometry")
    first = pack_obstacles(spheres)
    assert pack_obstacles(tuple(spheres)) is first
    if n == 0:
        return
    rows = first.spheres.copy()
    stride = max(1, n // 16)
    other = list(spheres)
    k = next((i for i in range(1, n - 1) if i % stride), 1)  # a place the key does not sample
    other[k] = Sphere(spheres[k].center + 0.3, spheres[k].radius)
    for changed in (other, spheres[::-1], spheres, other):
        fresh = [Sphere(o.center, o.radius) for o in changed]
        got, want = pack_obstacles(changed), pack_obstacles(fresh)
        for a, b in zip(got, want, strict=True):
            np.testing.assert_array_equal(a, b)
    assert not np.array_equal(pack_obstacles(other).spheres, rows)
    np.testing.assert_array_equal(pack_obstacles(spheres).spheres, rows)


def test_packed_digest_is_the_rows_digest_and_follows_the_content():
    """``packed_digest``: blake2b of each kind's packed rows with their shapes (computed here
    from the arrays), the same for a packing of fresh equal objects, another for other
    content, and the same again when asked twice (remembered by the arrays' identity)."""
    import hashlib

    from planner import caching
    from planner.geometry import Points, packed_digest

    rng = np.random.default_rng(5)
    scene = [Points(rng.uniform(-1, 1, (300, 3)), 0.01), Sphere([0.2, 0.1, 0.3], 0.05)]
    caching.clear("geometry")
    packed = pack_obstacles(scene)
    want = hashlib.blake2b(digest_size=16)
    for a in packed[:3]:
        want.update(np.asarray(a.shape, dtype=np.int64).tobytes())
        want.update(a.tobytes())
    assert packed_digest(packed) == packed_digest(packed) == want.digest()
    fresh = [Points(np.array(scene[0].points), 0.01), Sphere([0.2, 0.1, 0.3], 0.05)]
    assert pack_obstacles(fresh) is packed or packed_digest(pack_obstacles(fresh)) == want.digest()
    moved = [scene[0], Sphere([0.2, 0.1, 0.31], 0.05)]
    assert packed_digest(pack_obstacles(moved)) != want.digest()
