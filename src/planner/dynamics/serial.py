"""The serial counterpart of the manipulator: the same links driven as a serial arm, with the
distal motor riding on the links. It is the yardstick of the paper's claim that putting every
motor on the base or the first axis "considerably reduces the inertial effects"
(``docs/analysis.md``, *Inertia against a serial arm*).

Definition (:class:`SerialArm`). The plane turns about AB by theta1 as the five-bar's does;
in it, a two-link planar chain A-C-P: link AC (the five-bar's proximal link, same
:class:`~planner.dynamics.LinkInertia`), turned at A by the shoulder motor (angle theta2,
measured as in the five-bar), and link CP (the distal link), turned at C by the elbow motor
(relative angle ``theta_e = phi - theta2``, phi the absolute angle of CP, i.e. the five-bar's
theta4). Leg B is gone; the elbow motor rides at C as a point mass ``elbow_mass`` (by default
the mass of one of the five-bar's base motors, 0.6 kg: the same motor, moved from the base to
the elbow); the payload is at P. The turning base carries the shoulder motor only, so its
inertia about AB is ``base_inertia`` (by default half the five-bar's: one of its two motors
stays). The rotors are reflected to their joints as in the five-bar (``rotor_j qdd_j``; the
elbow rotor's gyroscopic coupling with link AC is neglected, as the five-bar's rotors' with
the base are). In a posture of the five-bar, the serial arm in ``(theta1, theta2,
theta4 - theta2)`` is leg A of that posture: P is the same point.

Mass matrix, closed form (kinetic energy of the bodies, the plane's frame ``(e, y, k)`` of
``docs/dynamics.md``: a point at in-plane (u, w) has ``|v|^2 = ud^2 + wd^2 + w^2 qd1^2``; a
link at in-plane angle phi turns with ``omega = qd1 y - phid k``, so its rotational energy is
``(I_perp phid^2 + (I_perp sin^2 phi + I_axial cos^2 phi) qd1^2) / 2``):

    M11 = I_base + rotor1 + sum_points m w^2 + sum_links (I_perp sin^2 phi + I_axial cos^2 phi)
    M12 = M13 = 0
    planar block in absolute angles (theta2, phi):
      a = m1 f1^2 L1^2 + I1_perp + (m2 + m_e + m_p) L1^2
      b = (m2 f2 + m_p) L1 L2 cos(phi - theta2)
      c = m2 f2^2 L2^2 + I2_perp + m_p L2^2
    in (theta2, theta_e): M22 = a + 2 b + c + rotor2, M23 = b + c, M33 = c + rotor3

(points: the two links' centres of mass at w = f1 L1 sin theta2 and
``L1 sin theta2 + f2 L2 sin phi``, the elbow motor at C, the payload at P). The torques
(:meth:`SerialArm.inverse_dynamics`) follow by Lagrange's equations,
``tau = M qdd + (dM/dt) qd - d/dq (qd^T M qd / 2) + dV/dq``, the derivatives of M and of the
potential V taken by central differences of these closed forms (step 1e-6 rad: ~1e-9 relative).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.design import Design
from planner.dynamics.inertia import DEFAULT_BASE_MOTOR_MASS, Inertia, _number, check_gravity
from planner.exceptions import InputError

__all__ = ["SerialArm", "serial_coordinates", "serial_motion"]

#: Step of the central differences of M and V in :meth:`SerialArm.inverse_dynamics`, rad.
_STEP = 1e-6


def serial_coordinates(q: np.ndarray, passive: np.ndarray) -> np.ndarray:
    """The serial arm's joints (N, 3) that put it in leg A of five-bar postures: (theta1,
    theta2, theta4 - theta2) from actuated q (N, 3) and passive (theta4, theta5) (N, 2)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    passive = np.atleast_2d(np.asarray(passive, dtype=float))
    return np.stack([q[:, 0], q[:, 1], passive[:, 0] - q[:, 1]], axis=1)


def serial_motion(
    design: Design, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, assembly_mode: str = "+"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The serial arm's (qs, qsd, qsdd), each (N, 3), that moves P as the five-bar's motion
    (q, qd, qdd) does: leg A's joints, the passive rate and acceleration of theta4 from the
    loop closure (``docs/dynamics.md``, equations (P)). NaN rows where the five-bar does
    not assemble or is parallel-singular."""
    from planner.kinematics import forward_batch

    fb = forward_batch(design, q, assembly_mode)
    qd = np.atleast_2d(np.asarray(qd, dtype=float))
    qdd = np.atleast_2d(np.asarray(qdd, dtype=float))
    t2, t3 = fb.q[:, 1], fb.q[:, 2]
    t4, t5 = fb.passive[:, 0], fb.passive[:, 1]

    def a(t: np.ndarray) -> np.ndarray:
        return np.stack([np.cos(t), np.sin(t)], axis=1)

    def nrm(t: np.ndarray) -> np.ndarray:
        return np.stack([-np.sin(t), np.cos(t)], axis=1)

    L1, L2 = design.L1, design.L2
    with np.errstate(divide="ignore", invalid="ignore"):
        s = L2 * np.sin(t5 - t4)
        r = L1 * (qd[:, 2:3] * nrm(t3) - qd[:, 1:2] * nrm(t2))
        t4d = np.sum(r * a(t5), axis=1) / s
        t5d = np.sum(r * a(t4), axis=1) / s
        r2 = L1 * (
            qdd[:, 2:3] * nrm(t3)
            - qd[:, 2:3] ** 2 * a(t3)
            - qdd[:, 1:2] * nrm(t2)
            + qd[:, 1:2] ** 2 * a(t2)
        )
        r2 += L2 * (t4d[:, None] ** 2 * a(t4) - t5d[:, None] ** 2 * a(t5))
        t4dd = np.sum(r2 * a(t5), axis=1) / s
    qs = serial_coordinates(fb.q, fb.passive)
    qsd = np.stack([qd[:, 0], qd[:, 1], t4d - qd[:, 1]], axis=1)
    qsdd = np.stack([qdd[:, 0], qdd[:, 1], t4dd - qdd[:, 1]], axis=1)
    bad = ~fb.ok | ~np.isfinite(s) | (np.abs(s) < 1e-12)
    for arr in (qs, qsd, qsdd):
        arr[bad] = np.nan
    return qs, qsd, qsdd


@dataclass(frozen=True, eq=False)
class SerialArm:
    """The same links as a serial arm (module docstring): shoulder at A, elbow motor at C.

    Parameters
    ----------
    design : the five-bar whose L0, L1, L2 it takes (A at (-L0/2, 0) in the plane)
    inertia : the five-bar's inertial model (links, payload, rotors)
    elbow_mass : kg, >= 0 -- the elbow motor, a point mass at C
    base_inertia : kg m^2, >= 0 -- the turning base about AB; None: half of
        ``inertia.base_inertia`` (the shoulder motor stays, the elbow motor left)
    """

    design: Design
    inertia: Inertia
    elbow_mass: float = DEFAULT_BASE_MOTOR_MASS
    base_inertia: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "elbow_mass", _number("elbow_mass", self.elbow_mass, 1e6))
        base = self.inertia.base_inertia / 2 if self.base_inertia is None else self.base_inertia
        object.__setattr__(self, "base_inertia", _number("base_inertia", base, 1e6))

    def _check(self, qs: object, name: str = "q") -> np.ndarray:
        arr = np.atleast_2d(np.asarray(qs, dtype=float))
        if arr.ndim != 2 or arr.shape[1] != 3:
            shape = np.asarray(qs, dtype=float).shape  # as given, before atleast_2d
            raise InputError(f"{name} must have shape (N, 3), got {shape}", field=name)
        return arr

    def points(self, qs: np.ndarray) -> dict[str, np.ndarray]:
        """In-plane (u, w) of C and P and the links' absolute angles, each (N,) or (N, 2)."""
        qs = self._check(qs)
        d = self.design
        t2, phi = qs[:, 1], qs[:, 1] + qs[:, 2]
        c = np.stack([-d.L0 / 2 + d.L1 * np.cos(t2), d.L1 * np.sin(t2)], axis=1)
        p = c + d.L2 * np.stack([np.cos(phi), np.sin(phi)], axis=1)
        return {"C": c, "P": p, "theta2": t2, "phi": phi}

    def mass_matrix(self, qs: np.ndarray) -> np.ndarray:
        """M(qs) (N, 3, 3) in (theta1, theta2, theta_e), the closed form of the module
        docstring."""
        qs = self._check(qs)
        d, i = self.design, self.inertia
        pr, di = i.proximal, i.distal
        m1, f1, m2, f2 = pr.mass, pr.com, di.mass, di.com
        me, mp = self.elbow_mass, i.payload_mass
        assert self.base_inertia is not None, "SerialArm.__post_init__ sets base_inertia"
        t2, phi = qs[:, 1], qs[:, 1] + qs[:, 2]
        s2, sp = np.sin(t2), np.sin(phi)
        w1 = f1 * d.L1 * s2
        wc = d.L1 * s2
        w2 = wc + f2 * d.L2 * sp
        wp = wc + d.L2 * sp
        m11 = (
            self.base_inertia
            + i.rotor[0]
            + m1 * w1**2
            + m2 * w2**2
            + me * wc**2
            + mp * wp**2
            + pr.I_perp * s2**2
            + pr.I_axial * np.cos(t2) ** 2
            + di.I_perp * sp**2
            + di.I_axial * np.cos(phi) ** 2
        )
        a = m1 * f1**2 * d.L1**2 + pr.I_perp + (m2 + me + mp) * d.L1**2
        b = (m2 * f2 + mp) * d.L1 * d.L2 * np.cos(phi - t2)
        c = m2 * f2**2 * d.L2**2 + di.I_perp + mp * d.L2**2
        m = np.zeros((qs.shape[0], 3, 3))
        m[:, 0, 0] = m11
        m[:, 1, 1] = a + 2 * b + c + i.rotor[1]
        m[:, 1, 2] = m[:, 2, 1] = b + c
        m[:, 2, 2] = c + i.rotor[2]
        return m

    def potential(self, qs: np.ndarray, gravity: object) -> np.ndarray:
        """V = -sum m g . x (N,), J: the points of :meth:`mass_matrix` in 3-D,
        ``x = u y + w e(theta1)``, e = (cos theta1, 0, -sin theta1)."""
        qs = self._check(qs)
        g = check_gravity(gravity)
        d, i = self.design, self.inertia
        pts = self.points(qs)
        a = np.array([-d.L0 / 2, 0.0])
        c, p = pts["C"], pts["P"]
        masses = (
            (i.proximal.mass, a + i.proximal.com * (c - a)),
            (i.distal.mass, c + i.distal.com * (p - c)),
            (self.elbow_mass, c),
            (i.payload_mass, p),
        )
        t1 = qs[:, 0]
        e = np.stack([np.cos(t1), np.zeros_like(t1), -np.sin(t1)], axis=1)
        y = np.array([0.0, 1.0, 0.0])
        v = np.zeros(qs.shape[0])
        for m, uw in masses:
            x = uw[:, :1] * y + uw[:, 1:] * e
            v -= m * (x @ g)
        return v

    def inverse_dynamics(
        self, qs: np.ndarray, qsd: np.ndarray, qsdd: np.ndarray, *, gravity: object
    ) -> np.ndarray:
        """tau (N, 3), N m, of the serial arm's motions (qs, qsd, qsdd), each (N, 3), by
        Lagrange's equations (module docstring)."""
        qs, qsd, qsdd = self._check(qs), self._check(qsd, "qd"), self._check(qsdd, "qdd")
        m = self.mass_matrix(qs)
        tau = np.einsum("nij,nj->ni", m, qsdd)
        dm = np.empty((qs.shape[0], 3, 3, 3))  # dm[:, k] = dM/dq_k
        dv = np.empty_like(qs)
        for k in range(3):
            step = np.zeros(3)
            step[k] = _STEP
            dm[:, k] = (self.mass_matrix(qs + step) - self.mass_matrix(qs - step)) / (2 * _STEP)
            dv[:, k] = (self.potential(qs + step, gravity) - self.potential(qs - step, gravity)) / (
                2 * _STEP
            )
        mdot = np.einsum("nkij,nk->nij", dm, qsd)
        tau += np.einsum("nij,nj->ni", mdot, qsd)
        tau -= 0.5 * np.einsum("nkij,ni,nj->nk", dm, qsd, qsd)
        return tau + dv
