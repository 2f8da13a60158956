"""The simulated robot: the product's MJCF model (:func:`planner.dynamics.mjcf.to_mjcf`: the
closed chain, the design's inertia and rotors, gravity) run in MuJoCo under a controller
(:mod:`planner.simulation.controller`), its actuators saturating at the torque limits. This
is the only module of the library that imports ``mujoco``.

The engine's settings, and why (``docs/simulation.md``; measured in ``tests/simulation``):

- RK4 at a physics step of at most :data:`MAX_PHYSICS_STEP` (the largest that divides the
  control period: 0.5 ms, two steps a period at 1 kHz), the loop's ``connect`` with
  ``solref`` :data:`LOOP_SOLREF` (2 ms, at least 4 steps) and ``solimp`` 0.9999 (the
  export's). Measured on the Adept cycle at 1 kHz (``docs/simulation.md``) against RK4 at
  25 us: 7e-8 rad apart, the loop's tips 2e-8 m from the product's P, ~20x faster than real
  time; Euler and ``implicitfast`` at 0.1-0.2 ms are 5e-4 to 1e-3 rad apart (not honest
  enough for a tracking error of 0.02 mm), RK4 at 0.1 ms costs 4x for 3e-8 rad. A soft loop
  (solimp's default 0.9) would bend the actuated accelerations by ~10 %.
- The loop is closed where the product's forward kinematics puts the passive joints, at the
  reference's first posture and assembly mode (MuJoCo picks no assembly mode: the initial
  guess does); the velocities start as the reference's, mapped to the tree's five joints
  through the loop's Jacobian (``qvel = S qd``, ``S = [I; -pinv(J_p) J_a]``). After the run,
  the sign of sin(theta5 - theta4) at every sample tells whether the loop kept its mode.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from planner.design import Design
from planner.dynamics import DEFAULT_GRAVITY, Inertia, check_gravity, inverse_dynamics
from planner.dynamics.mjcf import to_mjcf
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
    "LOOP_SOLREF",
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
#: The largest physics step, s (RK4), and the loop's ``solref`` time constant, s (4 steps).
MAX_PHYSICS_STEP = 5e-4
LOOP_SOLREF = 2e-3
#: The longest hold at the last posture after the motion, waiting for it to settle, s.
DEFAULT_HOLD_S = 1.0
#: P within this of the reference counts as settled, mm.
DEFAULT_SETTLE_TOLERANCE_MM = 0.1
#: Most control samples one simulation records (the motion and the hold at ``rate_hz``):
#: 200 s at 1 kHz, ~20 s of computation.
MAX_SIMULATION_SAMPLES = 200_000
#: The loop's tips at the first posture farther apart than this (m): it did not close.
_CLOSED_LOOP_TOL = 1e-9
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
    ff, mass = _feed_forward(design, inertia, reference, t, period, g, assembly_mode)
    kp, kd = controller.gains(np.diagonal(mass[0]))
    n_sub = int(np.ceil(period / MAX_PHYSICS_STEP - 1e-9))
    xml = to_mjcf(
        design,
        inertia,
        gravity=gravity,
        home=reference.q[0],
        assembly_mode=assembly_mode,
        torque_limits=limits,
        timestep=period / n_sub,
        loop_solref=LOOP_SOLREF,
    )
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    act, pas, tips = _start(model, data, reference.qd[0])
    lim = np.asarray(limits) if limits is not None else np.full(3, np.inf)

    law = _Law(ff, mass, kp, kd, controller.kind == "computed_torque", lim)
    hold = _Hold(n_end, max(1, round(SETTLE_WINDOW_S * rate_hz)), 1e-3 * settle_tolerance_mm)
    rec = _control_loop(model, data, law, hold, q_ref, qd_ref, p_ref, tips, n_sub, deadline)
    n = rec.n
    rec_q, rec_qd = rec.qpos[:, act], rec.qvel[:, act]
    rec_p = 0.5 * (rec.tips[:, 0] + rec.tips[:, 1])
    theta4 = rec.qpos[:, act[1]] + rec.qpos[:, pas[0]]
    theta5 = rec.qpos[:, act[2]] + rec.qpos[:, pas[1]]
    p_error_mm = 1e3 * np.linalg.norm(rec_p - p_ref[:n], axis=1)
    stops = find_stops(reference)
    window = min(hold.window, n - n_end)
    settles = settle_times(stops, t[:n], p_error_mm, settle_tolerance_mm, window)
    final = settles[-1]
    sign = _mode_sign(design, reference.q[0], assembly_mode)
    return Simulation(
        t=t[:n],
        q=rec_q,
        qd=rec_qd,
        tau=rec.tau,
        p=rec_p,
        q_ref=q_ref[:n],
        p_ref=p_ref[:n],
        p_error_mm=p_error_mm,
        tracking=tracking_of(rec_q, q_ref[:n], p_error_mm),
        planned_duration=reference.end - reference.start,
        realised_duration=None if final is None else reference.end - reference.start + final,
        stops=tuple(stops),
        settle_times=tuple(settles),
        engine=ENGINE,
        controller=controller.kind,
        rate_hz=float(rate_hz),
        physics_timestep=float(model.opt.timestep),
        saturated=int(np.sum(np.any(rec.raw != rec.tau, axis=1))),
        assembly_kept=bool(np.all(np.sign(np.sin(theta5 - theta4)) == sign)),
        computation_time_s=rec.cpu,
    )


@dataclass(frozen=True, slots=True)
class _Law:
    """The control law's data: feed-forward (K, 3), mass matrices (K, 3, 3), gains, the
    kind, the torque limits (3,)."""

    ff: np.ndarray
    mass: np.ndarray
    kp: np.ndarray
    kd: np.ndarray
    computed: bool
    limits: np.ndarray


@dataclass(frozen=True, slots=True)
class _Hold:
    """The hold after the motion: its first instant, the settled samples that end it, the
    tolerance (m)."""

    first: int
    window: int
    tolerance_m: float


@dataclass(frozen=True, slots=True)
class _Record:
    """The loop's record: n samples of MuJoCo's qpos, qvel, tip positions (n, 2, 3), the
    torques before and after saturation; its CPU time."""

    n: int
    qpos: np.ndarray
    qvel: np.ndarray
    tips: np.ndarray
    raw: np.ndarray
    tau: np.ndarray
    cpu: float


def _control_loop(
    model: Any,
    data: Any,
    law: _Law,
    hold: _Hold,
    q_ref: np.ndarray,
    qd_ref: np.ndarray,
    p_ref: np.ndarray,
    tips: list[int],
    n_sub: int,
    deadline: float | None,
) -> _Record:
    """Run the controller at each instant of ``q_ref`` (K, 3) until the hold ends: record the
    state, compute and clip the torque, step the physics over one control period
    (``n_sub`` physics steps)."""
    n_total = q_ref.shape[0]
    act = _actuated(model)
    qpos, qvel = np.empty((n_total, model.nq)), np.empty((n_total, model.nv))
    tip_xyz, raw, tau_rec = (
        np.empty((n_total, 2, 3)),
        np.empty((n_total, 3)),
        np.empty((n_total, 3)),
    )
    settled_run, k = 0, 0
    started = time.process_time()
    for k in range(n_total):
        if k % _DEADLINE_EVERY == 0:
            check_deadline(deadline, "simulating")
        qpos[k], qvel[k], tip_xyz[k] = data.qpos, data.qvel, data.site_xpos[tips]
        q, qd = qpos[k, act], qvel[k, act]
        v = law.kp * (q_ref[k] - q) + law.kd * (qd_ref[k] - qd)
        tau = law.ff[k] + law.mass[k] @ v if law.computed else v
        raw[k] = tau
        tau_rec[k] = clipped = np.minimum(np.maximum(tau, -law.limits), law.limits)
        if k >= hold.first:
            d = 0.5 * (tip_xyz[k, 0] + tip_xyz[k, 1]) - p_ref[k]
            settled_run = settled_run + 1 if float(d @ d) <= hold.tolerance_m**2 else 0
            if settled_run >= hold.window or k == n_total - 1:
                break
        data.ctrl[:] = clipped
        mujoco.mj_step(model, data, nstep=n_sub)
        mujoco.mj_kinematics(model, data)
    n = k + 1
    return _Record(
        n, qpos[:n], qvel[:n], tip_xyz[:n], raw[:n], tau_rec[:n], time.process_time() - started
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
    t: np.ndarray,
    period: float,
    gravity: np.ndarray,
    assembly_mode: str,
) -> tuple[np.ndarray, np.ndarray]:
    """The feed-forward torques (K, 3) held over each control period from the instants
    ``t`` (K,), and the mass matrices (K, 3, 3) there: the product's inverse dynamics at the
    period's middle (q and qd of the reference there) with the period's **mean**
    acceleration, ``(qd(t + T) - qd(t)) / T``. A torque held over the period then gives the
    velocity change the reference makes over it, even where its acceleration jumps inside
    the period (a time-optimal trajectory's switches fall between the samples: the
    acceleration at the middle would be off by up to the jump there, measured 0.49 mm of P
    on the Adept cycle at 1 kHz, against 0.022 mm with the mean). InputError at ``q.<i>`` (the nearest
    sample) where the reference is singular."""
    times = t + period / 2
    q, qd, _ = reference.at(times)
    qdd = (reference.at(t + period)[1] - reference.at(t)[1]) / period
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


def _actuated(model: Any) -> list[int]:
    """MuJoCo's dof indices of theta1, theta2, theta3 (every joint a hinge: their qpos
    indices too)."""
    return [int(model.joint(name).dofadr[0]) for name in ("theta1", "theta2", "theta3")]


def _start(model, data, qd0: np.ndarray) -> tuple[list[int], list[int], list[int]]:
    """Put the model at its keyframe (the loop closed at the first posture) with the
    reference's first velocities; the actuated and passive dof indices and the tip sites."""
    act = _actuated(model)
    pas = [int(model.joint(name).dofadr[0]) for name in ("theta4_rel", "theta5_rel")]
    tips = [int(model.site("tip_C").id), int(model.site("tip_D").id)]
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
    gap = float(np.linalg.norm(data.site_xpos[tips[0]] - data.site_xpos[tips[1]]))
    if gap > _CLOSED_LOOP_TOL:
        raise InputError(
            f"the loop does not close at the first posture (its tips {gap:g} m apart)",
            field=("q", 0),
        )
    return act, pas, tips


def _mode_sign(design: Design, q0: np.ndarray, assembly_mode: str) -> float:
    """The sign of sin(theta5 - theta4) of the product's posture in ``assembly_mode``."""
    passive = forward_batch(design, np.asarray(q0).reshape(1, 3), assembly_mode).passive[0]
    return float(np.sign(np.sin(passive[1] - passive[0])))
