"""The blended path: geometry checked by finite differences and closed forms."""

from __future__ import annotations

import numpy as np
import pytest
from timing_factories import brute_distance_to_polyline, random_walk

from planner.timing.path import ARC, LINE, BlendedPath, distance_to_polyline


@pytest.mark.parametrize("seed", range(4))
def test_path_is_c1_and_parameterised_by_arc_length(seed):
    w = random_walk(seed, n=8)
    path = BlendedPath.from_waypoints(w, 0.08)
    assert np.any(path.kind == ARC)
    s = np.linspace(0, path.length, 4001)[1:-1]
    h = 1e-6
    # q' is the finite difference of q, q'' that of q' (away from piece boundaries).
    inner = np.all(np.abs(s[:, None] - path.s0[None, :]) > 2 * h, axis=1)
    s = s[inner]
    fd1 = (path.evaluate(s + h, 0) - path.evaluate(s - h, 0)) / (2 * h)
    fd2 = (path.evaluate(s + h, 1) - path.evaluate(s - h, 1)) / (2 * h)
    np.testing.assert_allclose(path.evaluate(s, 1), fd1, atol=1e-7)
    np.testing.assert_allclose(path.evaluate(s, 2), fd2, atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(path.evaluate(s, 1), axis=1), 1.0, atol=1e-12)
    # Position and tangent continuous at every piece boundary.
    b = path.s0[1:-1]
    for order in (0, 1):
        left = path.evaluate(b, order, side="left")
        right = path.evaluate(b, order, side="right")
        np.testing.assert_allclose(left, right, atol=1e-12)
    assert path.evaluate([0.0])[0] == pytest.approx(w[0], abs=1e-15)
    np.testing.assert_allclose(path.evaluate([path.length])[0], w[-1], atol=1e-12)


def test_blend_deviation_matches_closed_form():
    # A right-angle corner with long segments: the blend is limited by delta only.
    w = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]])
    delta = 0.05
    path = BlendedPath.from_waypoints(w, delta)
    assert list(path.kind) == [LINE, ARC, LINE]
    # Kunz & Stilman: tangent length l = delta sin(a/2) / (1 - cos(a/2)), r = l / tan(a/2).
    half = np.pi / 4
    ell = delta * np.sin(half) / (1 - np.cos(half))
    assert path.s0[1] == pytest.approx(1.0 - ell, abs=1e-12)
    assert path.radius[1] == pytest.approx(ell / np.tan(half), abs=1e-12)
    s = np.linspace(path.s0[1], path.s0[2], 2001)
    dist_to_vertex = np.linalg.norm(path.evaluate(s) - w[1], axis=1)
    assert dist_to_vertex.min() == pytest.approx(delta, abs=1e-9)
    assert path.blend_deviation[1] == pytest.approx(delta, abs=1e-12)


def test_blend_never_takes_more_than_half_a_segment():
    w = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.1, 0.1, 0.0], [0.2, 0.1, 0.0]])
    path = BlendedPath.from_waypoints(w, 1.0)
    arcs = np.flatnonzero(path.kind == ARC)
    assert len(arcs) == 2
    # Each corner takes 0.05 of the shared middle segment: the arcs meet, no line between.
    assert path.s0[arcs[0] + 1] == pytest.approx(path.s0[arcs[1]], abs=1e-12)
    assert path.blend_deviation.max() <= 1.0


@pytest.mark.parametrize("how", ["zero_deviation", "stop_at", "reversal"])
def test_unblended_corners_are_stops_on_the_vertex(how):
    w = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.5, 1.0, 0.2]])
    dev = np.full(4, 0.05)
    stop = None
    if how == "zero_deviation":
        dev[1] = 0.0
    elif how == "stop_at":
        stop = np.array([False, True, False, False])
    else:
        w[2] = [0.5, 0.0, 0.0]  # goes back along the same line
    path = BlendedPath.from_waypoints(w, dev, stop)
    assert path.vertex_s[1] in path.stops
    np.testing.assert_allclose(path.evaluate([path.vertex_s[1]])[0], w[1], atol=1e-12)
    assert path.corner[path.kind == ARC].tolist() == [2]


def test_duplicates_are_merged_and_collinear_points_are_not_stops():
    w = np.array([[0.0, 0, 0], [0.0, 0, 0], [0.5, 0, 0], [1.0, 0, 0], [1.0, 0, 0]])
    path = BlendedPath.from_waypoints(w, 0.05, np.array([False, True, False, False, False]))
    assert path.waypoints.shape == (3, 3)
    assert path.index_map.tolist() == [0, 0, 1, 2, 2]
    assert path.stops.tolist() == [0.0, 1.0]  # the stop on the duplicate start is the start
    assert path.length == pytest.approx(1.0)


def test_distance_to_polyline_against_dense_sampling():
    rng = np.random.default_rng(3)
    w = random_walk(1, n=5)
    q = w[rng.integers(0, 5, 300)] + rng.normal(scale=0.2, size=(300, 3))
    d, nearest = distance_to_polyline(w, q)
    np.testing.assert_allclose(d, brute_distance_to_polyline(w, q, per_seg=5000), atol=2e-4)
    np.testing.assert_allclose(np.linalg.norm(q - nearest, axis=1), d, atol=1e-12)
    assert np.all(brute_distance_to_polyline(w, nearest, per_seg=5000) < 2e-4)
