"""The walk along a Cartesian polyline in one working mode: the polyline parameterised by arc
length, the inverse kinematics of the mode's branch at its points, joint values unwrapped
continuously from the start, and the narrowing of a bracket where a rule changes.

The polyline (:class:`Polyline`) starts at P of the start posture and runs through the
waypoints in order. Its points are turned into postures by the inverse kinematics of the
start's working mode (:func:`branch_ik`: one branch, the mode's sign triple fixes it; a point
where the branch does not exist or changes assembly mode has none), unwrapped towards a
reference (:func:`unwrap_to`, :func:`unwrap_chain`). :class:`Walker` holds what the steps of
:func:`planner.cartesian.plan.plan_cartesian` share; :func:`narrow_bracket` locates the
first change of a rule between two probes (:data:`PROBE_STEP` apart) to :data:`BISECT_TOL`,
for the plan and for :func:`planner.cartesian.inspection.inspect_cartesian`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from planner import _kernels
from planner.constants import ASSEMBLY_TOL
from planner.design import Design
from planner.exceptions import InputError
from planner.kinematics import inverse_in_mode
from planner.timing.path import BlendedPath, distance_to_polyline, piece_of, point_on_piece

__all__ = [
    "BISECT_TOL",
    "NARROW_POINTS",
    "PROBE_STEP",
    "Polyline",
    "Walker",
    "as_points",
    "branch_ik",
    "distance_to_polyline_3d",
    "max_deviation_along",
    "narrow_bracket",
    "unwrap_chain",
    "unwrap_to",
]

#: Spacing of the rule probes along the polyline, m (the first broken rule is located within
#: this, then bisected to :data:`BISECT_TOL`).
PROBE_STEP = 2e-3
#: Bisection tolerance on the stopping point along the polyline, m.
BISECT_TOL = 1e-8
#: Points classified at once per round of :func:`narrow_bracket` (one batched inverse kinematics
#: each): a bracket shrinks by NARROW_POINTS + 1 per round, 3 rounds from PROBE_STEP to
#: BISECT_TOL where bisection takes 18 single-point steps.
NARROW_POINTS = 64


def as_points(waypoints: object) -> np.ndarray:
    try:
        w = np.asarray(waypoints, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"waypoints must be numbers, got {waypoints!r}") from exc
    if w.ndim == 1 and w.shape == (3,):
        w = w[None]
    if w.ndim != 2 or w.shape[1] != 3 or w.shape[0] < 1:
        raise InputError(f"waypoints must have shape (K, 3) with K >= 1, got {w.shape}")
    if not np.all(np.isfinite(w)):
        raise InputError("waypoints must be finite (no NaN or infinity)")
    return w


class Polyline:
    """A Cartesian polyline parameterised by arc length s (m)."""

    def __init__(self, vertices: np.ndarray) -> None:
        seg = np.diff(vertices, axis=0)
        lengths = np.linalg.norm(seg, axis=1)
        keep = np.concatenate([[True], lengths > 1e-12])  # drop repeated points
        self.vertices = vertices[keep]
        seg = np.diff(self.vertices, axis=0)
        self.lengths = np.linalg.norm(seg, axis=1)
        self.cum = np.concatenate([[0.0], np.cumsum(self.lengths)])
        self.length = float(self.cum[-1])
        self.dirs = seg / np.maximum(self.lengths, 1e-300)[:, None]
        # index of each kept vertex among the given ones (for segment numbers in messages)
        self.given_index = np.flatnonzero(keep)

    def segment_of(self, s: np.ndarray) -> np.ndarray:
        i = np.searchsorted(self.cum, s, side="right") - 1
        return np.clip(i, 0, max(len(self.lengths) - 1, 0))

    def at(self, s: np.ndarray) -> np.ndarray:
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.length)
        if self.length == 0.0:
            return np.broadcast_to(self.vertices[0], (*s.shape, 3)).copy()
        i = self.segment_of(s)
        return self.vertices[i] + (s - self.cum[i])[..., None] * self.dirs[i]


def distance_to_polyline_3d(vertices: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance of each point (M, 3) to the polyline through ``vertices`` (K, 3), m.

    Exact: the least point-segment distance over the segments (a single vertex: the distance
    to it); :func:`planner.timing.path.distance_to_polyline`'s compiled pass, which measures
    any 3-vectors (there, joint postures).
    """
    v = np.asarray(vertices, dtype=float)
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    return distance_to_polyline(v, pts)[0]


def max_deviation_along(
    design: Design, path: BlendedPath, s: np.ndarray, assembly_mode: str, vertices: np.ndarray
) -> float:
    """Largest distance of P from the polyline through ``vertices`` (K, 3) over the postures
    of ``path`` at arc lengths ``s`` (any order, repeats allowed), m; inf when one of them
    does not assemble in ``assembly_mode``.

    The same number as ``max(distance_to_polyline_3d(vertices, forward_batch(design,
    path.evaluate_all(s)[0], assembly_mode).p))``, bit for bit (the same arithmetic in the
    same order; ``tests/planning/test_cartesian.py``), in one compiled pass: no array of
    postures, of points or of distances, no passive angles (the answer of a 0.6 m line
    measures ~4000 postures)."""
    w = np.asarray(vertices, dtype=float)
    if w.shape[0] == 1:
        w = np.concatenate([w, w])
    if path.n_pieces == 0:
        s = np.zeros(1)
    return float(
        _max_deviation_kernel(
            _kernels.read_only(s),
            _kernels.read_only(path.s0),
            _kernels.read_only(path.kind, np.int8),
            _kernels.read_only(path.origin),
            _kernels.read_only(path.direction),
            _kernels.read_only(path.normal),
            _kernels.read_only(path.radius),
            _kernels.read_only(path.waypoints[0]),
            path.n_pieces,
            design.L0,
            design.L1,
            design.L2,
            1.0 if assembly_mode == "+" else -1.0,
            ASSEMBLY_TOL,
            _kernels.read_only(w),
        )
    )


@njit(cache=True, nogil=True, error_model="numpy")
def _max_deviation_kernel(
    s, s0, kind, origin, direction, normal, radius, q_rest, n_pieces, L0, L1, L2, branch, tol, w
):  # pragma: no cover - compiled
    """:func:`max_deviation_along`'s pass: per position, the piece
    (:func:`~planner.timing.path.piece_of`), the posture on it
    (:func:`~planner.timing.path.point_on_piece`), P (the loop closure of
    :func:`planner._kernels.forward_kernel`) and its least squared distance to the segments
    (:func:`planner.timing.path._nearest_on_segments`' arithmetic: NaN never replaces inf)."""
    q, p = np.empty(3), np.empty(3)
    worst = 0.0
    hint = 0
    for m in range(s.shape[0]):
        if n_pieces == 0:
            q[0], q[1], q[2] = q_rest[0], q_rest[1], q_rest[2]
        else:
            k, hint = piece_of(s0, n_pieces, s[m], hint)
            q[0], q[1], q[2] = point_on_piece(
                k, s[m] - s0[k], kind, origin, direction, normal, radius
            )[:3]
        closes, _, _, _, _, pu, pw, _ = _kernels.close_loop(L0, L1, L2, q[1], q[2], branch, tol)
        if closes:
            p[0], p[1], p[2] = pw * math.cos(q[0]), pu, -pw * math.sin(q[0])
        else:
            p[0] = p[1] = p[2] = np.nan
        best = np.inf
        for seg in range(w.shape[0] - 1):
            denom = 0.0
            dot = 0.0
            for j in range(3):
                ab = w[seg + 1, j] - w[seg, j]
                denom += ab * ab
                dot += (p[j] - w[seg, j]) * ab
            t = dot / max(denom, 1e-300) if denom > 0 else 0.0
            t = min(max(t, 0.0), 1.0)
            d2 = 0.0
            for j in range(3):
                foot = w[seg, j] + t * (w[seg + 1, j] - w[seg, j])
                d2 += (p[j] - foot) ** 2
            if d2 < best:
                best = d2
        dist = math.sqrt(best)
        if dist > worst:
            worst = dist
    return worst


def branch_ik(design: Design, pts: np.ndarray, slot: int, asm_sign: int):
    """IK of points (M, 3) in one working-mode slot: q wrapped (M, 3), ok (M,), w (M,),
    flipped (M,) (the branch exists but in the other assembly mode)."""
    q, _, w, ok, degenerate, asm = inverse_in_mode(design, pts, slot)
    ok = ok & ~degenerate
    flipped = ok & (asm != asm_sign)
    return q, ok & ~flipped, w, flipped


def unwrap_to(q: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """q shifted by multiples of 2 pi per joint to be nearest ``ref``."""
    return q + 2 * np.pi * np.round((ref - q) / (2 * np.pi))


def unwrap_chain(q: np.ndarray, q0: np.ndarray) -> np.ndarray:
    """Postures ``q`` (M, 3) each unwrapped towards the one before it (``q0`` before the first),
    vectorised: ``q0`` plus the cumulative sum of wrapped differences."""
    d = np.diff(np.vstack([q0[None], q]), axis=0)
    d = d - 2 * np.pi * np.round(d / (2 * np.pi))
    return q0 + np.cumsum(d, axis=0)


def narrow_bracket(
    a: float,
    b: float,
    classify,
    tol: float,
    q_b: np.ndarray | None = None,
    reason_b: str = "",
) -> tuple[float, float, np.ndarray | None, str]:
    """Shrink a bracket [a, b] (m along the polyline) of a change of a rule to ``b - a <= tol``.

    ``classify(s)`` takes arc lengths (M,) inside the bracket and returns ``(same, q,
    reason)``: ``same`` (M,) bool, True where s is on a's side of the change; ``q`` (M, 3) the
    posture there (NaN where none); ``reason`` (M,) the rule broken there. Each round
    classifies :data:`NARROW_POINTS` evenly spaced interior points at once and keeps the
    interval from the last point on a's side before the first point on b's side to that
    point, so the change found is the first one the points see (as with bisection, two
    changes closer than a round's spacing can hide each other). Returns ``(a, b, q_b,
    reason_b)``: the final bracket and the posture and rule at its end (the given ones when
    b never moved)."""
    while b - a > tol:
        s = a + (b - a) * np.arange(1, NARROW_POINTS + 1) / (NARROW_POINTS + 1)
        same, q, reason = classify(s)
        if np.all(same):
            a = float(s[-1])
            continue
        j = int(np.argmax(~same))
        if j > 0:
            a = float(s[j - 1])
        b = float(s[j])
        q_b = q[j] if np.all(np.isfinite(q[j])) else None
        reason_b = str(reason[j])
    return a, b, q_b, reason_b


class Walker:
    """State shared by the steps of :func:`planner.cartesian.plan.plan_cartesian`."""

    def __init__(self, design, checker, poly, q0, slot, asm_sign):
        self.design = design
        self.checker = checker
        self.poly = poly
        self.q0 = q0
        self.slot = slot
        self.asm_sign = asm_sign

    def posture_at(self, s: np.ndarray, ref: np.ndarray):
        """(q unwrapped towards ref (M, 3), ok (M,), w (M,), flipped (M,)) at arc lengths s."""
        pts = self.poly.at(s)
        q, ok, w, flipped = branch_ik(self.design, pts, self.slot, self.asm_sign)
        q = np.where(ok[:, None], unwrap_to(q, ref), np.nan)
        return q, ok, w, flipped

    def probe_valid(self, s: np.ndarray, ref: np.ndarray):
        """Validity of the IK postures at arc lengths s (M,), unwrapped towards ``ref``:
        (valid (M,), q (M, 3), reason (M,)); the reason is "workspace" or "assembly" where the
        working mode's branch does not reach the point (or changes assembly mode)."""
        q, ok, _, flipped = self.posture_at(np.asarray(s, dtype=float), ref)
        valid = np.zeros(q.shape[0], dtype=bool)
        reason = np.where(flipped, "assembly", "workspace").astype(object)
        if np.any(ok):
            rep = self.checker.check_states(q[ok])
            valid[ok] = rep.valid
            reason[ok] = rep.reason
        return valid, q, reason
