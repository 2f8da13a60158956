"""The blends of a sequence's pass-through targets: asked in radians (``blend``, joint space)
or in metres at the tool point (``blend_radius``, MoveIt Pilz's name), used as a joint-space
radius by the timing, and shrunk to fit their legs.

Shrinking to fit is what controllers do with zones (ABB's zones, KUKA's approximate
positioning, Pilz's blend radius): a zone that does not fit is made smaller, the program is
never refused. The rule here: a target's blend is at most half the shorter of its two legs
(joint-space length along the joined path), so two neighbours' blends never overlap on the
leg between them, and a blend never reaches past the middle of a leg into the next target's.
Only a negative or non-finite blend is refused (by :class:`~planner.sequence.SequenceTarget`).

A blend in metres becomes a joint-space radius at the target's posture q: the largest b such
that every posture within b of q keeps P within ``blend_radius`` of P(q), from the largest
gain of the tool-point Jacobian over the ball (:func:`joint_radius`; P(q + dq) - P(q) is at most
that gain times |dq|). The trajectory passes within b of q, hence within ``blend_radius`` of
the target point.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planner.design import Design
from planner.kinematics import forward_batch
from planner.sequence.problem import BlendUse, SequenceTarget

__all__ = ["AskedBlend", "blend_uses", "fit_blends", "joint_radius", "shrink_message"]

#: Finite-difference step of the tool-point Jacobian, rad.
_FD_STEP = 1e-6
#: Relative margin on the gain over the ball (its sampled maximum may miss the true one by a
#: little between the sample directions).
_GAIN_MARGIN = 1.05
#: The ball's sample directions: the 26 of the cube's faces, edges and corners, unit length.
_DIRECTIONS = np.array(
    [d for d in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(d)], dtype=float
)
_DIRECTIONS /= np.linalg.norm(_DIRECTIONS, axis=1)[:, None]


def _largest_gain(design: Design, q: np.ndarray, assembly_mode: str) -> float:
    """The largest singular value of dP/dq (m per rad) over the postures ``q`` (N, 3) that
    assemble, by central differences; 0 when none does."""
    n = len(q)
    steps = np.vstack([_FD_STEP * np.eye(3), -_FD_STEP * np.eye(3)])
    probe = (q[:, None, :] + steps[None, :, :]).reshape(-1, 3)
    batch = forward_batch(design, probe, assembly_mode)
    p = batch.p.reshape(n, 6, 3)
    ok = batch.ok.reshape(n, 6).all(axis=1)
    if not ok.any():
        return 0.0
    jac = (p[ok, :3, :] - p[ok, 3:, :]).transpose(0, 2, 1) / (2 * _FD_STEP)
    return float(np.max(np.linalg.svd(jac, compute_uv=False)))


def joint_radius(design: Design, q: np.ndarray, assembly_mode: str, radius: float) -> float:
    """The joint-space radius (rad) about ``q`` within which P stays within ``radius`` (m) of
    P(q): ``radius`` over the largest Jacobian gain on the ball (its centre and 52 points at
    its full and half radius), iterated three times as the ball shrinks, with a 5 % margin."""
    if radius <= 0.0:
        return 0.0
    q = np.asarray(q, dtype=float)
    gain = _largest_gain(design, q[None, :], assembly_mode)
    if gain <= 0.0:
        return 0.0
    b = radius / (gain * _GAIN_MARGIN)
    for _ in range(3):
        ball = np.vstack([q, q + b * _DIRECTIONS, q + 0.5 * b * _DIRECTIONS])
        gain = max(gain, _largest_gain(design, ball, assembly_mode))
        b = radius / (gain * _GAIN_MARGIN)
    return b


@dataclass(frozen=True, slots=True)
class AskedBlend:
    """One pass-through target's blend as asked: ``value`` in ``unit`` ("rad" or "m"), and
    ``rad`` the joint-space radius it means at the target's posture."""

    target_index: int
    value: float
    unit: str
    rad: float

    @classmethod
    def of(
        cls,
        design: Design,
        index: int,
        target: SequenceTarget,
        q: np.ndarray,
        assembly_mode: str,
        *,
        off: bool = False,
    ) -> AskedBlend:
        """Target ``index``'s blend at its posture ``q``; with ``off`` as asked but used as 0
        (the sequence timed passing every target exactly)."""
        if target.blend_radius is None:
            return cls(index, target.blend, "rad", 0.0 if off else target.blend)
        rad = 0.0 if off else joint_radius(design, q, assembly_mode, target.blend_radius)
        return cls(index, target.blend_radius, "m", rad)


def _leg_length(w: np.ndarray, a: int, b: int) -> float:
    return float(np.sum(np.linalg.norm(np.diff(w[a : b + 1], axis=0), axis=1)))


def fit_blends(w: np.ndarray, at: Sequence[int], asked: Sequence[AskedBlend | None]) -> list[float]:
    """The joint-space blend each leg's target is passed with (0 at a stop, ``asked`` None):
    the asked radius, shrunk to half the shorter of the target's two legs (module
    docstring). ``w`` the joined path's waypoints, ``at`` each target's waypoint index."""
    used = []
    for i, a in enumerate(asked):
        if a is None:
            used.append(0.0)
            continue
        before = _leg_length(w, at[i - 1] if i > 0 else 0, at[i])
        after = _leg_length(w, at[i], at[i + 1]) if i + 1 < len(at) else math.inf
        used.append(min(a.rad, 0.5 * min(before, after)))
    return used


def blend_uses(asked: Sequence[AskedBlend | None], used: Sequence[float]) -> tuple[BlendUse, ...]:
    """``diagnostics.blends``: each passed target's blend as asked and as used, in the unit
    it was asked in (a shrunk blend in metres is the joint radius used times the metres per
    radian of the asked one)."""
    out = []
    for a, u in zip(asked, used, strict=False):
        if a is None:
            continue
        if a.unit == "rad":
            value = u
        elif a.rad <= 0.0:  # passed exactly (blend_radius 0, or every blend off)
            value = 0.0
        else:
            value = a.value if u >= a.rad else a.value * u / a.rad
        out.append(BlendUse(a.target_index, a.value, value, a.unit))
    return tuple(out)


def shrink_message(uses: Sequence[BlendUse]) -> str:
    """The message's account of the blends that shrank, or "" when none did."""
    # used 0 with a blend asked: not shrunk but set aside (passing exactly was quicker)
    shrunk = [u for u in uses if 0.0 < u.used < u.asked * (1 - 1e-9)]
    if not shrunk:
        return ""
    return "blends shrunk to fit (at most half the shorter adjacent leg): " + ", ".join(
        f"target {u.target_index} {u.asked:.4g} -> {u.used:.4g} {u.unit}" for u in shrunk
    )
