"""The minimum-time motion of the closed chain under torque limits, as an optimal-control
problem (CasADi with IPOPT): the yardstick of ``benchmarks/cycle_optimum.py``.

Independent of the product's dynamics on purpose. :func:`lagrangian_model` derives the
actuator torques by Lagrange's equations from the kinetic and potential energy of the five
bodies, differentiated symbolically by CasADi; the product (``planner.dynamics``) projects
Newton-Euler wrenches by virtual work on velocity Jacobians it writes out by hand. Nothing is
shared but the geometry of the conventions (the frame, the in-plane coordinates, the
assembly-mode sign) and the inertial parameters: the passive angles come from the circle
intersection written here, the bodies' angular velocities from their rotation matrices
(``omega^ = Rd R^T``), the equations of motion from

    tau = d/dt (dT/dqd) - dT/dq + dV/dq = M qdd + (d(M qd)/dq) qd - dT/dq + dV/dq,

with the rotors (``rotor_j qd_j^2 / 2``) and the base (``I_base qd1^2 / 2``) in T. The two
routes agreeing to rounding at random states (``tests/dynamics/test_lagrange_oracle.py``)
checks both.

:func:`minimum_time` solves for the fastest motion through a list of tool points, resting
at the stops and passing the others at free speed, exactly through each point: per segment
N intervals of free duration, states (q, qd) at the nodes, a constant qdd on each interval
(so the double integrator is integrated exactly: no discretisation error in the kinematics),
and at every node, at both ends of each interval, the torques within the limits, the joint
velocity and acceleration within theirs, the joint limits, and the validity margins of the
product (kappa(A) <= kappa_max, the serial measures of the working mode >= serial_min).
The torque between nodes is not bounded; the caller re-checks the answer densely with the
product's inverse dynamics (``dense_check``) and reports the largest ratio.

Only benchmarks and tests import this module (CasADi is a test dependency, not a run-time
one).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

__all__ = ["OcpResult", "lagrangian_model", "minimum_time"]


def _plane_point(q1, u, w):
    """In-plane (u, w) to 3-D: ``(w cos theta1, u, -w sin theta1)`` (the conventions)."""
    return ca.vertcat(w * ca.cos(q1), u, -w * ca.sin(q1))


def _passive(design, q, sigma):
    """theta4, theta5 from the circle intersection of the legs, and the in-plane C, D, P.
    ``sigma`` is the assembly mode's sign: with ``n = perp(D - C) / |D - C|`` (perp turns by
    +90 deg in (u, w)), P = (C + D) / 2 + sigma h n gives sin(theta5 - theta4) the sign of
    sigma (cross(P - C, P - D) = sigma h |D - C|)."""
    L0, L1, L2 = design.L0, design.L1, design.L2
    c = ca.vertcat(-L0 / 2 + L1 * ca.cos(q[1]), L1 * ca.sin(q[1]))
    d = ca.vertcat(L0 / 2 + L1 * ca.cos(q[2]), L1 * ca.sin(q[2]))
    cd = d - c
    dist2 = ca.dot(cd, cd)
    h = ca.sqrt(L2**2 - dist2 / 4)
    n = ca.vertcat(-cd[1], cd[0]) / ca.sqrt(dist2)
    p = (c + d) / 2 + sigma * h * n
    t4 = ca.atan2(p[1] - c[1], p[0] - c[0])
    t5 = ca.atan2(p[1] - d[1], p[0] - d[0])
    return t4, t5, c, d, p


def _link_frame(q1, phi):
    """Rotation matrix of a link at in-plane angle ``phi``: columns its direction
    ``cos phi y + sin phi e``, its in-plane normal, and the plane normal ``k = e x y``."""
    y = ca.vertcat(0, 1, 0)
    e = ca.vertcat(ca.cos(q1), 0, -ca.sin(q1))
    k = ca.cross(e, y)
    along = ca.cos(phi) * y + ca.sin(phi) * e
    normal = -ca.sin(phi) * y + ca.cos(phi) * e
    return ca.horzcat(along, normal, k), along


@dataclass(frozen=True)
class Model:
    """CasADi functions of one design, inertia, gravity and assembly mode.

    ``tau(q, qd, qdd)`` (3,), N m; ``point(q)`` P (3,), m; ``measures(q)``: kappa(A) and the
    three signed serial measures (w / (L1 + L2), sin(theta4 - theta2), sin(theta5 - theta3)).
    """

    tau: ca.Function
    point: ca.Function
    measures: ca.Function


def lagrangian_model(design, inertia, gravity, assembly_mode: str) -> Model:
    """The closed chain's equations of motion by Lagrange (module docstring)."""
    q, qd, qdd = ca.SX.sym("q", 3), ca.SX.sym("qd", 3), ca.SX.sym("qdd", 3)
    sigma = 1.0 if assembly_mode == "+" else -1.0
    t4, t5, c, d, p = _passive(design, q, sigma)
    g = ca.DM(np.asarray(gravity, dtype=float))
    L0, L1, L2 = design.L0, design.L1, design.L2
    prox, dist = inertia.proximal, inertia.distal
    bodies = [  # (mass, com in-plane (u, w), in-plane angle, link or None for a point)
        (prox.mass, ca.vertcat(-L0 / 2, 0) + prox.com * L1 * _a(q[1]), q[1], prox),
        (prox.mass, ca.vertcat(L0 / 2, 0) + prox.com * L1 * _a(q[2]), q[2], prox),
        (dist.mass, c + dist.com * L2 * _a(t4), t4, dist),
        (dist.mass, d + dist.com * L2 * _a(t5), t5, dist),
        (inertia.payload_mass, p, None, None),
    ]
    kinetic = 0.5 * inertia.base_inertia * qd[0] ** 2
    kinetic += 0.5 * sum(r * qd[j] ** 2 for j, r in enumerate(inertia.rotor))
    potential = 0
    for mass, uw, phi, link in bodies:
        r = _plane_point(q[0], uw[0], uw[1])
        v = ca.jtimes(r, q, qd)
        kinetic += 0.5 * mass * ca.dot(v, v)
        potential -= mass * ca.dot(g, r)
        if link is None:
            continue
        rot, along = _link_frame(q[0], phi)
        rot_dot = ca.reshape(ca.jtimes(ca.vec(rot), q, qd), 3, 3)
        w_hat = rot_dot @ rot.T
        omega = ca.vertcat(w_hat[2, 1], w_hat[0, 2], w_hat[1, 0])
        tensor = link.I_perp * ca.SX.eye(3) + (link.I_axial - link.I_perp) * (along @ along.T)
        kinetic += 0.5 * ca.dot(omega, tensor @ omega)
    mass_matrix, _ = ca.hessian(kinetic, qd)
    momentum = ca.gradient(kinetic, qd)
    tau = (
        mass_matrix @ qdd
        + ca.jtimes(momentum, q, qd)
        - ca.gradient(kinetic, q)
        + ca.gradient(potential, q)
    )
    point = _plane_point(q[0], p[0], p[1])
    delta = t4 - t5
    kappa = (1 + ca.fabs(ca.cos(delta))) / ca.fabs(ca.sin(delta))
    measures = ca.vertcat(kappa, p[1] / (L1 + L2), ca.sin(t4 - q[1]), ca.sin(t5 - q[2]))
    return Model(
        ca.Function("tau", [q, qd, qdd], [tau]),
        ca.Function("point", [q], [point]),
        ca.Function("measures", [q], [measures]),
    )


def _a(angle):
    return ca.vertcat(ca.cos(angle), ca.sin(angle))


@dataclass(frozen=True)
class OcpResult:
    """The optimum: ``durations`` (one per segment, s), node times ``t`` (M,), ``q``, ``qd``
    (M, 3), ``qdd`` (M - 1, 3) per interval; ``status`` IPOPT's return status."""

    durations: np.ndarray
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    status: str

    @property
    def total(self) -> float:
        return float(self.durations.sum())

    @property
    def solved(self) -> bool:
        return self.status in ("Solve_Succeeded", "Solved_To_Acceptable_Level")


def minimum_time(
    model: Model,
    postures: np.ndarray,
    stops: Sequence[bool],
    working_modes: Sequence[str],
    *,
    velocity: np.ndarray,
    acceleration: np.ndarray,
    torque: np.ndarray,
    joint_limits: np.ndarray,
    kappa_max: float,
    serial_min: float,
    guess_durations: np.ndarray,
    radii: Sequence[float] | None = None,
    nodes: int = 30,
    max_iter: int = 3000,
    exact_hessian: bool = False,
) -> OcpResult:
    """The fastest motion through ``postures`` (K + 1, 3: the targets' postures, the first
    and the last at rest), at rest at ``postures[k]`` where ``stops[k]`` (length K + 1) and
    passing the others at free velocity; the tool point at each target is that posture's
    point (the posture itself is free: only P is fixed). ``working_modes[k]`` (length K) is
    segment k's mode, its serial measures' signs kept on every node of the segment.
    ``radii`` (K + 1, rad; default zeros): a passed target with a radius r > 0 is met within
    the joint-space ball of radius r about its posture (the product's ``blend``) instead of
    exactly on its point.
    ``guess_durations`` (K,) starts the solver; the initial path is the straight joint-space
    line between the postures. IPOPT approximates the Lagrangian's Hessian by L-BFGS unless
    ``exact_hessian`` (the symbolic Hessian of the torques at every node costs seconds to
    build and gives the same optimum here, to 1e-6 s)."""
    postures = np.asarray(postures, dtype=float)
    segments = len(postures) - 1
    radii = [0.0] * (segments + 1) if radii is None else list(radii)
    opti = ca.Opti()
    durations = opti.variable(segments)
    q = [opti.variable(3, nodes + 1) for _ in range(segments)]
    qd = [opti.variable(3, nodes + 1) for _ in range(segments)]
    qdd = [opti.variable(3, nodes) for _ in range(segments)]
    lo, hi = joint_limits
    for k in range(segments):
        h = durations[k] / nodes
        signs = [1.0 if s == "+" else -1.0 for s in working_modes[k]]
        opti.subject_to(durations[k] >= 1e-3)
        for i in range(nodes):
            opti.subject_to(
                q[k][:, i + 1] == q[k][:, i] + h * qd[k][:, i] + h**2 / 2 * qdd[k][:, i]
            )
            opti.subject_to(qd[k][:, i + 1] == qd[k][:, i] + h * qdd[k][:, i])
            for node in (i, i + 1):
                tau = model.tau(q[k][:, node], qd[k][:, node], qdd[k][:, i])
                opti.subject_to(opti.bounded(-torque, tau, torque))
            opti.subject_to(opti.bounded(-acceleration, qdd[k][:, i], acceleration))
        for i in range(nodes + 1):
            opti.subject_to(opti.bounded(-velocity, qd[k][:, i], velocity))
            opti.subject_to(opti.bounded(lo, q[k][:, i], hi))
            m = model.measures(q[k][:, i])
            opti.subject_to(m[0] <= kappa_max)
            for j in range(3):
                opti.subject_to(signs[j] * m[1 + j] >= serial_min)
        # the segment's ends: on the target points, joined to the neighbours
        for node, index in ((0, k), (nodes, k + 1)):
            if radii[index] > 0:
                gap = q[k][:, node] - postures[index]
                opti.subject_to(ca.dot(gap, gap) <= radii[index] ** 2)
            else:
                opti.subject_to(model.point(q[k][:, node]) == model.point(postures[index]))
        if k > 0:
            opti.subject_to(q[k][:, 0] == q[k - 1][:, nodes])
            opti.subject_to(qd[k][:, 0] == qd[k - 1][:, nodes])
        if stops[k]:
            opti.subject_to(qd[k][:, 0] == 0)
        if k == segments - 1:
            opti.subject_to(qd[k][:, nodes] == 0)
        # initial guess: the straight joint-space line, at rest-to-rest speed
        s = np.linspace(0.0, 1.0, nodes + 1)
        line = postures[k][:, None] + (postures[k + 1] - postures[k])[:, None] * s[None, :]
        opti.set_initial(q[k], line)
        opti.set_initial(qd[k], np.zeros((3, nodes + 1)))
        opti.set_initial(qdd[k], np.zeros((3, nodes)))
    opti.subject_to(q[0][:, 0] == postures[0])  # the cycle starts where the product's does
    opti.set_initial(durations, np.asarray(guess_durations, dtype=float))
    opti.minimize(ca.sum1(durations))
    opti.solver(
        "ipopt",
        {"print_time": False},
        {
            "print_level": 0,
            "max_iter": max_iter,
            "sb": "yes",
            "tol": 1e-8,
            "hessian_approximation": "exact" if exact_hessian else "limited-memory",
        },
    )
    try:
        sol = opti.solve()
        value, status = sol.value, sol.stats()["return_status"]
    except RuntimeError:
        value, status = opti.debug.value, opti.stats()["return_status"]
    dur = np.atleast_1d(np.asarray(value(durations), dtype=float))
    qs = [np.asarray(value(x)).T for x in q]
    qds = [np.asarray(value(x)).T for x in qd]
    qdds = [np.asarray(value(x)).T for x in qdd]
    times = [np.linspace(0.0, dur[k], nodes + 1) + dur[:k].sum() for k in range(segments)]
    return OcpResult(
        dur,
        np.concatenate([times[0], *[t[1:] for t in times[1:]]]),
        np.vstack([qs[0], *[x[1:] for x in qs[1:]]]),
        np.vstack([qds[0], *[x[1:] for x in qds[1:]]]),
        np.vstack(qdds),
        status,
    )


def dense_samples(result: OcpResult, per_interval: int = 10):
    """The optimum's exact motion (constant qdd on each interval) at ``per_interval`` points
    of every interval: t, q, qd, qdd for a dense re-check of the torques."""
    ts, qs, qds, qdds = [], [], [], []
    for i in range(len(result.t) - 1):
        h = result.t[i + 1] - result.t[i]
        s = np.linspace(0.0, h, per_interval, endpoint=False)[:, None]
        a = result.qdd[i][None, :]
        ts.append(result.t[i] + s[:, 0])
        qs.append(result.q[i] + result.qd[i] * s + a * s**2 / 2)
        qds.append(result.qd[i] + a * s)
        qdds.append(np.repeat(a, per_interval, axis=0))
    return np.concatenate(ts), np.vstack(qs), np.vstack(qds), np.vstack(qdds)
