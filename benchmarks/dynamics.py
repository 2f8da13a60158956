"""Dynamics: inverse-dynamics throughput, torque-limited timing cost and the duration gained
over a uniform slow-down.

    .venv/bin/python benchmarks/dynamics.py [--postures 200000] [--paths 20] [--seed 0] [--repeats 3]

1. Inverse dynamics of N random postures of the default design (default inertia), one core:
   ``planner.dynamics.inverse_dynamics`` (its compiled loop; tau alone, and tau with M),
   against the same formulas in vectorised numpy (``numpy_torques`` below, with the same
   forward kinematics), the library function called once per posture, and
   against MuJoCo's per-posture ``mj_inverse`` on the exported model (with the S-matrix
   projection to actuated coordinates that a closed chain needs, as tests/dynamics does).
   Goal (issue 25): >= 1 M postures/s vectorised.
2. On seeded 20-waypoint random walks (default design, limits v 4 rad/s, a 40 rad/s^2, torque
   limits 60 % of the velocity-limited trajectory's peak torque per joint, at least 1.3 x the
   largest gravity torque on the path): ``time_path`` wall time with the torque limits
   against velocity/acceleration only (goal: within 1.5x), interleaved path by path, the best
   of --repeats runs of each; and the
   torque-limited duration against the usual practice, the velocity-limited trajectory
   slowed uniformly until its torques hold (ratio expected well below 1).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from _machine import print_machine

from planner import Design, forward_batch
from planner.dynamics import Inertia, inverse_dynamics
from planner.exceptions import TimingError
from planner.timing import JointLimits, time_path
from planner.timing.torque import TorqueModel, torque_time_scale


def numpy_torques(design, inertia, q, passive, qd, qdd, gravity):
    """The same formulas as the compiled kernel, in vectorised numpy (one temporary array
    per operation): the straightforward route the kernel is measured against."""
    l0, l1, l2 = design.L0, design.L1, design.L2
    t1, t2, t3, t4, t5 = q[:, 0], q[:, 1], q[:, 2], passive[:, 0], passive[:, 1]
    k = l1 / (l2 * np.sin(t5 - t4))
    jt4, jt5 = np.zeros_like(q), np.zeros_like(q)
    jt4[:, 1], jt4[:, 2] = -k * np.sin(t5 - t2), k * np.sin(t5 - t3)
    jt5[:, 1], jt5[:, 2] = -k * np.sin(t4 - t2), k * np.sin(t4 - t3)
    d1, d2, d3 = qd[:, 0], qd[:, 1], qd[:, 2]
    dd1, dd2, dd3 = qdd[:, 0], qdd[:, 1], qdd[:, 2]
    c2, s2, c3, s3 = np.cos(t2), np.sin(t2), np.cos(t3), np.sin(t3)
    c4, s4, c5, s5 = np.cos(t4), np.sin(t4), np.cos(t5), np.sin(t5)
    # passive rates and accelerations from the loop closure (docs/dynamics.md, eq. P)
    d4 = jt4[:, 1] * d2 + jt4[:, 2] * d3
    d5 = jt5[:, 1] * d2 + jt5[:, 2] * d3
    # R2 = L1 (dd3 n3 - d3^2 a3 - dd2 n2 + d2^2 a2) + L2 (d4^2 a4 - d5^2 a5), (u, w) parts
    r2u = l1 * (-dd3 * s3 - d3**2 * c3 + dd2 * s2 + d2**2 * c2) + l2 * (d4**2 * c4 - d5**2 * c5)
    r2w = l1 * (dd3 * c3 - d3**2 * s3 - dd2 * c2 + d2**2 * s2) + l2 * (d4**2 * s4 - d5**2 * s5)
    ls = l2 * np.sin(t5 - t4)
    dd4 = (r2u * c5 + r2w * s5) / ls
    dd5 = (r2u * c4 + r2w * s4) / ls
    # gravity in the plane's frame (e, y, k)
    ct1, st1 = np.cos(t1), np.sin(t1)
    g_e = gravity[0] * ct1 - gravity[2] * st1
    g_y = gravity[1]
    g_k = gravity[0] * st1 + gravity[2] * ct1
    tau = np.zeros_like(q)
    tau[:, 0] += inertia.base_inertia * dd1
    tau += inertia.rotor_array * qdd
    prox, dist = inertia.proximal, inertia.distal
    half = l0 / 2

    def translation(m, u, w, du, dw, ddu, ddw, ju, jw):
        # F = m (a - g) in (e, y, k); tau_j = F . dv/dqd_j (v = du y + dw e - w d1 k)
        f_e = m * (ddw - w * d1**2 - g_e)
        f_y = m * (ddu - g_y)
        f_k = m * (-(2 * dw * d1 + w * dd1) - g_k)
        tau[:] += ju * f_y[:, None] + jw * f_e[:, None]
        tau[:, 0] += -w * f_k

    def rotation(link, phi, dphi, ddphi, jphi):
        # omega = d1 y - dphi k, alpha = dd1 y - ddphi k - dphi d1 e; link direction
        # e_link = (sin phi, cos phi, 0); I = I_perp Id + dI e_link e_link^T
        cp, sp = np.cos(phi), np.sin(phi)
        di = link.I_axial - link.I_perp
        e_alpha = -sp * dphi * d1 + cp * dd1
        e_omega = cp * d1
        mo_y = link.I_perp * dd1 + di * e_alpha * cp - di * e_omega * dphi * sp
        mo_k = -link.I_perp * ddphi - di * e_omega * d1 * sp
        tau[:, 0] += mo_y
        tau[:] += -jphi * mo_k[:, None]

    # proximal links: pivot A (u = -L0/2) with theta2, pivot B (+L0/2) with theta3
    for sign, c, s, d, dd, j in ((-1.0, c2, s2, d2, dd2, 1), (1.0, c3, s3, d3, dd3, 2)):
        a = prox.com * l1
        ju = np.zeros_like(q)
        jw = np.zeros_like(q)
        ju[:, j] = -a * s
        jw[:, j] = a * c
        translation(
            prox.mass,
            sign * half + a * c,
            a * s,
            -a * s * d,
            a * c * d,
            a * (-dd * s - d**2 * c),
            a * (dd * c - d**2 * s),
            ju,
            jw,
        )
        jphi = np.zeros_like(q)
        jphi[:, j] = 1.0
        rotation(prox, t2 if j == 1 else t3, d, dd, jphi)
    # distal links (C with theta4, D with theta5) and the payload at P (on the C side)
    legs = (
        (-1.0, c2, s2, d2, dd2, 1, c4, s4, t4, d4, dd4, jt4),
        (1.0, c3, s3, d3, dd3, 2, c5, s5, t5, d5, dd5, jt5),
    )
    for sign, c, s, d, dd, j, cp, sp, phi, dp, ddp, jp in legs:
        bodies = [(dist.mass, dist.com * l2, dist)]
        if j == 1:
            bodies.append((inertia.payload_mass, l2, None))
        for m, b, link in bodies:
            ju = -b * sp[:, None] * jp
            jw = b * cp[:, None] * jp
            ju[:, j] += -l1 * s
            jw[:, j] += l1 * c
            u = sign * half + l1 * c + b * cp
            w = l1 * s + b * sp
            du = -l1 * s * d - b * sp * dp
            dw = l1 * c * d + b * cp * dp
            ddu = l1 * (-dd * s - d**2 * c) + b * (-ddp * sp - dp**2 * cp)
            ddw = l1 * (dd * c - d**2 * s) + b * (ddp * cp - dp**2 * sp)
            translation(m, u, w, du, dw, ddu, ddw, ju, jw)
            if link is not None:
                rotation(link, phi, dp, ddp, jp)
    return tau


def _postures(design: Design, n: int, rng: np.random.Generator) -> np.ndarray:
    q = rng.uniform(-np.pi, np.pi, size=(3 * n, 3))
    return q[forward_batch(design, q, "+").ok][:n]


def _best(f, repeats: int = 5) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def _mujoco_rate(design: Design, inertia: Inertia, q, qd, qdd) -> float | None:
    try:
        import mujoco
    except ImportError:
        return None
    from planner.dynamics.mjcf import JOINT_NAMES, mjcf_qpos, to_mjcf

    model = mujoco.MjModel.from_xml_string(to_mjcf(design, inertia))
    data = mujoco.MjData(model)
    dofs = [int(model.joint(n).dofadr[0]) for n in JOINT_NAMES]
    act, pas = [dofs[0], dofs[1], dofs[3]], [dofs[2], dofs[4]]
    qpos = mjcf_qpos(design, q, "+")
    jc, jd = np.zeros((3, model.nv)), np.zeros((3, model.nv))

    def jac(pos):
        data.qpos[:] = pos
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_jacSite(model, data, jc, None, model.site("tip_C").id)
        mujoco.mj_jacSite(model, data, jd, None, model.site("tip_D").id)
        return jc - jd

    def run() -> None:
        for i in range(q.shape[0]):
            j = jac(qpos[i])
            pinv = np.linalg.pinv(j[:, pas])
            s = np.zeros((model.nv, 3))
            s[act] = np.eye(3)
            s[pas] = -pinv @ j[:, act]
            v = s @ qd[i]
            jdv = (jac(qpos[i] + 1e-6 * v) - jac(qpos[i] - 1e-6 * v)) @ v / 2e-6
            acc = np.zeros(model.nv)
            acc[act] = qdd[i]
            acc[pas] = -pinv @ (j[:, act] @ qdd[i] + jdv)
            data.qpos[:], data.qvel[:], data.qacc[:] = qpos[i], v, acc
            mujoco.mj_inverse(model, data)
            _ = s.T @ data.qfrc_inverse

    return q.shape[0] / _best(run, 3)


def throughput(n: int, rng: np.random.Generator) -> None:
    design = Design.default()
    inertia = Inertia.default(design)
    q = _postures(design, n, rng)
    qd, qdd = rng.normal(size=q.shape), rng.normal(size=q.shape) * 5
    inverse_dynamics(design, inertia, q[:10], qd[:10], qdd[:10])  # numba kernels loaded
    vec = q.shape[0] / _best(lambda: inverse_dynamics(design, inertia, q, qd, qdd))
    vec_m = q.shape[0] / _best(
        lambda: inverse_dynamics(design, inertia, q, qd, qdd, with_mass_matrix=True)
    )
    batch = forward_batch(design, q, "+")
    g = np.array([0.0, 0.0, -9.81])
    ref = numpy_torques(design, inertia, q, batch.passive, qd, qdd, g)
    fast = inverse_dynamics(design, inertia, q, qd, qdd).tau
    agree = float(np.max(np.abs(ref - fast)) / np.max(np.abs(ref)))
    vec_np = q.shape[0] / _best(
        lambda: (
            numpy_torques(design, inertia, q, batch.passive, qd, qdd, g)
            + forward_batch(design, q, "+").q
        )
    )
    m = 2000

    def loop() -> None:
        for i in range(m):
            inverse_dynamics(design, inertia, q[i], qd[i : i + 1], qdd[i : i + 1])

    per = m / _best(loop, 3)
    mj = _mujoco_rate(design, inertia, q[:m], qd[:m], qdd[:m])
    print(f"inverse dynamics, default design and inertia, {q.shape[0]} postures, one process")
    print(f"{'route':<44} {'postures/s':>12} {'vs per-posture':>15}")
    rows = [
        ("compiled loop (the product), tau", vec),
        ("compiled loop (the product), tau + M", vec_m),
        ("vectorised numpy, same formulas, tau", vec_np),
        ("per-posture numpy (same function, N = 1)", per),
    ]
    if mj is not None:
        rows.append(("MuJoCo per posture (S projection)", mj))
    for label, rate in rows:
        print(f"{label:<44} {rate:>12.4g} {rate / per:>14.1f}x")
    print(f"compiled vs numpy torques agree to {agree:.1e} (relative to the largest)")
    print(f"goal >= 1e6 postures/s vectorised (tau): {'met' if vec >= 1e6 else 'NOT met'}")
    print()


def timing(paths: int, rng: np.random.Generator, repeats: int = 3) -> None:
    design = Design.default()
    base = JointLimits(velocity=(4.0,) * 3, acceleration=(40.0,) * 3)
    model = TorqueModel(design)
    rows = []
    for _ in range(paths * 3):
        if len(rows) >= paths:
            break
        w = np.clip(np.cumsum(rng.uniform(-0.5, 0.5, size=(20, 3)), axis=0), -2.5, 2.5)
        w[:, 2] = np.clip(w[:, 2], 0.3, 2.8)  # keep leg B away from its folded posture
        w[:, 1] = np.clip(w[:, 1], 0.3, 2.8)
        try:
            free = time_path(design, w, base)
            t = np.linspace(0.0, free.duration, 20001)
            q, qd, qdd, _ = free.at(t)
            dyn, grav = model.split(q, qd, qdd)
            peak = np.nanmax(np.abs(dyn + grav), axis=0)
            limit = np.maximum(0.6 * peak, 1.3 * np.nanmax(np.abs(grav), axis=0))
            limits = JointLimits(
                velocity=base.velocity, acceleration=base.acceleration, torque=tuple(limit.tolist())
            )
            limited = time_path(design, w, limits)
        except TimingError:
            continue
        # side by side, interleaved, the best of `repeats` each, in CPU time of this process:
        # the machine is shared (wall times under load were 2-4x and noisy), and the least
        # time is the one least disturbed by other jobs
        t_free, t_lim = np.inf, np.inf
        for _ in range(repeats):
            t0 = time.process_time()
            time_path(design, w, base)
            t_free = min(t_free, time.process_time() - t0)
            t0 = time.process_time()
            time_path(design, w, limits)
            t_lim = min(t_lim, time.process_time() - t0)
        c = torque_time_scale(dyn, grav, limit)
        rows.append((t_free, t_lim, limited.duration / (free.duration / c), limited.repairs))
    if not rows:
        print("no path could be timed")
        return
    t_free, t_lim, ratio, repairs = (np.array(x) for x in zip(*rows, strict=True))
    print(
        f"torque-limited toppra, {len(rows)} seeded 20-waypoint paths (default design; CPU "
        f"time of this process, the best of {repeats} interleaved runs per path)"
    )
    print(f"{'':<44} {'p50':>10} {'p95':>10}")
    print(
        f"{'velocity/acceleration only [ms]':<44} {np.median(t_free) * 1e3:>10.1f} "
        f"{np.percentile(t_free, 95) * 1e3:>10.1f}"
    )
    print(
        f"{'with torque limits [ms]':<44} {np.median(t_lim) * 1e3:>10.1f} "
        f"{np.percentile(t_lim, 95) * 1e3:>10.1f}"
    )
    cost = t_lim / t_free
    print(
        f"{'time ratio torque / velocity-only':<44} {np.median(cost):>10.2f} "
        f"{np.percentile(cost, 95):>10.2f}   goal <= 1.5: "
        f"{'met' if np.median(cost) <= 1.5 else 'NOT met'} (p50)"
    )
    print(
        f"{'duration torque-optimal / uniform slow-down':<44} {np.median(ratio):>10.3f} "
        f"{np.percentile(ratio, 95):>10.3f}   (max {np.max(ratio):.3f})"
    )
    print(f"{'repairs':<44} {np.median(repairs):>10.0f} {np.max(repairs):>10.0f}")


def main() -> None:
    print_machine()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--postures", type=int, default=200_000)
    parser.add_argument("--paths", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=3, help="timings per path (best kept)")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    throughput(args.postures, rng)
    timing(args.paths, rng, args.repeats)


if __name__ == "__main__":
    main()
