"""Packing obstacles for the compiled kernels (:mod:`planner.geometry`, "Packing"):
:func:`pack_obstacles` and its caches (by identity and by content, through
:mod:`planner.caching`)."""

from __future__ import annotations

import hashlib
import operator
import weakref
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from planner.caching import BoundedCache, bounded_cache
from planner.constants import MAX_POINTS
from planner.exceptions import InputError
from planner.geometry.shapes import Box, Capsule, Obstacle, Points, Sphere
from planner.spatial_index import build_grid, build_tree

__all__ = ["PackedObstacles", "pack_obstacles", "packed_digest"]


class PackedObstacles(NamedTuple):
    """Obstacles as float arrays for the compiled kernels (layout in the module docstring),
    each kind's rows in the order of its tree (:mod:`planner.spatial_index`)."""

    spheres: np.ndarray  # (ns, 4): spheres and the points of every cloud
    capsules: np.ndarray  # (nc, 7)
    boxes: np.ndarray  # (nb, 15)
    sphere_nodes: np.ndarray  # (2 M - 1, 7) tree of the sphere rows
    capsule_nodes: np.ndarray
    box_nodes: np.ndarray
    sphere_grid: np.ndarray  # (K,) the sphere rows' grid, empty when they have none

    @property
    def count(self) -> int:  # type: ignore[override]  # the obstacles', not tuple.count
        return len(self.spheres) + len(self.capsules) + len(self.boxes)


def pack_obstacles(obstacles: Sequence[Obstacle]) -> PackedObstacles:
    """Pack obstacles into :class:`PackedObstacles`, their trees built (once: a caller that
    checks many postures against one obstacle set packs it once and shares the result).

    Two caches: by identity, the same obstacle objects (the next plan of a library user or
    of a named scene, which keeps its objects) find their packing without a look at their
    rows (rows of 1,000 spheres take 4 ms to gather, a 100,000-point cloud 3 ms to hash);
    by content, an equal set of other objects (the same obstacles sent inline again) finds
    the trees built. Obstacles are immutable (frozen, read-only arrays), so identity is
    enough: an entry holds its objects, and a hit is every object the very one it holds,
    in order (:func:`_by_identity`)."""
    if not isinstance(obstacles, list | tuple):
        obstacles = tuple(obstacles)
    large = len(obstacles) >= _IDENTITY_FROM or any(isinstance(o, Points) for o in obstacles)
    cache = _BY_IDENTITY if large else _BY_IDENTITY_SMALL
    return _by_identity(cache, obstacles)


def _by_identity(
    cache: BoundedCache[tuple[tuple, PackedObstacles]], obstacles: list | tuple
) -> PackedObstacles:
    """The packing of ``obstacles`` remembered in ``cache`` by the objects' identity, or
    packed now (:func:`_pack`) and remembered.

    The key is a fingerprint: the count and the ids of at most :data:`_KEY_IDS` + 1 objects
    spread over the list (the last one included); a hit is then confirmed object by object
    (``is``, in C: 1,000 objects in ~15 us, where a key of every id cost ~30 us to build and
    as much again to hash and compare in the look-up, and ~115 us in all per plan among the
    1,000 spheres of ``benchmarks/planning.py --fair``, docs/planning.md, run K). Two lists
    of one fingerprint but other objects (a rare pattern: the same objects at the sampled
    places, others between them) take each other's entry in turn, each packed again by
    content (:func:`_pack`, its trees found in the content cache): slower, never wrong."""
    n = len(obstacles)
    stride = max(1, n // _KEY_IDS)
    key = (n, *map(id, obstacles[::stride]), id(obstacles[-1])) if n else (0,)
    hit = cache.get(key)
    if hit is not None and all(map(operator.is_, hit[0], obstacles)):  # same length: key
        return hit[1]
    packed = _pack(obstacles)
    cache.put(key, (tuple(obstacles), packed))
    return packed


def packed_digest(packed: PackedObstacles) -> bytes:
    """A digest (16 bytes) of the packed rows of the three kinds, their shapes included: the
    same for equal obstacle sets whatever their objects, for a cache keyed by the obstacles'
    content (the corridor grids'). Computed once per packing: remembered by the identity of
    its arrays (checked through weak references, so an array freed and its id reused is not
    mistaken for it), where hashing a 100,000-point cloud's rows cost ~0.75 ms a look-up
    (docs/planning.md, run K)."""
    rows = packed[:3]
    key = tuple(map(id, rows))
    hit = _DIGESTS.get(key)
    if hit is not None and all(r() is a for r, a in zip(hit[0], rows, strict=True)):
        return hit[1]
    digest = hashlib.blake2b(digest_size=16)
    for a in rows:
        digest.update(np.asarray(a.shape, dtype=np.int64).tobytes())
        digest.update(np.ascontiguousarray(a).tobytes())
    out = digest.digest()
    _DIGESTS.put(key, (tuple(weakref.ref(a) for a in rows), out))
    return out


def _pack(obstacles: Sequence[Obstacle]) -> PackedObstacles:
    """:func:`pack_obstacles` without the identity cache."""
    spheres, clouds, capsules, boxes = [], [], [], []
    n_points = 0
    for i, ob in enumerate(obstacles):
        if isinstance(ob, Sphere):
            spheres.append(ob.row)
        elif isinstance(ob, Points):
            n_points += len(ob.points)
            if n_points > MAX_POINTS:
                raise InputError(
                    f"obstacles hold at most {MAX_POINTS} points in all, got {n_points} by "
                    f"obstacles[{i}]",
                    field=str(i),
                )
            clouds.append(np.column_stack([ob.points, np.full(len(ob.points), ob.radius)]))
        elif isinstance(ob, Capsule):
            capsules.append(ob.row)
        elif isinstance(ob, Box):
            boxes.append(ob.row)
        else:
            raise InputError(
                f"obstacles[{i}] must be a Sphere, Box, Capsule or Points, got {type(ob).__name__}"
            )
    rows = (
        np.vstack([np.array(spheres, dtype=float).reshape(-1, 4), *clouds]),
        np.array(capsules, dtype=float).reshape(-1, 7),
        np.array(boxes, dtype=float).reshape(-1, 15),
    )
    small = sum(len(r) for r in rows) <= _CACHE_FROM
    digest = hashlib.blake2b(digest_size=16)
    for r in rows:
        digest.update(np.asarray(r.shape, dtype=np.int64).tobytes())
        digest.update(r.tobytes())
    key = digest.digest()
    cache = _PACKED_SMALL if small else _PACKED
    hit = cache.get(key)
    if hit is None:
        hit = _pack_rows(rows)
        cache.put(key, hit)
    return hit


def _pack_rows(rows: tuple[np.ndarray, np.ndarray, np.ndarray]) -> PackedObstacles:
    """The trees of the three kinds' rows, every array read-only (shared through the cache)."""
    (s_rows, s_nodes), (c_rows, c_nodes), (b_rows, b_nodes) = (
        build_tree(kind, r) for kind, r in enumerate(rows)
    )
    packed = PackedObstacles(s_rows, c_rows, b_rows, s_nodes, c_nodes, b_nodes, build_grid(s_rows))
    for a in packed:
        a.flags.writeable = False
    return packed


#: Obstacle sets are packed once per process and content: the next checker of the same set
#: (the next request of a scene) finds its trees built; sets of more rows than this in
#: ``geometry.packed``, smaller ones in ``geometry.packed_small`` (:mod:`planner.caching`).
_CACHE_FROM = 64
_PACKED: BoundedCache[PackedObstacles] = bounded_cache("geometry.packed")
#: Sets of at most ``_CACHE_FROM`` rows have a cache of their own (hashing a few rows costs
#: a microsecond, packing them with their trees some tens: every plan packs its scene), so
#: that many small scenes never push a large scene's trees out of ``_PACKED``.
_PACKED_SMALL: BoundedCache[PackedObstacles] = bounded_cache("geometry.packed_small")
#: Obstacle lists of at least this many objects (or holding a cloud) are remembered by
#: identity (:func:`pack_obstacles`) in ``geometry.by_identity``; smaller ones in
#: ``geometry.by_identity_small`` (their own, as the content caches: many small scenes never
#: push a large scene's entry out; a hit there costs ~1 us, hashing their rows ~8 us).
_IDENTITY_FROM = 16
_BY_IDENTITY: BoundedCache[tuple[tuple, PackedObstacles]] = bounded_cache("geometry.by_identity")
_BY_IDENTITY_SMALL: BoundedCache[tuple[tuple, PackedObstacles]] = bounded_cache(
    "geometry.by_identity_small"
)
#: Ids of at most this many objects (and the last one's) make an identity key
#: (:func:`_by_identity`).
_KEY_IDS = 16
#: :func:`packed_digest`'s digests by the identity of the packed arrays (weak references).
_DIGESTS: BoundedCache[tuple[tuple, bytes]] = bounded_cache("geometry.digests")
