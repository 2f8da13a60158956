"""Serial-singularity crossings: when the straight motion through a transit posture is a
valid change of working mode.

A transit posture q_transit lies on a serial singular surface, where one signed measure of
(s_axis, s_A, s_B) vanishes. It is crossed by the straight motion q_in -> q_transit -> q_out
along the gradient of that measure (:func:`planner.transits.crossing_through`). The
mode-change search (:mod:`planner.planning.mode_change`) keeps a crossing when q_in and q_out
are valid in their segments' checkers, both motions are certified by a ``serial_rules=False``
checker, and the dense walk of :func:`crossing_signs_hold` (every :data:`CROSSING_CHECK_STEP`
rad) finds the flipped measure with its 'before' sign up to the transit and the other sign
after it, and the two other measures >= ``margins.serial_min`` all along.
"""

from __future__ import annotations

import numpy as np

from planner.design import Design
from planner.kinematics import forward_batch, mode_signs
from planner.transits import Crossing
from planner.validity import densify

__all__ = ["CROSSING_CHECK_STEP", "crossing_signs_hold"]

#: Joint-space step (max-norm, rad) of the dense sign walk along a crossing.
CROSSING_CHECK_STEP = 0.002


def crossing_signs_hold(
    design: Design,
    c: Crossing,
    before: str,
    after: str,
    j: int,
    asm: str,
    serial_min: float,
    *,
    step: float = CROSSING_CHECK_STEP,
) -> bool:
    """Dense walk along a crossing: the flipped measure j has ``before``'s sign strictly
    before the transit and ``after``'s strictly after it; the two others keep their (shared)
    signs with magnitude >= ``serial_min``; every posture assembles."""
    halves = (
        densify(np.stack([c.q_in, c.q_transit]), step)[:-1],
        densify(np.stack([c.q_transit, c.q_out]), step)[1:],
    )
    for line, mode in zip(halves, (before, after), strict=True):
        b = forward_batch(design, line, asm)
        if not b.ok.all():
            return False
        signs = mode_signs(mode).astype(float)
        m = b.serial_measures * signs
        if not np.all(m[:, j] > 0):
            return False
        others = [k for k in range(3) if k != j]
        if not np.all(m[:, others] >= serial_min):
            return False
    return True
