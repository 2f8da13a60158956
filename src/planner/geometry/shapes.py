"""The obstacle shapes of the wire vocabulary (:mod:`planner.geometry`): a sphere, a capsule,
an oriented box and a point cloud, validated and immutable (frozen, read-only arrays), each
with its packed row made once (:mod:`planner.geometry.packing`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from planner.constants import MAX_POINTS
from planner.exceptions import InputError

__all__ = ["Box", "Capsule", "Obstacle", "Points", "Sphere"]


def _vector(name: str, value: object, size: int = 3) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be {size} numbers, got {value!r}") from exc
    if arr.shape != (size,):
        raise InputError(f"{name} must be {size} numbers, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be finite, got {arr.tolist()}")
    arr = arr.copy()
    arr.flags.writeable = False
    return arr


def _length(name: str, value: object, *, positive: bool) -> float:
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a number, got {value!r}") from exc
    if not math.isfinite(v) or v < 0 or (positive and v == 0):
        rule = "> 0" if positive else ">= 0"
        raise InputError(f"{name} must be finite and {rule}, got {v}")
    return v


@dataclass(frozen=True, slots=True, eq=False)
class Sphere:
    """A ball: ``center`` (3,) m, ``radius`` m (>= 0; 0 is a point)."""

    center: np.ndarray
    radius: float
    #: its packed row (:func:`pack_obstacles`), made once: every checker packs its scene
    row: tuple[float, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vector("sphere.center", self.center))
        object.__setattr__(self, "radius", _length("sphere.radius", self.radius, positive=False))
        object.__setattr__(self, "row", (*self.center.tolist(), self.radius))


@dataclass(frozen=True, slots=True, eq=False)
class Capsule:
    """The points within ``radius`` (m) of the segment ``a``-``b`` ((3,) m each)."""

    a: np.ndarray
    b: np.ndarray
    radius: float
    #: its packed row (:func:`pack_obstacles`), made once: every checker packs its scene
    row: tuple[float, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "a", _vector("capsule.a", self.a))
        object.__setattr__(self, "b", _vector("capsule.b", self.b))
        object.__setattr__(self, "radius", _length("capsule.radius", self.radius, positive=False))
        object.__setattr__(self, "row", (*self.a.tolist(), *self.b.tolist(), self.radius))


@dataclass(frozen=True, slots=True, eq=False)
class Box:
    """An oriented box: ``center`` (3,) m, full edge lengths ``size`` (3,) m (> 0), and the
    unit quaternion ``[w, x, y, z]`` turning the box frame into the base frame (normalised
    here; a zero quaternion is an error)."""

    center: np.ndarray
    size: np.ndarray
    quaternion: np.ndarray = (1.0, 0.0, 0.0, 0.0)  # type: ignore[assignment]
    #: its packed row (:func:`pack_obstacles`): centre, rotation, half sizes, made once
    row: tuple[float, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vector("box.center", self.center))
        size = _vector("box.size", self.size)
        if np.any(size <= 0):
            raise InputError(f"box.size must be > 0 in every axis, got {size.tolist()}")
        object.__setattr__(self, "size", size)
        quat = np.asarray(_vector("box.quaternion", self.quaternion, 4))
        norm = float(np.linalg.norm(quat))
        if norm < 1e-12:
            raise InputError("box.quaternion must not be zero (it is normalised, [w, x, y, z])")
        quat = quat / norm
        quat.flags.writeable = False
        object.__setattr__(self, "quaternion", quat)
        half = (size / 2).tolist()
        row = (*self.center.tolist(), *self.rotation.ravel().tolist(), *half)
        object.__setattr__(self, "row", row)

    @property
    def rotation(self) -> np.ndarray:
        """Shape (3, 3): box-frame to base-frame rotation matrix of the quaternion."""
        w, x, y, z = self.quaternion
        return np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
            ]
        )


@dataclass(frozen=True, slots=True, eq=False)
class Points:
    """A point cloud: ``points`` (N, 3) m, 1 <= N <= :data:`MAX_POINTS`, every point a ball
    of ``radius`` m (> 0: a sensor's points stand for surfaces of some thickness)."""

    points: np.ndarray
    radius: float

    def __post_init__(self) -> None:
        try:
            pts = np.array(self.points, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError("points.points must be N x 3 numbers", field="points") from exc
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise InputError(
                f"points.points must have shape (N, 3), got {pts.shape}", field="points"
            )
        if len(pts) == 0:
            raise InputError("points.points must hold at least one point", field="points")
        if len(pts) > MAX_POINTS:
            raise InputError(
                f"points.points holds at most {MAX_POINTS} points, got {len(pts)}",
                field="points",
            )
        finite = np.isfinite(pts).all(axis=1)
        if not finite.all():
            i = int(np.argmin(finite))
            raise InputError(
                f"points.points[{i}] must be finite, got {pts[i].tolist()}", field="points"
            )
        pts.flags.writeable = False
        object.__setattr__(self, "points", pts)
        try:
            radius = _length("points.radius", self.radius, positive=True)
        except InputError as exc:
            raise InputError(str(exc), field="radius") from exc
        object.__setattr__(self, "radius", radius)


Obstacle = Sphere | Box | Capsule | Points
