"""The validity rules of a planned path, for the timing: which postures near the path a timed
trajectory may pass through.

A path through transits leaves its segments' checkers at each crossing (the serial margin
cannot hold on a serial singular surface), and the timing's blends cut its corners; so a
trajectory near the path is held to the rules of :func:`path_state_checker`: the checker of
the posture's own working mode when that is one of the segments' modes, and, within the
corner allowance of a crossing, every non-serial rule with the two signs the transit keeps.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from planner.design import Design
from planner.geometry import Obstacle
from planner.kinematics import forward_batch, mode_signs
from planner.planning.mode_graph import FLIP_NAMES
from planner.planning.result import PlanPath
from planner.validity import Margins, ValidityChecker

__all__ = ["path_state_checker"]


def _mode_code(mode: str) -> int:
    """The integer of :func:`path_state_checker`'s sign-triple encoding for a mode label."""
    return sum((2 if ch == "+" else 0) * f for ch, f in zip(mode, (9, 3, 1), strict=True))


def path_state_checker(
    design: Design,
    margins: Margins,
    obstacles: Sequence[Obstacle],
    path: PlanPath,
    *,
    near: float = 0.0,
) -> Callable[[np.ndarray], np.ndarray]:
    """The validity rules of a planned path for a timed trajectory near it: Q (M, 3) ->
    valid (M,) bool.

    A posture is valid when it satisfies every rule of the checker of its own working mode,
    that mode being one of the path's segments'; or when it lies within ``near`` + 1e-9 rad
    (joint space) of a crossing (the motions q_in -> q_transit -> q_out of a transit), keeps
    the two working-mode signs that the transit does not flip, and satisfies every
    non-serial rule (``serial_rules=False``). ``near`` is the timing's corner allowance
    (``max_deviation``).
    """
    segs = path.segments
    asm = segs[0].assembly_mode if segs else "+"
    free = ValidityChecker(design, margins, obstacles, asm, "+++", serial_rules=False)
    checkers = {s.working_mode: free.with_mode(s.working_mode, serial_rules=True) for s in segs}
    w = np.asarray(path.waypoints, dtype=float)
    crossings = []
    for t in path.transits:
        if 0 < t.index < len(w) - 1:
            before = next(s.working_mode for s in segs if s.end_index == t.index)
            crossings.append((w[t.index - 1], w[t.index + 1], FLIP_NAMES.index(t.flipped), before))

    def check(q: np.ndarray) -> np.ndarray:
        q = np.atleast_2d(np.asarray(q, dtype=float))
        fb = forward_batch(design, q, asm)
        signs = fb.working_mode_signs
        valid = np.zeros(len(q), dtype=bool)
        code = (signs.astype(np.int64) + 1) @ np.array([9, 3, 1])  # one integer per sign triple
        for mode, chk in checkers.items():
            sel = code == _mode_code(mode)
            if sel.any():
                valid[sel] = chk.is_valid(q[sel])
        rest = ~valid
        if crossings and rest.any():
            free_ok = np.zeros(len(q), dtype=bool)
            free_ok[rest] = free.is_valid(q[rest])
            for a, b, j, before in crossings:
                ab = b - a
                t = np.clip((q - a) @ ab / float(ab @ ab), 0.0, 1.0)
                dist = np.linalg.norm(a + t[:, None] * ab - q, axis=1)
                others = [k for k in range(3) if k != j]
                want = mode_signs(before)[others]
                keep = np.all(signs[:, others] == want, axis=1)
                valid |= rest & free_ok & keep & (dist <= near + 1e-9)
        return valid

    return check
