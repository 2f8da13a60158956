"""Factories shared by the timing tests: seeded joint paths and small validity checkers."""

from __future__ import annotations

import itertools

import numpy as np

from planner import Design, conditioning, forward_batch


def random_walk(seed: int, n: int = 6, step: float = 0.5, bound: float = 2.5) -> np.ndarray:
    """A seeded joint-space polyline, shape (n, 3), rad: steps uniform in [-step, step] per
    joint, kept inside [-bound, bound]."""
    rng = np.random.default_rng(seed)
    return np.clip(np.cumsum(rng.uniform(-step, step, size=(n, 3)), axis=0), -bound, bound)


def box_checker(lo: np.ndarray, hi: np.ndarray):
    """check_states rejecting the postures inside the joint-space box [lo, hi]."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)

    def check(q: np.ndarray) -> np.ndarray:
        return ~np.all((q >= lo) & (q <= hi), axis=1)

    return check


def kappa_checker(design: Design, kappa_max: float, assembly_mode: str = "+"):
    """check_states: the posture assembles and kappa(A) <= kappa_max (parallel margin)."""

    def check(q: np.ndarray) -> np.ndarray:
        batch = forward_batch(design, q, assembly_mode)
        cond = conditioning(design, batch.q, batch.passive, batch.w)
        return batch.ok & (np.nan_to_num(cond.kappa_A, nan=np.inf) <= kappa_max)

    return check


def fine_times(duration: float, n: int = 20001) -> np.ndarray:
    """A uniform time grid on [0, duration], independent of the library's check times."""
    return np.linspace(0.0, duration, n)


def segment_distance_to_polyline(waypoints: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Exact distance of each posture to the polyline (independent of the library): the
    closest point of every segment (the projection clamped to the segment), the least over
    the segments. Exact where :func:`brute_distance_to_polyline` overestimates by up to half
    its sample spacing, and a thousand times cheaper on 20,000 postures: the timing tests'
    deviation checks use it (a pass with it is a pass of the rule itself, not of a sample)."""
    q = np.asarray(q, float)
    out = np.full(q.shape[0], np.inf)
    for a, b in itertools.pairwise(np.asarray(waypoints, float)):
        ab = b - a
        length2 = float(ab @ ab)
        s = np.zeros(q.shape[0]) if length2 == 0.0 else np.clip((q - a) @ ab / length2, 0, 1)
        np.minimum(out, np.linalg.norm(q - a - s[:, None] * ab, axis=1), out=out)
    return out


def brute_distance_to_polyline(waypoints: np.ndarray, q: np.ndarray, per_seg: int = 2000):
    """Distance of each posture to a densely sampled polyline (independent of the library,
    and of :func:`segment_distance_to_polyline`'s projection: the check of the library's own
    projection uses it)."""
    pts = np.concatenate([np.linspace(a, b, per_seg) for a, b in itertools.pairwise(waypoints)])
    out = np.empty(q.shape[0])
    for i in range(0, q.shape[0], 500):
        d = np.linalg.norm(q[i : i + 500, None, :] - pts[None], axis=2)
        out[i : i + 500] = d.min(axis=1)
    return out
