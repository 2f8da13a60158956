"""The graph of working modes: which modes a plan may pass through on its way to the goal's.

A working mode changes only by crossing a serial singularity, which flips exactly one sign of
(s_axis, s_A, s_B) (``docs/conventions.md``); the assembly mode never changes (that would cross a
parallel singularity). So the 8 working modes of one assembly mode are the corners of a cube,
joined by an edge where one sign differs.

*Mode sequences* (:func:`mode_sequences`): walks over that graph from the start's mode to a
mode where the goal is valid, without revisiting a mode, with at most :data:`MAX_DETOUR` flips
more than the signs that differ; every order of the flips is a walk. The mode-change search
(:mod:`planner.planning.mode_change`) orders them by number of transits, then by an
estimated cost.
"""

from __future__ import annotations

from collections.abc import Sequence

__all__ = ["FLIP_NAMES", "MAX_DETOUR", "flipped_sign", "mode_sequences"]

#: Extra flips allowed beyond the signs that differ (a sign flipped there and back).
MAX_DETOUR = 2
#: The measure whose sign each character of a working-mode label holds, in order (the
#: ``flipped`` of a transit).
FLIP_NAMES = ("axis", "A", "B")


def flipped_sign(before: str, after: str) -> int:
    """Index (into :data:`FLIP_NAMES`) of the sign that differs between two adjacent modes."""
    return next(i for i in range(3) if before[i] != after[i])


def _flip(mode: str, j: int) -> str:
    return mode[:j] + ("-" if mode[j] == "+" else "+") + mode[j + 1 :]


def mode_sequences(start_mode: str, goal_modes: Sequence[str], *, detour: int = MAX_DETOUR):
    """Walks over the mode graph from ``start_mode`` to any of ``goal_modes``.

    Each walk is a tuple of modes (start first) in which consecutive modes differ by one sign
    and no mode repeats; at most ``hamming + detour`` flips. Ordered by number of flips
    (fewest first), then lexicographically (the planner re-orders equal lengths by cost).
    """
    goals = set(goal_modes)
    out: list[tuple[str, ...]] = []

    def walk(path: tuple[str, ...], limit: int) -> None:
        if path[-1] in goals and len(path) > 1:
            out.append(path)
        if len(path) - 1 >= limit:
            return
        for j in range(3):
            nxt = _flip(path[-1], j)
            if nxt not in path:
                walk((*path, nxt), limit)

    for g in goals:
        hamming = sum(a != b for a, b in zip(start_mode, g, strict=True))
        walk((start_mode,), hamming + detour)
    unique = sorted(set(out), key=lambda p: (len(p), p))
    return [p for p in unique if p[-1] in goals]
