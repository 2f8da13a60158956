"""Inverse dynamics of the closed chain in actuated coordinates, vectorised over N postures.

The derivation is in ``docs/dynamics.md``. In short: the five bodies (two proximal links, two
distal links, the payload at P; plus the turning base and the rotors) are written in the
frame of the linkage plane ``(e, y, k)`` that turns with theta1. The loop closure
``C + L2 a(theta4) = D + L2 a(theta5)`` gives the passive rates and accelerations in closed
form (divided by ``L2 sin(theta5 - theta4)``: a parallel singularity is where they blow up).
Each body's Newton-Euler wrench ``(m (a - g), I alpha + omega x I omega)`` is projected on the
actuated coordinates by its velocity Jacobians (virtual work: the loop's constraint forces do
no work on motions that keep it closed), so

    tau = M(q) qdd + h(q, qd),   h = (velocity-product terms) + (gravity terms).

``M`` is assembled from the same projection with unit accelerations, no velocity and no
gravity (three evaluations), so it is exactly the matrix of the torques computed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner._kernels import read_only
from planner.constants import KAPPA_SOLVABLE
from planner.design import Design
from planner.dynamics import _kernels
from planner.dynamics.inertia import Inertia, check_gravity
from planner.exceptions import InputError
from planner.kinematics import forward_batch

__all__ = [
    "DynamicsBatch",
    "inverse_dynamics",
    "inverse_dynamics_terms",
    "mass_matrix",
]


def _rates(name: str, value: object, n: int) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numbers, got {value!r}", field=name) from exc
    arr = np.atleast_2d(arr)
    if arr.ndim != 2 or arr.shape[1] != 3:
        shape = np.asarray(value, dtype=float).shape  # as given, before atleast_2d
        raise InputError(f"{name} must have shape (N, 3), got {shape}", field=name)
    if arr.shape[0] != n:
        raise InputError(
            f"{name} must have {n} rows (one per posture of q), got {arr.shape[0]}", field=name
        )
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be finite (no NaN or infinity)", field=name)
    return arr


@dataclass(frozen=True, eq=False)
class _Kin:
    """Actuated and passive angles of N postures (internal)."""

    q: np.ndarray  # (N, 3), C-contiguous
    passive: np.ndarray  # (N, 2), (theta4, theta5); 0 where not ok
    ok: np.ndarray  # assembled and kappa(A) <= KAPPA_SOLVABLE
    kappa: np.ndarray


def _kinematics(design: Design, q: np.ndarray, assembly_mode: object) -> _Kin:
    batch = forward_batch(design, q, assembly_mode)
    d = batch.passive[:, 1] - batch.passive[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = (1.0 + np.abs(np.cos(d))) / np.abs(np.sin(d))  # kappa(A), erratum 2
    ok = batch.ok & (kappa <= KAPPA_SOLVABLE)
    passive = np.ascontiguousarray(np.where(ok[:, None], batch.passive, 0.0))
    return _Kin(np.ascontiguousarray(batch.q), passive, ok, kappa)


def _params(inertia: Inertia) -> np.ndarray:
    """The inertia as the kernel's parameter vector (order :data:`_kernels.PARAMS`)."""
    p, d = inertia.proximal, inertia.distal
    return np.array(
        [
            p.mass,
            p.com,
            p.I_perp,
            p.I_axial,
            d.mass,
            d.com,
            d.I_perp,
            d.I_axial,
            inertia.payload_mass,
            inertia.base_inertia,
            *inertia.rotor,
        ]
    )


def _forces(
    design: Design,
    inertia: Inertia,
    kin: _Kin,
    qd: np.ndarray,
    qdd: np.ndarray,
    gravity: np.ndarray,
) -> np.ndarray:
    """Generalised forces (N, 3) of the motion (q, qd, qdd) under ``gravity`` (the compiled
    loop of :mod:`planner.dynamics._kernels`; NaN where the posture is not ``ok``)."""
    out = np.empty_like(kin.q)
    prm, q, passive, ok, qd1, qdd1, g = _inputs(_params(inertia), kin, qd, qdd, gravity)
    _kernels.inverse_kernel(design.L1, design.L2, prm, q, passive, ok, qd1, qdd1, g, out)
    return out


def _inputs(params, kin: _Kin, qd, qdd, gravity) -> tuple[np.ndarray, ...]:
    """The input arrays of :func:`_kernels.inverse_kernel`, each read-only and C-contiguous
    (:func:`planner._kernels.read_only`: one compiled signature for every caller, the
    warm-up's included, whether its rates or gravity came frozen or not)."""
    return (
        read_only(params),
        read_only(kin.q),
        read_only(kin.passive),
        read_only(kin.ok, np.bool_),
        read_only(qd),
        read_only(qdd),
        read_only(gravity),
    )


@dataclass(frozen=True, eq=False)
class DynamicsBatch:
    """Inverse dynamics of N postures.

    Attributes
    ----------
    tau : shape (N, 3), N m -- actuator torques producing the motion (NaN where not ``ok``)
    mass_matrix : shape (N, 3, 3), kg m^2 (and kg m for mixed entries) -- M(q), symmetric
        positive definite where ``ok``; NaN elsewhere
    ok : shape (N,), bool -- the posture assembles and kappa(A) <= KAPPA_SOLVABLE
    kappa_A : shape (N,) -- kappa(A) of each posture (inf when parallel-singular or not
        assembled)
    """

    tau: np.ndarray
    mass_matrix: np.ndarray | None
    ok: np.ndarray
    kappa_A: np.ndarray


def inverse_dynamics(
    design: Design,
    inertia: Inertia,
    q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    *,
    assembly_mode: object = "+",
    gravity: object = (0.0, 0.0, -9.81),
    with_mass_matrix: bool = False,
) -> DynamicsBatch:
    """Actuator torques ``tau = M(q) qdd + h(q, qd)`` of N motions of the closed chain.

    Parameters
    ----------
    design, inertia : the robot
    q, qd, qdd : shape (N, 3) or (3,): rad, rad/s, rad/s^2 (actuated joints)
    assembly_mode : '+' | '-' | array of +1/-1 (N,)
    gravity : shape (3,), m/s^2, base frame
    with_mass_matrix : also return M(q) (three more projections)

    Returns
    -------
    DynamicsBatch
        Where a posture does not assemble, or is parallel-singular (kappa(A) above
        :data:`~planner.constants.KAPPA_SOLVABLE`: M grows like kappa(A)^2 there and the
        torques of a finite motion are undefined at the singularity itself), ``ok`` is False
        and ``tau`` and ``mass_matrix`` are NaN.
    """
    g = check_gravity(gravity)
    kin = _kinematics(design, q, assembly_mode)
    n = kin.q.shape[0]
    qd2 = _rates("qd", qd, n)
    qdd2 = _rates("qdd", qdd, n)
    tau = _forces(design, inertia, kin, qd2, qdd2, g)
    tau[~kin.ok] = np.nan
    m = _mass_matrix_of(design, inertia, kin) if with_mass_matrix else None
    return DynamicsBatch(tau, m, kin.ok, np.where(kin.ok, kin.kappa, np.inf))


def inverse_dynamics_terms(
    design: Design,
    inertia: Inertia,
    q: np.ndarray,
    terms: list[tuple[np.ndarray, np.ndarray, object]],
    *,
    assembly_mode: object = "+",
) -> list[np.ndarray]:
    """The torques of several motions through the same postures q (N, 3): for each
    ``(qd, qdd, gravity)`` of ``terms``, what :func:`inverse_dynamics` answers as ``tau``, with
    the postures' kinematics solved once (the timing's torque constraint asks three such
    terms of every grid, :meth:`planner.timing.torque.TorqueModel.path_coefficients`)."""
    kin = _kinematics(design, q, assembly_mode)
    n = kin.q.shape[0]
    out = []
    for qd, qdd, gravity in terms:
        tau = _forces(
            design, inertia, kin, _rates("qd", qd, n), _rates("qdd", qdd, n), check_gravity(gravity)
        )
        tau[~kin.ok] = np.nan
        out.append(tau)
    return out


def _mass_matrix_of(design: Design, inertia: Inertia, kin: _Kin) -> np.ndarray:
    """M(q), shape (N, 3, 3), of kinematics already computed (column j: the torques of a unit
    acceleration of joint j at rest without gravity), symmetrised."""
    n = kin.q.shape[0]
    zero = np.zeros((n, 3))
    g0 = np.zeros(3)
    m = np.empty((n, 3, 3))
    for j in range(3):
        unit = np.zeros((n, 3))
        unit[:, j] = 1.0
        m[:, :, j] = _forces(design, inertia, kin, zero, unit, g0)
    m = 0.5 * (m + np.swapaxes(m, 1, 2))  # symmetric by construction, exactly so to rounding
    m[~kin.ok] = np.nan
    return m


def mass_matrix(
    design: Design, inertia: Inertia, q: np.ndarray, *, assembly_mode: object = "+"
) -> np.ndarray:
    """M(q) of N postures, shape (N, 3, 3) (NaN where not ``ok``, see
    :func:`inverse_dynamics`)."""
    return _mass_matrix_of(design, inertia, _kinematics(design, q, assembly_mode))
