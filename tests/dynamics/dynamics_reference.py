"""An independent oracle of the dynamics: the robot's energy from its bodies' motion.

Nothing here uses the product's passive rates, Jacobians or mass matrix: the positions of the
joint centres come from the product's forward kinematics (``link_points``), every velocity is
a central finite difference of those positions (in time, or along a joint-space direction),
and each link's angular velocity is read off the finite difference of its body frame
``R = [e, k x e, k]`` (e the link's direction from the joint centres, k the plane normal
turned by theta1): ``skew(omega) = R' R^T``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from planner import Design, forward_batch, link_points
from planner.dynamics import Inertia

# joint-centre rows of link_points: A, B, C, D, P
_LINKS = (("proximal", 0, 2), ("proximal", 1, 3), ("distal", 2, 4), ("distal", 3, 4))


def bodies(design: Design, q: np.ndarray, mode: str) -> tuple[np.ndarray, list, np.ndarray]:
    """Joint centres (N, 5, 3), per link (start, end) index pairs, and frames (N, 4, 3, 3)."""
    batch = forward_batch(design, q, mode)
    assert np.all(batch.ok)
    pts = link_points(design, batch.q, batch.passive)
    t1 = batch.q[:, 0]
    k = np.stack([np.sin(t1), np.zeros_like(t1), np.cos(t1)], axis=1)
    frames = []
    for _, a, b in _LINKS:
        e = pts[:, b] - pts[:, a]
        e /= np.linalg.norm(e, axis=1, keepdims=True)
        frames.append(np.stack([e, np.cross(k, e), k], axis=2))  # columns
    return pts, list(_LINKS), np.stack(frames, axis=1)


def _com(inertia: Inertia, pts: np.ndarray) -> list[tuple[float, np.ndarray]]:
    out = []
    for kind, a, b in _LINKS:
        link = getattr(inertia, kind)
        out.append((link.mass, pts[:, a] + link.com * (pts[:, b] - pts[:, a])))
    out.append((inertia.payload_mass, pts[:, 4]))
    return out


def kinetic_energy(
    design: Design,
    inertia: Inertia,
    mode: str,
    q_minus: np.ndarray,
    q_plus: np.ndarray,
    q_mid: np.ndarray,
    h: float,
) -> np.ndarray:
    """Kinetic energy (N,) of the motion through q_mid whose postures at -h and +h (time, or
    any path parameter) are q_minus and q_plus: central differences of the bodies."""
    pm, _, rm = bodies(design, q_minus, mode)
    pp, _, rp = bodies(design, q_plus, mode)
    _, _, r0 = bodies(design, q_mid, mode)
    qd = (q_plus - q_minus) / (2 * h)
    ke = 0.5 * inertia.base_inertia * qd[:, 0] ** 2 + 0.5 * np.sum(inertia.rotor_array * qd**2, 1)
    for (m, xm), (_, xp) in zip(_com(inertia, pm), _com(inertia, pp), strict=True):
        v = (xp - xm) / (2 * h)
        ke += 0.5 * m * np.sum(v**2, axis=1)
    for i, (kind, _, _) in enumerate(_LINKS):
        link = getattr(inertia, kind)
        rdot = (rp[:, i] - rm[:, i]) / (2 * h)
        w_skew = rdot @ np.swapaxes(r0[:, i], 1, 2)
        omega = np.stack([w_skew[:, 2, 1], w_skew[:, 0, 2], w_skew[:, 1, 0]], axis=1)
        body = np.einsum("nji,nj->ni", r0[:, i], omega)  # components in the link frame
        ke += 0.5 * (link.I_axial * body[:, 0] ** 2 + link.I_perp * np.sum(body[:, 1:] ** 2, 1))
    return ke


def potential_energy(
    design: Design, inertia: Inertia, mode: str, q: np.ndarray, gravity: np.ndarray
) -> np.ndarray:
    """-sum m g . x_com, J (N,)."""
    pts, _, _ = bodies(design, q, mode)
    return -sum(m * (x @ gravity) for m, x in _com(inertia, pts))


def energy_along(
    design: Design,
    inertia: Inertia,
    mode: str,
    q_of_t: Callable[[np.ndarray], np.ndarray],
    t: np.ndarray,
    gravity: np.ndarray,
    h: float = 1e-5,
) -> np.ndarray:
    """Total energy (N,) at times t of the trajectory q_of_t (t (N,) -> (N, 3))."""
    ke = kinetic_energy(design, inertia, mode, q_of_t(t - h), q_of_t(t + h), q_of_t(t), h)
    return ke + potential_energy(design, inertia, mode, q_of_t(t), gravity)


def mass_matrix_by_polarisation(
    design: Design, inertia: Inertia, mode: str, q: np.ndarray, h: float = 1e-6
) -> np.ndarray:
    """M(q) (N, 3, 3) as the Hessian in qd of the kinetic energy T = qd^T M qd / 2, by
    polarisation: M_ij = (T(e_i + e_j) - T(e_i - e_j)) / 2, with T from central differences
    of the bodies along each direction (exact for a quadratic form up to the differences)."""
    n = q.shape[0]
    out = np.empty((n, 3, 3))
    eye = np.eye(3)

    def ke(direction: np.ndarray) -> np.ndarray:
        step = h * direction
        return kinetic_energy(design, inertia, mode, q - step, q + step, q, h)

    for i in range(3):
        for j in range(i, 3):
            if i == j:
                out[:, i, i] = 2 * ke(eye[i])
            else:
                out[:, i, j] = out[:, j, i] = (ke(eye[i] + eye[j]) - ke(eye[i] - eye[j])) / 2
    return out


def random_postures(
    design: Design, mode: str, n: int, seed: int, kappa_max: float = 20.0
) -> np.ndarray:
    """n seeded postures (n, 3) that assemble in ``mode`` with kappa(A) <= kappa_max and the
    serial measures above 0.05 (well inside the workspace)."""
    from planner import conditioning

    rng = np.random.default_rng(seed)
    found = []
    while sum(len(f) for f in found) < n:
        q = rng.uniform(-np.pi, np.pi, size=(4 * n, 3))
        b = forward_batch(design, q, mode)
        c = conditioning(design, b.q, b.passive, b.w)
        good = b.ok & (np.nan_to_num(c.kappa_A, nan=np.inf) <= kappa_max)
        good &= np.nan_to_num(c.min_serial, nan=0.0) > 0.05
        found.append(q[good])
    return np.concatenate(found)[:n]
