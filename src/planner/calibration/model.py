"""The measurement model of kinematic calibration: P of the five-bar with its two legs'
lengths apart, actuator zero offsets, the tracker's frame, and their analytic Jacobians.

The product's kinematics (:mod:`planner.kinematics`) is that of the symmetric design
(``|AC| = |BD| = L1``, ``|CP| = |DP| = L2``). A real robot's legs differ by their build
errors, so the calibration model writes the loop with four lengths: ``L1_A = |AC|``,
``L1_B = |BD|``, ``L2_A = |CP|``, ``L2_B = |DP|`` (and ``L0 = |AB|``). With the legs equal it
is the product's model exactly (a test checks P and the passive angles against
:func:`planner.kinematics.forward_batch`, and dP/dq against the product's ``A^-1 B``).

In the linkage plane (u along +y, w along e(theta1)), with ``q_e = q + offsets``:
``C = (-L0/2 + L1_A cos q2, L1_A sin q2)``, ``D = (L0/2 + L1_B cos q3, L1_B sin q3)``,
P the intersection of the circles ``|P - C| = L2_A``, ``|P - D| = L2_B`` on the side
``s`` = the assembly mode (``sign sin(theta5 - theta4)``, the product's convention):
``P = C + a e + s h n`` with ``e = (D - C) / d``, ``n`` = e turned +90 deg,
``a = (L2_A^2 - L2_B^2 + d^2) / (2 d)``, ``h = sqrt(L2_A^2 - a^2)``.

Jacobians by implicit differentiation of the two closure equations
``|P - C|^2 = L2_A^2``, ``|P - D|^2 = L2_B^2``:
``[(P - C)^T; (P - D)^T] dP = [(P - C) . dC + L2_A dL2_A; (P - D) . dD + L2_B dL2_B]``,
the two in-plane rows of the product's matrix A (``docs/conventions.md``); it is singular
exactly at the parallel singularity.

The tracker's frame: a measured point ``p`` (tracker frame) is ``R p + t`` in the base frame,
``R = exp([phi]x)`` (``phi`` a rotation vector). The residual of one measurement is
``R p + t - P(q + offsets)`` (m, base frame: its norm is the measurement-space distance).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "FULL_NAMES",
    "LEG_NAMES",
    "LENGTH_NAMES",
    "LoopState",
    "loop_state",
    "measurement_jacobian",
    "residuals",
    "right_jacobian",
    "rotation_matrix",
]

#: The full parameter vector, in this order: five lengths (m), three offsets (rad), the
#: frame's position (m) and rotation vector (rad).
FULL_NAMES: tuple[str, ...] = (
    "L0",
    "L1_A",
    "L1_B",
    "L2_A",
    "L2_B",
    "offsets[0]",
    "offsets[1]",
    "offsets[2]",
    "frame.position[0]",
    "frame.position[1]",
    "frame.position[2]",
    "frame.rotation[0]",
    "frame.rotation[1]",
    "frame.rotation[2]",
)
#: The lengths of the symmetric model (``identify`` "lengths").
LENGTH_NAMES: tuple[str, ...] = ("L0", "L1", "L2")
#: The lengths with the legs apart (``identify`` "leg_lengths").
LEG_NAMES: tuple[str, ...] = ("L0", "L1_A", "L1_B", "L2_A", "L2_B")


def _skew(v: np.ndarray) -> np.ndarray:
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rotation_matrix(phi: np.ndarray) -> np.ndarray:
    """``exp([phi]x)`` (Rodrigues), shape (3, 3), of a rotation vector ``phi`` (3,), rad."""
    phi = np.asarray(phi, dtype=float)
    a = float(np.linalg.norm(phi))
    k = _skew(phi)
    if a < 1e-8:
        return np.eye(3) + k + 0.5 * k @ k
    return np.eye(3) + np.sin(a) / a * k + (1 - np.cos(a)) / a**2 * k @ k


def right_jacobian(phi: np.ndarray) -> np.ndarray:
    """The right Jacobian of SO(3), shape (3, 3): ``exp(phi + d) = exp(phi) exp(J_r d)`` to
    first order, so ``d (R p) / d phi = -R [p]x J_r(phi)``."""
    phi = np.asarray(phi, dtype=float)
    a = float(np.linalg.norm(phi))
    k = _skew(phi)
    if a < 1e-6:
        return np.eye(3) - 0.5 * k + k @ k / 6.0
    return np.eye(3) - (1 - np.cos(a)) / a**2 * k + (a - np.sin(a)) / a**3 * k @ k


@dataclass(frozen=True, eq=False)
class LoopState:
    """The closed loop of N postures of the calibration model (all arrays leading N).

    ``q`` the actuated angles with the offsets added; ``c``, ``d``, ``p`` (N, 2) in-plane
    (u, w) points; ``p3`` (N, 3) P in the base frame; ``ok`` the loop closes (``h^2 > 0``)."""

    q: np.ndarray
    c: np.ndarray
    d: np.ndarray
    p: np.ndarray
    p3: np.ndarray
    ok: np.ndarray

    @property
    def passive(self) -> np.ndarray:
        """(theta4, theta5), shape (N, 2), rad."""
        pc, pd = self.p - self.c, self.p - self.d
        return np.stack([np.arctan2(pc[:, 1], pc[:, 0]), np.arctan2(pd[:, 1], pd[:, 0])], axis=1)

    @property
    def working_mode_signs(self) -> np.ndarray:
        """(sign w, sign sin(theta4 - theta2), sign sin(theta5 - theta3)), shape (N, 3)."""
        t = self.passive
        return np.sign(
            np.stack(
                [self.p[:, 1], np.sin(t[:, 0] - self.q[:, 1]), np.sin(t[:, 1] - self.q[:, 2])],
                axis=1,
            )
        )


def loop_state(full: np.ndarray, q: np.ndarray, branch: np.ndarray) -> LoopState:
    """P of N postures ``q`` (N, 3) with the full parameter vector ``full``
    (:data:`FULL_NAMES`) on the assembly branches ``branch`` (N,) of +1/-1."""
    L0, l1a, l1b, l2a, l2b = full[:5]
    qe = q + full[5:8]
    c2, s2, c3, s3 = np.cos(qe[:, 1]), np.sin(qe[:, 1]), np.cos(qe[:, 2]), np.sin(qe[:, 2])
    c = np.stack([-L0 / 2 + l1a * c2, l1a * s2], axis=1)
    d = np.stack([L0 / 2 + l1b * c3, l1b * s3], axis=1)
    dv = d - c
    dist = np.maximum(np.hypot(dv[:, 0], dv[:, 1]), 1e-300)
    e = dv / dist[:, None]
    n = np.stack([-e[:, 1], e[:, 0]], axis=1)
    a = (l2a**2 - l2b**2 + dist**2) / (2 * dist)
    h2 = l2a**2 - a**2
    ok = (h2 > 0) & (dist > 1e-12)
    h = np.sqrt(np.maximum(h2, 0.0))
    p = c + a[:, None] * e + (branch * h)[:, None] * n
    t1 = qe[:, 0]
    p3 = np.stack([p[:, 1] * np.cos(t1), p[:, 0], -p[:, 1] * np.sin(t1)], axis=1)
    return LoopState(qe, c, d, p, p3, ok)


def _p3_jacobian(full: np.ndarray, s: LoopState) -> np.ndarray:
    """dP3 / d(the first 8 parameters: lengths and offsets), shape (N, 3, 8)."""
    n = s.q.shape[0]
    l1a, l1b, l2a, l2b = full[1:5]
    c2, s2, c3, s3 = (np.cos(s.q[:, 1]), np.sin(s.q[:, 1]), np.cos(s.q[:, 2]), np.sin(s.q[:, 2]))
    pc, pd = s.p - s.c, s.p - s.d
    # dC, dD (N, 2, 8) by parameter
    dc = np.zeros((n, 2, 8))
    dd = np.zeros((n, 2, 8))
    dc[:, 0, 0], dd[:, 0, 0] = -0.5, 0.5
    dc[:, :, 1] = np.stack([c2, s2], axis=1)
    dd[:, :, 2] = np.stack([c3, s3], axis=1)
    dc[:, :, 6] = l1a * np.stack([-s2, c2], axis=1)
    dd[:, :, 7] = l1b * np.stack([-s3, c3], axis=1)
    rhs = np.stack(
        [np.einsum("ni,nik->nk", pc, dc), np.einsum("ni,nik->nk", pd, dd)], axis=1
    )  # (N, 2, 8)
    rhs[:, 0, 3] += l2a
    rhs[:, 1, 4] += l2b
    # [pc; pd] dP = rhs, solved by Cramer's rule with the determinant kept off zero: a
    # trial step of the fit may reach a posture where the loop does not close (h = 0, the
    # matrix singular); its huge Jacobian then turns the step back instead of raising
    det = pc[:, 0] * pd[:, 1] - pc[:, 1] * pd[:, 0]
    floor = 1e-12 * l2a * l2b
    det = np.where(np.abs(det) < floor, np.where(det < 0, -floor, floor), det)[:, None]
    dp = np.stack(
        [
            (pd[:, 1, None] * rhs[:, 0] - pc[:, 1, None] * rhs[:, 1]) / det,
            (pc[:, 0, None] * rhs[:, 1] - pd[:, 0, None] * rhs[:, 0]) / det,
        ],
        axis=1,
    )  # (N, 2, 8): d(u, w)
    t1 = s.q[:, 0]
    ct, st = np.cos(t1), np.sin(t1)
    out = np.empty((n, 3, 8))
    out[:, 0] = dp[:, 1] * ct[:, None]
    out[:, 1] = dp[:, 0]
    out[:, 2] = -dp[:, 1] * st[:, None]
    w = s.p[:, 1]
    out[:, 0, 5] += -w * st
    out[:, 2, 5] += -w * ct
    return out


def residuals(full: np.ndarray, q: np.ndarray, branch: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``R p + t - P(q + offsets)``, shape (N, 3), m (module docstring)."""
    r = rotation_matrix(full[11:14])
    return p @ r.T + full[8:11] - loop_state(full, q, branch).p3


def measurement_jacobian(
    full: np.ndarray, q: np.ndarray, branch: np.ndarray, p: np.ndarray
) -> np.ndarray:
    """d :func:`residuals` / d ``full``, shape (3 N, 14) (rows: measurement-major)."""
    n = q.shape[0]
    s = loop_state(full, q, branch)
    jac = np.zeros((n, 3, len(FULL_NAMES)))
    jac[:, :, :8] = -_p3_jacobian(full, s)
    jac[:, :, 8:11] = np.eye(3)
    phi = full[11:14]
    r = rotation_matrix(phi)
    jr = right_jacobian(phi)
    skew = np.zeros((n, 3, 3))
    skew[:, 0, 1], skew[:, 0, 2] = -p[:, 2], p[:, 1]
    skew[:, 1, 0], skew[:, 1, 2] = p[:, 2], -p[:, 0]
    skew[:, 2, 0], skew[:, 2, 1] = -p[:, 1], p[:, 0]
    jac[:, :, 11:14] = -np.einsum("ij,njk,kl->nil", r, skew, jr)
    return jac.reshape(3 * n, len(FULL_NAMES))
