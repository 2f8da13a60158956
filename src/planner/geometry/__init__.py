"""Obstacles and distances between the link capsules and them (numpy and numba, no I/O).

Obstacles are the shapes of the wire vocabulary (``docs/conventions.md``): a sphere, an
oriented box (quaternion ``[w, x, y, z]``, frame of the box to the base frame), a capsule, and
a point cloud (every point a sphere of one radius, as a depth camera gives them). A floor is
a large flat box. Distances are *signed* distances between a link's axis segment
and the obstacle's surface (negative when the segment enters the obstacle); the link radius
is subtracted by the caller (:mod:`planner.validity`).

Why each routine is right:

* sphere and capsule: closed-form point-to-segment distance (sphere), and for a capsule the
  minimum over the link parameter of the point-to-segment distance; that function is convex in
  the parameter (a distance to a convex set composed with an affine map), so a golden-section
  search finds its minimum;
* box: outside the box, an exact piecewise-quadratic minimisation in the box frame
  (:func:`segment_box_distance`); for a segment entering the box, the signed distance
  function of a convex set is convex, so the same golden-section search over the link
  parameter gives the (negative) segment-to-box signed distance.

The search stops when the bracket is below :data:`LINE_SEARCH_TOL` of the segment; the
distance error is then below that times the segment length (a distance is 1-Lipschitz in the
point), i.e. below 1e-9 m for links under a metre. The tests compare every routine with dense
point sampling.

The package's rooms: :mod:`planner.geometry.shapes` (the obstacles),
:mod:`planner.geometry.packing` (:func:`pack_obstacles` and its caches) and
:mod:`planner.geometry.distance` (the compiled distances); every name is exported here.

Packing: :func:`pack_obstacles` turns a list of obstacles into three float arrays that the
compiled kernels read (rows ``[cx, cy, cz, r]`` for spheres and for each point of a cloud,
``[ax, ay, az, bx, by, bz, r]`` for capsules, ``[cx, cy, cz, R (9, row-major), hx, hy, hz]``
for boxes, R the box-to-base rotation and h the half sizes), each with the tree of
:mod:`planner.spatial_index` over its rows (the rows reordered along it), built once per
obstacle set. :func:`segment_min_distance` walks the trees: the distance it returns is the
same minimum a loop over every obstacle finds, in time that grows slowly with their number.
"""

from __future__ import annotations

from planner.constants import MAX_POINTS
from planner.geometry.distance import (
    LINE_SEARCH_TOL,
    box_sdf,
    point_segment_distance,
    segment_box_distance,
    segment_convex_distance,
    segment_min_distance,
    segment_obstacle_distance,
)
from planner.geometry.packing import PackedObstacles, pack_obstacles, packed_digest
from planner.geometry.shapes import Box, Capsule, Obstacle, Points, Sphere

__all__ = [
    "LINE_SEARCH_TOL",
    "MAX_POINTS",
    "Box",
    "Capsule",
    "Obstacle",
    "PackedObstacles",
    "Points",
    "Sphere",
    "box_sdf",
    "pack_obstacles",
    "packed_digest",
    "point_segment_distance",
    "segment_box_distance",
    "segment_convex_distance",
    "segment_min_distance",
    "segment_obstacle_distance",
]
