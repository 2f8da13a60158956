"""Step 4 of a sequence (:mod:`planner.sequence.solve`): the legs' paths joined into one, the
targets that cannot be passed at speed found, and an exact pass-through (blend 0) made smooth
by two short straight pieces around the target. The blends are fitted to the joined legs by
:mod:`planner.sequence.blends`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from planner.planning import PlanPath, PlanResult, Segment, Transit

__all__ = ["EXACT_CORRIDOR", "PASS_OFFSET", "join_legs", "smooth_pass_through", "turning_back"]

#: An exact pass-through (blend 0) at a corner: the path runs straight through the target
#: over this distance on either side (rad; at most a quarter of the adjacent segments), and
#: the two new corners there are blended as any other.
PASS_OFFSET = 0.05
#: How far (rad) the moves of a via chain through an exact pass-through (blend 0) may leave
#: the planned segments: the via posture is the target's own, its velocity free, and the
#: moves between the vias run within this corridor of the plan (checked densely against the
#: path's validity rules, as every trajectory is); the same scale as :data:`PASS_OFFSET`.
EXACT_CORRIDOR = 0.05
#: A corner turning by more than pi minus this (rad) cannot be passed at speed: the target
#: is a stop (the timing could not blend it either).
_REVERSAL = 1e-3


def join_legs(start_q: np.ndarray, plans: Sequence[PlanResult]) -> tuple[PlanPath, list[int]]:
    """Step 4: the legs' paths as one path (segments of one working mode merged across a
    target, transits shifted), and each target's waypoint index in it."""
    w = [np.asarray(start_q, dtype=float)]
    segs: list[Segment] = []
    transits: list[Transit] = []
    at: list[int] = []
    for plan in plans:
        path = plan.path
        assert path is not None
        off = len(w) - 1
        w.extend(np.asarray(path.waypoints, dtype=float)[1:])
        for s in path.segments:
            s = replace(s, start_index=s.start_index + off, end_index=s.end_index + off)
            last = segs[-1] if segs else None
            if (
                last is not None
                and last.working_mode == s.working_mode
                and last.end_index == s.start_index
            ):
                segs[-1] = replace(last, end_index=s.end_index)
            else:
                segs.append(s)
        transits += [replace(t, index=t.index + off) for t in path.transits]
        at.append(len(w) - 1)
    return PlanPath(np.array(w), tuple(segs), tuple(transits)), at


def turning_back(w: np.ndarray, at: list[int], passes: list[bool]) -> list[int]:
    """The pass-through targets that cannot be passed at speed: the path turns back there
    (a corner within :data:`_REVERSAL` of pi) or does not move on either side (a leg of
    zero length). They are stops."""
    out = []
    for i, k in enumerate(at):
        if not passes[i]:
            continue
        if k <= 0 or k >= len(w) - 1:
            out.append(i)
            continue
        d_in, d_out = w[k] - w[k - 1], w[k + 1] - w[k]
        l_in, l_out = float(np.linalg.norm(d_in)), float(np.linalg.norm(d_out))
        if l_in == 0.0 or l_out == 0.0:
            out.append(i)
            continue
        cos = float(np.clip(d_in @ d_out / (l_in * l_out), -1.0, 1.0))
        if math.acos(cos) > math.pi - _REVERSAL:
            out.append(i)
    return out


def smooth_pass_through(
    path: PlanPath, at: list[int], exact: list[bool]
) -> tuple[PlanPath, list[int]]:
    """An exact pass-through target (blend 0) at a corner: the waypoints
    ``T - e b`` and ``T + e b`` inserted around it (``b`` the corner's bisecting direction,
    ``e`` = :data:`PASS_OFFSET` or a quarter of the shorter segment), so the path runs
    straight through T and the trajectory passes it exactly, at speed (a target where the
    path turns back is a stop already, :func:`turning_back`). Returns the new path and the
    targets' new waypoint indices."""
    w = np.asarray(path.waypoints, dtype=float)
    insert: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for i, k in enumerate(at):
        if not exact[i] or k <= 0 or k >= len(w) - 1:
            continue
        d_in, d_out = w[k] - w[k - 1], w[k + 1] - w[k]
        l_in, l_out = float(np.linalg.norm(d_in)), float(np.linalg.norm(d_out))
        if l_in == 0.0 or l_out == 0.0:
            continue
        u1, u2 = d_in / l_in, d_out / l_out
        angle = math.acos(float(np.clip(u1 @ u2, -1.0, 1.0)))
        if angle < 1e-9 or angle > math.pi - _REVERSAL:
            continue  # straight already, or a stop
        b = (u1 + u2) / np.linalg.norm(u1 + u2)
        e = min(PASS_OFFSET, 0.25 * l_in, 0.25 * l_out)
        insert[k] = (w[k] - e * b, w[k] + e * b)
    if not insert:
        return path, list(at)
    new_index = np.zeros(len(w), dtype=int)
    rows: list[np.ndarray] = []
    for k, q in enumerate(w):
        if k in insert:
            rows.append(insert[k][0])
        new_index[k] = len(rows)
        rows.append(q)
        if k in insert:
            rows.append(insert[k][1])

    # the point inserted before a target lies in the segment that ends there, the one after
    # it in the segment that starts there
    segs = tuple(
        replace(s, start_index=int(new_index[s.start_index]), end_index=int(new_index[s.end_index]))
        for s in path.segments
    )
    transits = tuple(replace(t, index=int(new_index[t.index])) for t in path.transits)
    return PlanPath(np.array(rows), segs, transits), [int(new_index[k]) for k in at]
