"""The geometric path to be timed: the planned joint-space polyline with circular corner blends.

A planned path is a polyline in joint space (``docs/conventions.md``: consecutive waypoints are
joined by the straight segment between their literal joint values). A polyline has a corner at
every interior waypoint, where a trajectory with finite acceleration has to stop. To keep
moving, each corner ``k`` may be replaced by a circular arc tangent to both segments (the
blend of Kunz and Stilman, RSS 2012) whose distance to the vertex is at most
``max_deviation[k]`` (rad, joint space). The path is then C1 (continuous tangent), parameterised
by its joint-space arc length ``s`` (rad), and made of *pieces*: straight lines (exactly on the
polyline) and arcs (inside the corner, within ``max_deviation`` of the vertex).

A corner with deviation 0, a requested stop, or a reversal (turning angle near pi) is not
blended: the path keeps the vertex and the trajectory comes to rest there. The path is split
into *sections* at such stops; each section is timed from rest to rest.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numba import njit

from planner import _kernels
from planner.exceptions import InputError

__all__ = ["BlendedPath", "distance_to_polyline"]

#: Which piece a boundary ``s`` belongs to, as :func:`numpy.searchsorted` names it.
Side = Literal["left", "right"]

#: Consecutive waypoints closer than this (rad) are one waypoint (a zero-length segment has
#: no direction, and a nearly zero one gives a corner no trajectory can take at speed).
DUPLICATE_TOL = 1e-9
#: A corner turning by less than this (rad) is straight: neither blended nor stopped at (its
#: blend radius would be ~1e6 times the segment, losing precision; the tangent jumps by at most
#: this, so the velocity direction does too).
STRAIGHT_ANGLE = 1e-6
#: A corner turning by more than pi minus this (rad) is a reversal: it cannot be blended.
REVERSAL_ANGLE = 1e-6

#: Straight pieces shorter than this (rad) are dropped (rounding between two touching blends).
_PIECE_TOL = 1e-12

LINE, ARC = 0, 1


@dataclass(frozen=True, eq=False)
class BlendedPath:
    """A polyline with circular corner blends, parameterised by joint-space arc length.

    Build it with :meth:`from_waypoints`. Piece ``i`` covers ``s in [s0[i], s0[i + 1]]``.

    Attributes
    ----------
    waypoints : shape (N, 3), rad
        The polyline after merging consecutive duplicates.
    index_map : shape (N_in,), int
        For each input waypoint, its index in ``waypoints``.
    kind : shape (K,), int8
        ``LINE`` (0) or ``ARC`` (1) per piece.
    s0 : shape (K + 1,), rad
        Start of each piece along the path; ``s0[-1]`` is the path length.
    origin, direction, normal : shape (K, 3)
        Line: start point, unit direction, zeros. Arc: centre ``c``, unit ``x`` (from the centre
        to the arc's start), unit ``y`` (the incoming direction); the arc is
        ``c + r (x cos phi + y sin phi)``, ``phi = (s - s0) / r``.
    radius : shape (K,), rad
        Arc radius; ``inf`` for lines.
    corner : shape (K,), int
        For an arc, the waypoint index of its corner; -1 for a line.
    blend_deviation : shape (N,), rad
        Distance from each vertex to its arc (0 where not blended).
    stops : shape (S + 1,), rad
        Section boundaries along ``s``: 0, every vertex where the path comes to rest, the end.
    vertex_s : shape (N,), rad
        Path parameter at each vertex (for a blended vertex, the middle of its arc).
    """

    waypoints: np.ndarray
    index_map: np.ndarray
    kind: np.ndarray
    s0: np.ndarray
    origin: np.ndarray
    direction: np.ndarray
    normal: np.ndarray
    radius: np.ndarray
    corner: np.ndarray
    blend_deviation: np.ndarray
    stops: np.ndarray
    vertex_s: np.ndarray

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_waypoints(
        cls,
        waypoints: np.ndarray,
        max_deviation: float | np.ndarray,
        stop_at: np.ndarray | None = None,
        min_radius: float = 0.0,
    ) -> BlendedPath:
        """Blend the corners of a joint-space polyline.

        Parameters
        ----------
        waypoints : array, shape (N, 3), rad
            Finite, N >= 2 (checked by the caller).
        max_deviation : float or array of shape (N,), rad, >= 0
            Largest distance from each vertex to its blend; 0 keeps the vertex (a stop).
            Entries for the first and last waypoints are ignored.
        stop_at : bool array of shape (N,), optional
            Vertices where the trajectory must come to rest (no blend).
        min_radius : float, rad
            A corner whose blend radius would be smaller becomes a stop: the speed through
            such a blend, ``sqrt(acceleration * radius)``, is nearly zero anyway, and the
            solver's tolerances are absolute.

        The blend at a corner turning by ``alpha`` between segments of lengths ``L_in``,
        ``L_out`` has tangent length ``l = min(f_in L_in, f_out L_out,
        delta sin(alpha/2) / (1 - cos(alpha/2)))`` and radius ``r = l / tan(alpha/2)``, so its
        vertex distance ``r (1 / cos(alpha/2) - 1)`` is at most ``delta``. ``f`` is 1/2 when
        the segment's other end is a corner that may be blended too, and 1 when it is one that
        never is (an end of the path, a stop, a straight corner, a reversal): neighbouring
        blends never overlap, and a short segment between a stop and a corner (the lift of a
        pick-and-place cycle) can be rounded over its whole length.
        """
        w, index_map, stop, dev = _merge_duplicates(waypoints, max_deviation, stop_at)
        if w.shape[0] == 1:
            empty3 = np.zeros((0, 3))
            return cls(
                w,
                index_map,
                np.zeros(0, np.int8),
                np.zeros(1),
                empty3,
                empty3,
                empty3,
                np.zeros(0),
                np.zeros(0, int),
                np.zeros(1),
                np.zeros(1),
                np.zeros(1),
            )
        seg = np.diff(w, axis=0)
        seg_len = np.linalg.norm(seg, axis=1)
        seg_dir = seg / seg_len[:, None]
        alpha, tangent, is_stop = _blend_tangents(seg_len, seg_dir, stop, dev, min_radius)
        pieces = _pieces(w, seg_len, seg_dir, alpha, tangent)
        return cls(
            waypoints=w,
            index_map=index_map,
            stops=np.unique(pieces["vertex_s"][is_stop]),
            **pieces,
        )

    # ------------------------------------------------------------------ queries
    @property
    def length(self) -> float:
        """Joint-space length of the blended path, rad."""
        return float(self.s0[-1])

    @property
    def n_pieces(self) -> int:
        return int(self.kind.shape[0])

    def piece_index(
        self, s: np.ndarray, lo: int = 0, hi: int | None = None, side: Side = "right"
    ) -> np.ndarray:
        """Index of the piece holding each ``s``, restricted to pieces ``lo..hi`` (inclusive):
        a piece boundary belongs to the later piece (``side="right"``) or the earlier one
        (``"left"``)."""
        hi = self.n_pieces - 1 if hi is None else hi
        idx = np.searchsorted(self.s0, s, side=side) - 1
        return np.clip(idx, lo, hi)

    def evaluate(
        self,
        s: np.ndarray,
        order: int = 0,
        lo: int = 0,
        hi: int | None = None,
        side: Side = "right",
    ) -> np.ndarray:
        """Path point (order 0), tangent q'(s) (1) or curvature vector q''(s) (2) at ``s``.

        Parameters
        ----------
        s : array, shape (M,), rad
        order : 0, 1 or 2
        lo, hi : pieces to evaluate on (see :meth:`piece_index`); a section uses its own.
        side : "right" or "left"
            Which piece a boundary belongs to (q'' jumps there between line and arc).

        Returns
        -------
        array, shape (M, 3): rad, dimensionless, 1/rad.
        """
        if order not in (0, 1, 2):
            raise InputError(f"order must be 0, 1 or 2, got {order}")
        return self.evaluate_all(s, lo, hi, side)[order]

    def evaluate_all(
        self, s: np.ndarray, lo: int = 0, hi: int | None = None, side: Side = "right"
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, q', q'') at ``s`` in one pass, each shape (M, 3) (see :meth:`evaluate`)."""
        s = np.ascontiguousarray(np.atleast_1d(np.asarray(s, dtype=float)))
        if self.n_pieces == 0:
            q = np.broadcast_to(self.waypoints[0], (s.shape[0], 3)).copy()
            return q, np.zeros_like(q), np.zeros_like(q)
        idx = self.piece_index(s, lo, hi, side)
        q, d1, d2 = np.empty((s.shape[0], 3)), np.empty((s.shape[0], 3)), np.empty((s.shape[0], 3))
        _evaluate_pieces(
            s,
            idx,
            self.s0,
            self.kind,
            self.origin,
            self.direction,
            self.normal,
            self.radius,
            q,
            d1,
            d2,
        )
        return q, d1, d2

    def kept_stops(self) -> np.ndarray:
        """Vertices where the path comes to rest, bool (N,) (so a rebuilt path keeps them)."""
        return np.isin(self.vertex_s, self.stops)

    def section_pieces(self, s_start: float, s_end: float) -> tuple[int, int]:
        """First and last piece of the section ``[s_start, s_end]``."""
        lo = int(np.searchsorted(self.s0, s_start, side="right") - 1)
        hi = int(np.searchsorted(self.s0, s_end, side="left") - 1)
        return max(lo, 0), min(max(hi, lo), self.n_pieces - 1)

    def arc_corner_at(self, s: np.ndarray) -> np.ndarray:
        """Waypoint index of the blend holding each ``s``, or -1 on a straight piece."""
        if self.n_pieces == 0:
            return np.full(np.shape(s), -1)
        return self.corner[self.piece_index(np.asarray(s, dtype=float))]


@njit(cache=True)
def _evaluate_pieces(
    s, idx, s0, kind, origin, direction, normal, radius, q, d1, d2
):  # pragma: no cover
    """q, q', q'' (M, 3) at ``s`` (M,) on the pieces ``idx`` (M,), into q, d1, d2
    (:func:`point_on_piece` per position: one pass of compiled code, a check evaluates
    thousands, several times a timing)."""
    for m in range(s.shape[0]):
        k = idx[m]
        q0, q1, q2, t0, t1, t2, c0, c1, c2 = point_on_piece(
            k, s[m] - s0[k], kind, origin, direction, normal, radius
        )
        q[m, 0], q[m, 1], q[m, 2] = q0, q1, q2
        d1[m, 0], d1[m, 1], d1[m, 2] = t0, t1, t2
        d2[m, 0], d2[m, 1], d2[m, 2] = c0, c1, c2


@njit(cache=True, nogil=True)
def point_on_piece(k, ds, kind, origin, direction, normal, radius):  # pragma: no cover
    """q, q', q'' (three numbers each) at ``ds`` along piece ``k`` (of the
    :class:`BlendedPath` arrays): a line ``o + d ds``; an arc ``o + r (d cos phi + n sin
    phi)``, ``phi = ds / r``, its tangent ``n cos phi - d sin phi`` and curvature vector
    ``-(d cos phi + n sin phi) / r``. The one copy of these formulas for every compiled
    reader of a path (numbers, not arrays: no view per position)."""
    if kind[k] == ARC:
        r = radius[k]
        phi = ds / r
        c, si = np.cos(phi), np.sin(phi)
        r0 = direction[k, 0] * c + normal[k, 0] * si
        r1 = direction[k, 1] * c + normal[k, 1] * si
        r2 = direction[k, 2] * c + normal[k, 2] * si
        return (
            origin[k, 0] + r * r0,
            origin[k, 1] + r * r1,
            origin[k, 2] + r * r2,
            normal[k, 0] * c - direction[k, 0] * si,
            normal[k, 1] * c - direction[k, 1] * si,
            normal[k, 2] * c - direction[k, 2] * si,
            -r0 / r,
            -r1 / r,
            -r2 / r,
        )
    return (
        origin[k, 0] + direction[k, 0] * ds,
        origin[k, 1] + direction[k, 1] * ds,
        origin[k, 2] + direction[k, 2] * ds,
        direction[k, 0],
        direction[k, 1],
        direction[k, 2],
        0.0,
        0.0,
        0.0,
    )


@njit(cache=True, nogil=True)
def piece_of(s0, n_pieces, s, hint):  # pragma: no cover
    """:meth:`BlendedPath.piece_index` of one position (side "right", every piece), and the
    count of ``s0`` found (the next call's ``hint``, :func:`planner._kernels.count_at_most_from`)."""
    count = _kernels.count_at_most_from(s0, s, hint)
    return min(max(count - 1, 0), n_pieces - 1), count


def _merge_duplicates(
    waypoints: np.ndarray,
    max_deviation: float | np.ndarray,
    stop_at: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The first step of :meth:`BlendedPath.from_waypoints`: consecutive duplicates merged.
    Returns the waypoints (N, 3), rad, the index of each input waypoint among them, and
    per waypoint whether it is a stop (a stop on either copy is kept) and its deviation
    (the least of its copies'), rad."""
    w_in = np.asarray(waypoints, dtype=float)
    n_in = w_in.shape[0]
    dev_in = np.broadcast_to(np.asarray(max_deviation, dtype=float), (n_in,))
    stop_in = np.zeros(n_in, bool) if stop_at is None else np.asarray(stop_at, bool)

    # Merge consecutive duplicates; a stop on either copy is kept.
    keep = np.ones(n_in, bool)
    keep[1:] = np.linalg.norm(np.diff(w_in, axis=0), axis=1) > DUPLICATE_TOL
    if n_in > 1 and not keep[1:].any() and np.linalg.norm(w_in[-1] - w_in[0]) > 0.0:
        # start and end differ (a little): keep both ends exact; not when the difference
        # is so small (below ~1e-154 rad) that its length underflows to 0: that path is
        # one point, at its end
        keep[-1] = True
    index_map = np.cumsum(keep) - 1
    w = w_in[keep]
    w[-1] = w_in[-1]  # the path ends exactly on the last waypoint
    n = w.shape[0]
    if n == n_in and stop_in.shape == (n_in,):  # nothing merged: the same values, no .at
        return w, index_map, stop_in.copy(), np.array(dev_in, dtype=float)
    stop = np.zeros(n, bool)
    np.logical_or.at(stop, index_map, stop_in)
    dev = np.full(n, np.inf)
    np.minimum.at(dev, index_map, dev_in)
    return w, index_map, stop, dev


def _blend_tangents(
    seg_len: np.ndarray,
    seg_dir: np.ndarray,
    stop: np.ndarray,
    dev: np.ndarray,
    min_radius: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The second step of :meth:`BlendedPath.from_waypoints`: per vertex (N,), the turning
    angle (rad), the blend's tangent length ``l`` (rad, 0: not blended) of the method's
    docstring, and whether the path comes to rest there (the ends, stops, reversals and
    corners too tight for ``min_radius``), from the segments' lengths and unit directions."""
    n = seg_len.shape[0] + 1
    tangent = np.zeros(n)  # l at each vertex (0: not blended)
    alpha = np.zeros(n)
    alpha[1:-1] = np.arccos(np.clip(np.sum(seg_dir[:-1] * seg_dir[1:], axis=1), -1.0, 1.0))
    # vertices that take no blend whatever the lengths: the ends, stops, straight corners
    # and reversals; a blend next to one may take the whole segment, else half of it
    unblended = np.ones(n, bool)
    unblended[1:-1] = (
        stop[1:-1]
        | (dev[1:-1] <= 0.0)
        | (alpha[1:-1] > np.pi - REVERSAL_ANGLE)
        | (alpha[1:-1] < STRAIGHT_ANGLE)
    )
    share = np.where(unblended, 1.0, 0.5)
    is_stop = np.zeros(n, bool)
    is_stop[0] = is_stop[-1] = True
    for k in range(1, n - 1):
        a = float(alpha[k])
        if a < STRAIGHT_ANGLE and not stop[k]:
            continue
        if stop[k] or dev[k] <= 0.0 or a > np.pi - REVERSAL_ANGLE or a < STRAIGHT_ANGLE:
            is_stop[k] = True
            continue
        half = a / 2
        tangent[k] = min(
            seg_len[k - 1] * share[k - 1],
            seg_len[k] * share[k + 1],
            dev[k] / np.tan(half / 2),  # = delta sin(a/2) / (1 - cos(a/2))
        )
        if tangent[k] / np.tan(half) < min_radius:
            tangent[k] = 0.0
            is_stop[k] = True
    return alpha, tangent, is_stop


def _pieces(
    w: np.ndarray,
    seg_len: np.ndarray,
    seg_dir: np.ndarray,
    alpha: np.ndarray,
    tangent: np.ndarray,
) -> dict[str, np.ndarray]:
    """The last step of :meth:`BlendedPath.from_waypoints`: the lines and arcs of the path
    along ``s``, as the fields of :class:`BlendedPath` (``kind``, ``s0``, ``origin``,
    ``direction``, ``normal``, ``radius``, ``corner``, ``blend_deviation``, ``vertex_s``)."""
    n = w.shape[0]
    kind = np.empty(2 * n, np.int8)
    s_len, radius = np.empty(2 * n), np.empty(2 * n)
    origin, direction, normal = np.empty((2 * n, 3)), np.empty((2 * n, 3)), np.empty((2 * n, 3))
    corner = np.empty(2 * n, np.int64)
    vertex_s, blend_dev = np.zeros(n), np.zeros(n)
    count = _pieces_kernel(
        np.ascontiguousarray(w, dtype=float),
        np.ascontiguousarray(seg_len, dtype=float),
        np.ascontiguousarray(seg_dir, dtype=float),
        np.ascontiguousarray(alpha, dtype=float),
        np.ascontiguousarray(tangent, dtype=float),
        _PIECE_TOL,
        kind,
        s_len,
        origin,
        direction,
        normal,
        radius,
        corner,
        vertex_s,
        blend_dev,
    )
    return {
        "kind": kind[:count].copy(),
        "s0": np.concatenate([[0.0], np.cumsum(s_len[:count])]),
        "origin": origin[:count].copy(),
        "direction": direction[:count].copy(),
        "normal": normal[:count].copy(),
        "radius": radius[:count].copy(),
        "corner": corner[:count].astype(int),
        "blend_deviation": blend_dev,
        "vertex_s": vertex_s,
    }


@njit(cache=True)
def _pieces_kernel(
    w,
    seg_len,
    seg_dir,
    alpha,
    tangent,
    piece_tol,
    kind,
    s_len,
    origin,
    direction,
    normal,
    radius,
    corner,
    vertex_s,
    blend_dev,
):  # pragma: no cover
    """The loop of :func:`_pieces`, compiled: each segment's line (what its blends leave of
    it, unless only rounding is left) and the arc of its end vertex, into the arrays
    (2 N rows at most); returns the piece count."""
    n = w.shape[0]
    count = 0
    s = 0.0
    for i in range(n - 1):
        length = seg_len[i] - tangent[i] - tangent[i + 1]
        if i == 0 or tangent[i] == 0.0:
            vertex_s[i] = s
        if length > piece_tol:  # not the rounding left between two blends
            kind[count] = LINE
            s_len[count] = length
            for j in range(3):
                origin[count, j] = w[i, j] + tangent[i] * seg_dir[i, j]
                direction[count, j] = seg_dir[i, j]
                normal[count, j] = 0.0
            radius[count] = np.inf
            corner[count] = -1
            count += 1
            s += length
        k = i + 1
        if tangent[k] > 0.0:
            half = alpha[k] / 2
            r = tangent[k] / np.tan(half)
            bis = seg_dir[k] - seg_dir[k - 1]
            bis = bis / np.sqrt(bis[0] * bis[0] + bis[1] * bis[1] + bis[2] * bis[2])
            centre = w[k] + bis * (r / np.cos(half))
            x = (w[k] - tangent[k] * seg_dir[k - 1] - centre) / r
            x_norm = np.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
            kind[count] = ARC
            s_len[count] = r * alpha[k]
            for j in range(3):
                origin[count, j] = centre[j]
                direction[count, j] = x[j] / x_norm
                normal[count, j] = seg_dir[k - 1, j]
            radius[count] = r
            corner[count] = k
            count += 1
            blend_dev[k] = r * (1.0 / np.cos(half) - 1.0)
            vertex_s[k] = s + r * alpha[k] / 2
            s += r * alpha[k]
    vertex_s[n - 1] = s
    return count


def distance_to_polyline(
    waypoints: np.ndarray, q: np.ndarray, segments: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Euclidean joint-space distance of each posture to a polyline, and the nearest point.

    Parameters
    ----------
    waypoints : shape (N, 3), rad
    q : shape (M, 3), rad
    segments : shape (M, 2), int, optional
        For each posture, the first and last segment (segment i joins waypoints i and i+1)
        to measure against: the part of the plan it stands for. Default: every segment.

    Returns
    -------
    distance : shape (M,), rad
    nearest : shape (M, 3), rad
        The closest point of those segments to each posture.
    """
    w = np.asarray(waypoints, dtype=float)
    q = np.asarray(q, dtype=float)
    m, n_seg = q.shape[0], max(w.shape[0] - 1, 1)
    if w.shape[0] == 1:
        w = np.concatenate([w, w])
    if segments is None:
        segments = np.tile([0, n_seg - 1], (m, 1))
    lo = np.clip(segments[:, 0], 0, n_seg - 1)
    hi = np.clip(segments[:, 1], lo, n_seg - 1)
    best_d2 = np.full(m, np.inf)
    nearest = np.empty((m, 3))
    _nearest_on_segments(np.ascontiguousarray(w), np.ascontiguousarray(q), lo, hi, best_d2, nearest)
    return np.sqrt(best_d2), nearest


@njit(cache=True)
def _nearest_on_segments(w, q, lo, hi, best_d2, nearest):  # pragma: no cover
    """For each posture q[i], the least squared distance to the segments lo[i]..hi[i] of the
    polyline w (into best_d2, inf on entry) and the foot of the perpendicular (into nearest):
    the foot's parameter clipped to [0, 1] (0 on a segment of zero length); the first of
    equally near segments is kept."""
    foot = np.empty(3)
    for i in range(q.shape[0]):
        for seg in range(lo[i], hi[i] + 1):
            denom = 0.0
            dot = 0.0
            for j in range(3):
                ab = w[seg + 1, j] - w[seg, j]
                denom += ab * ab
                dot += (q[i, j] - w[seg, j]) * ab
            t = dot / max(denom, 1e-300) if denom > 0 else 0.0
            t = min(max(t, 0.0), 1.0)
            d2 = 0.0
            for j in range(3):
                foot[j] = w[seg, j] + t * (w[seg + 1, j] - w[seg, j])
                d2 += (q[i, j] - foot[j]) ** 2
            if d2 < best_d2[i]:
                best_d2[i] = d2
                for j in range(3):
                    nearest[i, j] = foot[j]
