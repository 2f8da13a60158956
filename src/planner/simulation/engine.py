"""The simulated robot: the product's MJCF model (:func:`planner.dynamics.mjcf.to_mjcf`: the
closed chain, the design's inertia and rotors, gravity) run in MuJoCo under a controller
(:mod:`planner.simulation.controller`), its actuators saturating at the torque limits. This
is the only module of the library that imports ``mujoco``.

The engine's settings, and why (``docs/simulation.md``; measured in ``tests/simulation``):

- RK4 at a physics step of at most :data:`MAX_PHYSICS_STEP` (the largest that divides the
  control period), the loop's ``connect`` with ``solref`` 20 physics steps and ``solimp``
  0.9999 (the export's): RK4 follows the product's dynamics ~100x closer than Euler or
  ``implicitfast`` on this closed chain, and a soft loop (solimp's default 0.9) bends the
  actuated accelerations by ~10 %. 2e-4 s rather than the export's 1e-4 s halves the cost
  (the simulation then runs ~10x faster than real time) for an error still far below the
  controller's.
- The loop is closed where the product's forward kinematics puts the passive joints, at the
  reference's first posture and assembly mode (MuJoCo picks no assembly mode: the initial
  guess does); the velocities start as the reference's, mapped to the tree's five joints
  through the loop's Jacobian (``qvel = S qd``, ``S = [I; -pinv(J_p) J_a]``). After the run,
  the sign of sin(theta5 - theta4) at every sample tells whether the loop kept its mode.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import mujoco
import numpy as np

from planner.design import Design
from planner.dynamics import DEFAULT_GRAVITY, Inertia, check_gravity, inverse_dynamics
from planner.dynamics.mjcf import JOINT_NAMES, to_mjcf
from planner.exceptions import InputError, check_deadline
from planner.kinematics import forward_batch
from planner.simulation.controller import Controller
from planner.simulation.reference import Reference, find_stops
from planner.simulation.result import (
    SETTLE_WINDOW_S,
    Simulation,
    settle_times,
    tracking_of,
)

__all__ = [
    "DEFAULT_HOLD_S",
    "DEFAULT_RATE_HZ",
    "DEFAULT_SETTLE_TOLERANCE_MM",
    "ENGINE",
    "MAX_PHYSICS_STEP",
    "MAX_RATE_HZ",
    "MAX_SIMULATION_SAMPLES",
    "MIN_RATE_HZ",
    "simulate",
]

#: The engine's name and version, as the answer reports it.
ENGINE = f"mujoco {mujoco.__version__}"
#: The control rate when none is given, Hz, and its bounds.
DEFAULT_RATE_HZ = 1000.0
MIN_RATE_HZ = 10.0
MAX_RATE_HZ = 10_000.0
#: The largest physics step, s (RK4).
MAX_PHYSICS_STEP = 2e-4
#: The longest hold at the last posture after the motion, waiting for it to settle, s.
DEFAULT_HOLD_S = 1.0
#: P within this of the reference counts as settled, mm.
DEFAULT_SETTLE_TOLERANCE_MM = 0.1
#: Most control samples one simulation records (the motion and the hold at ``rate_hz``):
#: 200 s at 1 kHz, ~20 s of computation.
MAX_SIMULATION_SAMPLES = 200_000
#: Control steps between two looks at the deadline.
_DEADLINE_EVERY = 1000


def simulate(
    design: Design,
    reference: Reference,
    *,
    inertia: Inertia | None = None,
    controller: Controller | None = None,
    rate_hz: float = DEFAULT_RATE_HZ,
    torque_limits: Sequence[float] | None = None,
    gravity: Sequence[float] = DEFAULT_GRAVITY,
    assembly_mode: str = "+",
    settle_tolerance_mm: float = DEFAULT_SETTLE_TOLERANCE_MM,
    hold_s: float = DEFAULT_HOLD_S,
    deadline: float | None = None,
    max_samples: int | None = None,
) -> Simulation:
    """Run ``reference`` on the simulated robot.

    Parameters
    ----------
    design, inertia : the robot (inertia default :meth:`Inertia.default`)
    reference : the trajectory to follow (:class:`~planner.simulation.Reference`)
    controller : default ``computed_torque`` with its default gains
    rate_hz : control rate, Hz, in [:data:`MIN_RATE_HZ`, :data:`MAX_RATE_HZ`]
    torque_limits : 3 N m, > 0: the actuators saturate there (None: no saturation)
    gravity : m/s^2, base frame; assembly_mode : '+' or '-' (the reference's)
    settle_tolerance_mm : > 0; hold_s : >= 0, the longest hold after the motion
    deadline : a :func:`time.monotonic` value (DeadlineError past it); max_samples : a
        bound on the recorded samples below :data:`MAX_SIMULATION_SAMPLES`

    Raises
    ------
    InputError
        A bad option (its field), a reference posture that does not assemble or is
        singular (field ``q.<i>``), or more samples than the bound (field ``rate_hz``).
    """
    controller = controller if controller is not None else Controller()
    inertia = inertia if inertia is not None else Inertia.default(design)
    g = check_gravity(gravity)
    limits = _check_options(rate_hz, torque_limits, settle_tolerance_mm, hold_s)
    period = 1.0 / rate_hz
    # the first control instant at or after the end, then the hold
    n_end = int(np.ceil((reference.end - reference.start) * rate_hz - 1e-9))
    n_total = n_end + 1 + int(np.ceil(hold_s * rate_hz - 1e-9))
    bound = min(MAX_SIMULATION_SAMPLES, max_samples or MAX_SIMULATION_SAMPLES)
    if n_total > bound:
        raise InputError(
            f"the simulation would record {n_total} samples ({reference.end - reference.start:g} s "
            f"and a hold of {hold_s:g} s at {rate_hz:g} Hz), more than the bound {bound}",
            field="rate_hz",
        )
    _check_assembles(design, reference.q, assembly_mode)
    t = reference.start + np.arange(n_total) * period
    q_ref, qd_ref, _ = reference.at(t)
    p_ref = forward_batch(design, q_ref, assembly_mode).p
    ff, mass = _feed_forward(design, inertia, reference, t + period / 2, g, assembly_mode)
    kp, kd = controller.gains(np.diagonal(mass[0]))
    computed = controller.kind == "computed_torque"
    n_sub = int(np.ceil(period / MAX_PHYSICS_STEP - 1e-9))
    xml = to_mjcf(
        design,
        inertia,
        gravity=g,
        home=reference.q[0],
        assembly_mode=assembly_mode,
        torque_limits=limits,
        timestep=period / n_sub,
    )
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    act, pas, tips = _start(model, data, reference.qd[0])
    lim = np.asarray(limits) if limits is not None else np.full(3, np.inf)

    rec_q, rec_qd, rec_tau = np.empty((n_total, 3)), np.empty((n_total, 3)), np.empty((n_total, 3))
    rec_p, rec_sign = np.empty((n_total, 3)), np.empty(n_total)
    window = max(1, round(SETTLE_WINDOW_S * rate_hz))
    settled_run, saturated, k = 0, 0, 0
    started = time.process_time()
    for k in range(n_total):
        if k % _DEADLINE_EVERY == 0:
            check_deadline(deadline, "simulating")
        q, qd = data.qpos[act], data.qvel[act]
        rec_q[k], rec_qd[k] = q, qd
        rec_p[k] = 0.5 * (data.site_xpos[tips[0]] + data.site_xpos[tips[1]])
        rec_sign[k] = np.sin(
            data.qpos[pas[1]] + data.qpos[act[2]] - data.qpos[pas[0]] - data.qpos[act[1]]
        )
        v = kp * (q_ref[k] - q) + kd * (qd_ref[k] - qd)
        tau = ff[k] + mass[k] @ v if computed else v
        clipped = np.clip(tau, -lim, lim)
        saturated += bool(np.any(clipped != tau))
        rec_tau[k] = clipped
        if k >= n_end:
            err_mm = 1e3 * np.linalg.norm(rec_p[k] - p_ref[k])
            settled_run = settled_run + 1 if err_mm <= settle_tolerance_mm else 0
            if settled_run >= window or k == n_total - 1:
                break
        data.ctrl[:] = clipped
        mujoco.mj_step(model, data, nstep=n_sub)
        mujoco.mj_kinematics(model, data)
    cpu = time.process_time() - started
    n = k + 1
    p_error_mm = 1e3 * np.linalg.norm(rec_p[:n] - p_ref[:n], axis=1)
    stops = find_stops(reference)
    settles = settle_times(stops, t[:n], p_error_mm, settle_tolerance_mm, min(window, n - n_end))
    final = settles[-1]
    sign = _mode_sign(design, reference.q[0], assembly_mode)
    return Simulation(
        t=t[:n],
        q=rec_q[:n],
        qd=rec_qd[:n],
        tau=rec_tau[:n],
        p=rec_p[:n],
        q_ref=q_ref[:n],
        p_ref=p_ref[:n],
        p_error_mm=p_error_mm,
        tracking=tracking_of(rec_q[:n], q_ref[:n], p_error_mm),
        planned_duration=reference.end - reference.start,
        realised_duration=None if final is None else reference.end - reference.start + final,
        stops=tuple(stops),
        settle_times=tuple(settles),
        engine=ENGINE,
        controller=controller.kind,
        rate_hz=float(rate_hz),
        physics_timestep=float(model.opt.timestep),
        saturated=saturated,
        assembly_kept=bool(np.all(np.sign(rec_sign[:n]) == sign)),
        computation_time_s=cpu,
    )


def _check_options(
    rate_hz: float,
    torque_limits: Sequence[float] | None,
    settle_tolerance_mm: float,
    hold_s: float,
) -> tuple[float, float, float] | None:
    if not (np.isfinite(rate_hz) and MIN_RATE_HZ <= rate_hz <= MAX_RATE_HZ):
        raise InputError(
            f"rate_hz must be in [{MIN_RATE_HZ:g}, {MAX_RATE_HZ:g}] Hz, got {rate_hz!r}",
            field="rate_hz",
        )
    if not (np.isfinite(settle_tolerance_mm) and settle_tolerance_mm > 0):
        raise InputError("settle_tolerance_mm must be > 0", field="settle_tolerance_mm")
    if not (np.isfinite(hold_s) and hold_s >= 0):
        raise InputError("hold_s must be >= 0", field="hold_s")
    if torque_limits is None:
        return None
    lim = np.asarray(torque_limits, dtype=float)
    if lim.shape != (3,) or not np.all(np.isfinite(lim)) or np.any(lim <= 0):
        raise InputError(
            f"torque limits must be 3 values > 0, got {torque_limits!r}", field="torque"
        )
    return (float(lim[0]), float(lim[1]), float(lim[2]))


def _check_assembles(design: Design, q: np.ndarray, assembly_mode: str) -> None:
    """InputError at ``q.<i>`` for the first reference sample that does not assemble."""
    ok = forward_batch(design, q, assembly_mode).ok
    if not np.all(ok):
        i = int(np.flatnonzero(~ok)[0])
        raise InputError(
            f"q[{i}] = {q[i].tolist()} does not assemble in assembly mode {assembly_mode!r}: "
            "the closed chain cannot be simulated there",
            field=("q", i),
        )


def _feed_forward(
    design: Design,
    inertia: Inertia,
    reference: Reference,
    times: np.ndarray,
    gravity: np.ndarray,
    assembly_mode: str,
) -> tuple[np.ndarray, np.ndarray]:
    """The product's torques (K, 3) and mass matrices (K, 3, 3) of the reference at
    ``times``; InputError at ``q.<i>`` (the nearest sample) where it is singular."""
    q, qd, qdd = reference.at(times)
    batch = inverse_dynamics(
        design,
        inertia,
        q,
        qd,
        qdd,
        assembly_mode=assembly_mode,
        gravity=gravity,
        with_mass_matrix=True,
    )
    if not np.all(batch.ok):
        k = int(np.flatnonzero(~batch.ok)[0])
        i = int(np.clip(np.searchsorted(reference.t, times[k]), 0, reference.t.size - 1))
        raise InputError(
            f"the reference is singular near t = {times[k]:g} s (q[{i}] = "
            f"{reference.q[i].tolist()}): the closed chain's dynamics are undefined there",
            field=("q", i),
        )
    assert batch.mass_matrix is not None
    return batch.tau, batch.mass_matrix


def _start(model, data, qd0: np.ndarray) -> tuple[list[int], list[int], tuple[int, int]]:
    """Put the model at its keyframe (the loop closed at the first posture) with the
    reference's first velocities; the actuated and passive dof indices and the tip sites."""
    dof = {name: int(model.joint(name).dofadr[0]) for name in JOINT_NAMES}
    act = [dof["theta1"], dof["theta2"], dof["theta3"]]
    pas = [dof["theta4_rel"], dof["theta5_rel"]]
    tips = (int(model.site("tip_C").id), int(model.site("tip_D").id))
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    jc, jd = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    mujoco.mj_jacSite(model, data, jc, None, tips[0])
    mujoco.mj_jacSite(model, data, jd, None, tips[1])
    j = jc - jd
    qvel = np.zeros(model.nv)
    qvel[act] = qd0
    qvel[pas] = -np.linalg.pinv(j[:, pas]) @ (j[:, act] @ qd0)
    data.qvel[:] = qvel
    mujoco.mj_forward(model, data)
    return act, pas, tips


def _mode_sign(design: Design, q0: np.ndarray, assembly_mode: str) -> float:
    """The sign of sin(theta5 - theta4) of the product's posture in ``assembly_mode``."""
    passive = forward_batch(design, np.asarray(q0).reshape(1, 3), assembly_mode).passive[0]
    return float(np.sign(np.sin(passive[1] - passive[0])))
