"""Serial-singularity transits: the postures through which a working mode changes.

A working mode (s_axis, s_A, s_B) can only change by crossing a serial singularity, which
flips exactly one sign (``docs/conventions.md``):

=================== ========= ==================================================
kind                flipped   surface in joint space
=================== ========= ==================================================
``P_on_axis``       ``axis``  w = 0 (P on the line AB; theta1 is free there)
``leg_A_stretched`` ``A``     theta4 = theta2 (C on segment AP, |AP| = L1 + L2)
``leg_A_folded``    ``A``     theta4 = theta2 + pi (|AP| = |L2 - L1|)
``leg_B_stretched`` ``B``     theta5 = theta3
``leg_B_folded``    ``B``     theta5 = theta3 + pi
=================== ========= ==================================================

In joint space, with the assembly mode fixed, the direct kinematics is smooth away from
parallel singularities, so each surface is the zero set of a smooth measure
f(q) (w, sin(theta4 - theta2) or sin(theta5 - theta3)) and a straight joint-space motion
that crosses it transversally flips that sign once. This module samples those surfaces
(pure numpy, vectorised) and builds the straight crossing through a chosen posture; which
candidates are valid (limits, clearance, kappa(A)) is the validity checker's business.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from planner.design import Design
from planner.exceptions import InputError
from planner.kinematics import forward_batch, inverse_batch, mode_signs

__all__ = [
    "FLIPPED_SIGN",
    "TRANSIT_KINDS",
    "Crossing",
    "crossing_through",
    "kinds_flipping",
    "sample_transits",
    "serial_measure",
    "transit_kind",
]

TransitKind = Literal[
    "P_on_axis", "leg_A_stretched", "leg_A_folded", "leg_B_stretched", "leg_B_folded"
]
Flipped = Literal["axis", "A", "B"]

#: Every transit kind, in a fixed order.
TRANSIT_KINDS: tuple[str, ...] = (
    "P_on_axis",
    "leg_A_stretched",
    "leg_A_folded",
    "leg_B_stretched",
    "leg_B_folded",
)
#: The working-mode sign each kind flips.
FLIPPED_SIGN: dict[str, str] = {
    "P_on_axis": "axis",
    "leg_A_stretched": "A",
    "leg_A_folded": "A",
    "leg_B_stretched": "B",
    "leg_B_folded": "B",
}
_SIGN_INDEX = {"axis": 0, "A": 1, "B": 2}


def kinds_flipping(flipped: str) -> tuple[str, ...]:
    """Transit kinds that flip the given sign ('axis', 'A' or 'B')."""
    if flipped not in _SIGN_INDEX:
        raise InputError(f"flipped must be 'axis', 'A' or 'B', got {flipped!r}")
    return tuple(k for k in TRANSIT_KINDS if FLIPPED_SIGN[k] == flipped)


def serial_measure(design: Design, q: np.ndarray, assembly_mode: str, flipped: str) -> np.ndarray:
    """The signed measure whose sign is the working-mode component ``flipped``, for postures
    q (N, 3): w / (L1 + L2), sin(theta4 - theta2) or sin(theta5 - theta3). NaN where q does
    not assemble."""
    batch = forward_batch(design, np.atleast_2d(q), assembly_mode)
    return batch.serial_measures[:, _SIGN_INDEX[flipped]]


def transit_kind(design: Design, q: np.ndarray, assembly_mode: str, flipped: str) -> str:
    """Name of the serial singularity a transit posture q sits on (stretched or folded for a
    leg, by the sign of cos(theta_distal - theta_proximal))."""
    if flipped == "axis":
        return "P_on_axis"
    batch = forward_batch(design, np.atleast_2d(q), assembly_mode)
    leg = _SIGN_INDEX[flipped]
    c = np.cos(batch.passive[0, leg - 1] - batch.q[0, leg])
    return f"leg_{flipped}_{'stretched' if c > 0 else 'folded'}"


def sample_transits(
    design: Design,
    kind: str,
    *,
    working_mode: str,
    assembly_mode: str,
    n: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Postures on the singular surface ``kind`` whose other two working-mode signs are those
    of ``working_mode`` (its sign at the flipped position is ignored), in ``assembly_mode``
    and inside the joint limits.

    Parameters
    ----------
    kind : one of :data:`TRANSIT_KINDS`
    working_mode : '+-+'-style, the mode on either side of the transit
    n : number of surface points drawn (fewer come back: those outside reach, limits or the
        assembly mode are dropped)

    Returns
    -------
    q : shape (M, 3), rad, M <= n
    """
    if kind not in TRANSIT_KINDS:
        raise InputError(f"kind must be one of {TRANSIT_KINDS}, got {kind!r}")
    if len(working_mode) != 3 or any(c not in "+-" for c in working_mode):
        raise InputError(f"working_mode must be 3 of '+'/'-', got {working_mode!r}")
    flipped = FLIPPED_SIGN[kind]
    lo, hi = np.array(design.joint_min), np.array(design.joint_max)
    t1 = rng.uniform(lo[0], hi[0], n)
    if kind == "P_on_axis":
        # P = (0, u, 0): u where both legs reach
        radius = (abs(design.L1 - design.L2), design.L1 + design.L2)
        u_lo = max(-design.L0 / 2 - radius[1], design.L0 / 2 - radius[1])
        u_hi = min(-design.L0 / 2 + radius[1], design.L0 / 2 + radius[1])
        u = rng.uniform(u_lo, u_hi, n)
        u = u[(np.abs(u + design.L0 / 2) >= radius[0]) & (np.abs(u - design.L0 / 2) >= radius[0])]
        p = np.stack([np.zeros_like(u), u, np.zeros_like(u)], axis=1)
        ib = inverse_batch(design, p)
        # on the axis only the '+' axis slot exists; theta1 is free: use the sampled one
        slot = (0 if working_mode[1] == "+" else 2) + (0 if working_mode[2] == "+" else 1)
        q = ib.q[ib.ok[:, slot], slot].copy()
        q[:, 0] = t1[: len(q)]
    else:
        leg = kind[4]
        pivot_u = -design.L0 / 2 if leg == "A" else design.L0 / 2
        dist = design.L1 + design.L2 if kind.endswith("stretched") else design.L1 - design.L2
        angle = rng.uniform(lo[1 if leg == "A" else 2], hi[1 if leg == "A" else 2], n)
        if dist == 0.0:
            return np.empty((0, 3))  # folded with L1 = L2: P on the pivot, degenerate
        pu = pivot_u + dist * np.cos(angle)
        pw = dist * np.sin(angle)
        # 3-D point in the plane theta1; the IK slot with the requested other signs
        p = np.stack([pw * np.cos(t1), pu, -pw * np.sin(t1)], axis=1)
        ib = inverse_batch(design, p)
        ax = 0 if working_mode[0] == "+" else 1
        # the flipped leg's sign is 0 there: only its '+' slot is kept by inverse_batch
        sa = 0 if (leg == "A" or working_mode[1] == "+") else 1
        sb = 0 if (leg == "B" or working_mode[2] == "+") else 1
        slot = 4 * ax + 2 * sa + sb  # either axis slot reaches P (theta1 differs by pi)
        q = ib.q[ib.ok[:, slot], slot]
    if len(q) == 0:
        return q.reshape(0, 3)
    batch = forward_batch(design, q, assembly_mode)
    keep = batch.ok & np.all((q >= lo) & (q <= hi), axis=1)
    signs = batch.working_mode_signs
    idx = _SIGN_INDEX[flipped]
    want = mode_signs(working_mode)
    for j in range(3):
        if j != idx:
            keep &= signs[:, j] == want[j]
    keep &= batch.assembly_mode_signs == mode_signs(assembly_mode)[0]
    return q[keep]


@dataclass(frozen=True, slots=True)
class Crossing:
    """A straight joint-space crossing of a serial singularity.

    ``q_in`` (in the mode before) -> ``q_transit`` (on the surface) -> ``q_out`` (in the mode
    after) are collinear; along the line the measure changes sign once, at ``q_transit``.
    """

    q_in: np.ndarray
    q_transit: np.ndarray
    q_out: np.ndarray
    kind: str
    flipped: str


def crossing_through(
    design: Design,
    q_transit: np.ndarray,
    *,
    assembly_mode: str,
    flipped: str,
    sign_before: int,
    margin: float,
    max_step: float = 0.5,
    samples: int = 64,
) -> Crossing | None:
    """The straight crossing through ``q_transit`` along the joint-space gradient of the
    serial measure, long enough that both ends have |measure| >= ``margin``.

    The line is checked at ``samples`` points per side: the measure keeps the sign
    ``sign_before`` strictly before the transit and the opposite sign strictly after it
    (one crossing, no grazing). Returns None when no step up to ``max_step`` rad achieves
    that (the surface folds back too close to the posture).
    """
    q_t = np.asarray(q_transit, dtype=float)
    h = 1e-6
    stencil = q_t + np.concatenate([np.eye(3) * h, -np.eye(3) * h])
    f = serial_measure(design, stencil, assembly_mode, flipped)
    grad = (f[:3] - f[3:]) / (2 * h)
    norm = float(np.linalg.norm(grad))
    if not np.isfinite(norm) or norm < 1e-9:
        return None
    direction = grad / norm * (1 if sign_before < 0 else -1)  # points from 'before' to 'after'
    step = min(max_step, 1.5 * margin / norm)
    frac = np.linspace(1.0 / samples, 1.0, samples)
    while step <= max_step:
        line = q_t + np.concatenate([-frac, frac])[:, None] * step * direction
        m = serial_measure(design, line, assembly_mode, flipped)
        before, after = m[:samples], m[samples:]
        if (
            np.all(np.sign(before) == sign_before)
            and np.all(np.sign(after) == -sign_before)
            and abs(before[-1]) >= margin
            and abs(after[-1]) >= margin
        ):
            return Crossing(
                q_in=q_t - step * direction,
                q_transit=q_t.copy(),
                q_out=q_t + step * direction,
                kind=transit_kind(design, q_t, assembly_mode, flipped),
                flipped=flipped,
            )
        step *= 1.5
    return None
