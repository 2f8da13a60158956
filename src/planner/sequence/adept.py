"""The Adept cycle, the field's pick-and-place benchmark for parallel robots, placed in a
design's workspace: up h, across d, down h, and back the same way (25 / 305 / 25 mm for a
robot of a metre's reach), scaled by the design's reach (L1 + L2).

Shared by the sequences' benchmark (``benchmarks/sequences.py``: its cycle time) and the
design-side dynamics (``planner inertia-report``: the torques of the cycle), so that both
time the same motion.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from planner.design import Design
from planner.kinematics import WORKING_MODES, inverse_batch
from planner.planning import CartesianTarget, JointPosture
from planner.sequence.problem import SequenceResult, SequenceTarget
from planner.sequence.solve import solve_sequence

__all__ = ["ADEPT_ACROSS", "ADEPT_UP", "AdeptCycle", "adept_targets", "place_adept_cycle"]

#: The Adept cycle for a robot of a metre's reach, m: up (and down), across.
ADEPT_UP, ADEPT_ACROSS = 0.025, 0.305


def adept_targets(
    pick: np.ndarray,
    h: float,
    d: float,
    modes: Sequence[str],
    stops: Sequence[bool],
    blends: Sequence[float],
) -> list[SequenceTarget]:
    """The cycle's five targets from the pick point (3,), m: up h, across d along +y, down
    (place), up, across back; ``cycle=True`` returns to the pick. ``modes``, ``stops`` and
    ``blends`` give each target's working mode, stop flag and blend (rad)."""
    pick = np.asarray(pick, dtype=float)
    up_a, up_b, place = (pick + np.array(v) for v in ([0, 0, h], [0, d, h], [0, d, 0]))
    points = [up_a, up_b, place, up_b, up_a]
    return [
        SequenceTarget(CartesianTarget(p, m), stop=s, blend=b)
        for p, m, s, b in zip(points, modes, stops, blends, strict=True)
    ]


class AdeptCycle(NamedTuple):
    """A placed, solved all-stops Adept cycle (:func:`place_adept_cycle`)."""

    pick: np.ndarray  #: shape (3,), m -- the pick point
    start: JointPosture  #: the pick point's posture (s_axis '+', assembly mode '+')
    h: float  #: up, m
    d: float  #: across, m
    result: SequenceResult  #: the solved cycle, every target a stop


def place_adept_cycle(design: Design, **solve_options: Any) -> AdeptCycle:
    """The first pick point of a fixed grid of the workspace whose all-stops Adept cycle
    solves, with its start posture (the pick point in the first working mode with
    s_axis = '+' that reaches it, assembly mode '+'). ``solve_options`` go to
    :func:`~planner.sequence.solve_sequence` (e.g. ``timing``, ``limits``, ``inertia``).

    Raises
    ------
    LookupError
        No placement of the grid solves.
    """
    h, d = ADEPT_UP * design.reach, ADEPT_ACROSS * design.reach
    for x, z, y in itertools.product(
        (0.35, 0.45, 0.25, 0.55), (-0.45, -0.35, -0.55, -0.25), (-0.15, -0.25, -0.05, 0.0)
    ):
        pick = np.array([x, y, z]) * design.reach / 0.8
        ik = inverse_batch(design, pick)
        for k in np.flatnonzero(ik.ok[0]):
            if WORKING_MODES[k][0] != "+":
                continue
            start = JointPosture(ik.q[0, k], "+")
            targets = adept_targets(pick, h, d, ["any"] * 5, [True] * 5, [0.0] * 5)
            r = solve_sequence(
                design, start, targets, cycle=True, objective="fixed", **solve_options
            )
            if r.solved:
                return AdeptCycle(pick, start, h, d, r)
    raise LookupError("no placement of the Adept cycle solved")
