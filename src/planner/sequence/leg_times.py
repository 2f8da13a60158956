"""Step 6 of a sequence (:mod:`planner.sequence.solve`): when the one trajectory reaches each
target (its rest instant, or its closest approach when passing through) and crosses each
working-mode transit of a leg, read from the trajectory itself."""

from __future__ import annotations

import numpy as np

from planner.planning import PlanPath
from planner.timing.trajectory import Curve, Trajectory

__all__ = ["SAMPLING_SLACK", "leg_times", "transit_times"]

#: How much farther than its ball a sampled closest approach may seem (rad): half the
#: 0.01 rad spacing of the samples :func:`leg_times` reads, and a little.
SAMPLING_SLACK = 0.006


def leg_times(
    trajectory: Trajectory,
    w: np.ndarray,
    at: list[int],
    stops: list[bool],
    reach: list[float],
    close: list[float],
) -> list[tuple[float, float, float]]:
    """Step 6: for each target in order, (time, distance, speed) where the trajectory
    reaches it: a stop at its rest instant, a pass-through at its first closest approach
    within ``close`` (its ball and the sampling's slack, rad), else within ``reach``, after
    the previous target. Sampled at the dense re-check's spacing and
    refined between the neighbouring samples."""
    curve = trajectory.curve
    t = np.union1d(curve.check_times(0.01), trajectory.t)
    q = curve.evaluate(t)[0]
    rests = np.concatenate([curve.rest_times(), [curve.duration]])
    out: list[tuple[float, float, float]] = []
    t_prev = 0.0
    for i, k in enumerate(at):
        target = w[k]
        after = t >= t_prev
        dist = np.where(after, np.linalg.norm(q - target, axis=1), np.inf)
        # the first closest approach (a local minimum of the distance) within the target's
        # ball (plus the sampling's slack), else within ``reach``: a pass-through whose blend
        # is near half its leg stays within reach through the next target and back (a
        # pick-and-place cycle passes each top corner twice), and a short first leg starts
        # within it, so neither the first sample within reach nor the overall minimum will do
        prev = np.concatenate([[np.inf], dist[:-1]])
        nxt = np.concatenate([dist[1:], [np.inf]])
        minima = np.flatnonzero(after & (dist <= prev) & (dist <= nxt))
        j = int(np.argmin(dist))
        for limit in (close[i], reach[i]):
            good = minima[dist[minima] <= limit]
            if good.size:
                j = int(good[0])
                break
        lo, hi = t[max(j - 1, 0)], t[min(j + 1, len(t) - 1)]
        fine = np.linspace(max(lo, t_prev), hi, 201)
        qf = curve.evaluate(fine)[0]
        m = int(np.argmin(np.linalg.norm(qf - target, axis=1)))
        t_k = _closest(curve, target, float(fine[max(m - 1, 0)]), float(fine[min(m + 1, 200)]))
        if stops[i]:
            r = rests[np.argmin(np.abs(rests - t_k))]
            if abs(r - t_k) <= max(hi - lo, 1e-9):
                t_k = float(r)
        qk, qdk = curve.evaluate(np.array([t_k]))[:2]
        out.append((t_k, float(np.linalg.norm(qk[0] - target)), float(np.linalg.norm(qdk[0]))))
        t_prev = t_k
    return out


def _closest(curve: Curve, target: np.ndarray, lo: float, hi: float) -> float:
    """The instant in [lo, hi] where ``curve`` is closest to ``target`` (bounded Brent, to
    1e-12 s): an exact pass-through (a via state on the target's posture) reads 0 there, not
    the grid's spacing times the speed."""
    from scipy.optimize import minimize_scalar

    if hi <= lo:
        return lo

    def dist(x: float) -> float:
        return float(np.linalg.norm(curve.evaluate(np.array([x]))[0][0] - target))

    best = minimize_scalar(dist, bounds=(lo, hi), method="bounded", options={"xatol": 1e-12})
    ends = [(dist(lo), lo), (dist(hi), hi), (float(best.fun), float(best.x))]
    return min(ends)[1]


def transit_times(curve: Curve, path: PlanPath, begin: float, end: float) -> tuple[float, ...]:
    """When the trajectory crosses each working-mode transit of a leg's path (``path.
    transits``, in order): its closest approach to the transit posture between the leg's
    ``begin`` and ``end``, after the previous transit (at rest there with
    ``stop_at_transits``; else within the corner allowance of it). Sampled every 1 ms,
    then refined between the neighbours of the closest sample."""
    out: list[float] = []
    lo = begin
    for tr in path.transits:
        q_tr = np.asarray(tr.q, dtype=float)
        a, b, best = lo, end, lo
        for n in (max(3, int((end - lo) / 1e-3) + 1), 201):
            t = np.linspace(a, b, n)
            j = int(np.argmin(np.linalg.norm(curve.evaluate(t)[0] - q_tr, axis=1)))
            best, a, b = float(t[j]), float(t[max(j - 1, 0)]), float(t[min(j + 1, n - 1)])
        out.append(best)
        lo = best
    return tuple(out)
