"""The validated inputs of one :func:`planner.timing.time_path` call (step 1 of
:mod:`planner.timing.parameterize`): every argument checked, with a typed error naming the
field and the rule, gathered into a :class:`TimingJob` that the later steps read."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from planner.design import Design
from planner.dynamics import DEFAULT_GRAVITY, Inertia
from planner.exceptions import InputError, LimitsError, TimingInfeasibleError
from planner.kinematics import ASSEMBLY_MODES
from planner.timing.checks import StateChecker
from planner.timing.limits import MAX_RATE, MIN_RATE, JointLimits
from planner.timing.options import METHODS
from planner.timing.path import BlendedPath
from planner.timing.torque import TorqueModel, gravity_excess
from planner.timing.trajectory import p_velocity

__all__ = ["MAX_OUTPUT_SAMPLES", "TimingJob", "validate_inputs"]

#: Most output samples of one trajectory.
MAX_OUTPUT_SAMPLES = 1_000_000


def _waypoints(design: Design, waypoints: object) -> np.ndarray:
    try:
        w = np.asarray(waypoints, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"waypoints must be numbers, got {waypoints!r}", field="waypoints"
        ) from exc
    if w.ndim != 2 or w.shape[1] != 3 or w.shape[0] < 1:
        raise InputError(
            f"waypoints must have shape (N, 3) with N >= 1, got {w.shape}", field="waypoints"
        )
    if not np.all(np.isfinite(w)):
        raise InputError("waypoints must be finite (no NaN or infinity)", field="waypoints")
    lo, hi = np.asarray(design.joint_min), np.asarray(design.joint_max)
    out = np.any((w < lo) | (w > hi), axis=1)
    if np.any(out):
        i = int(np.argmax(out))
        raise InputError(
            f"waypoints[{i}] = {w[i].tolist()} is outside the joint limits "
            f"[{list(design.joint_min)}, {list(design.joint_max)}]",
            field="waypoints",
        )
    return w


def _positive(name: str, value: object) -> float:
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a number, got {value!r}", field=name) from exc
    if not (math.isfinite(x) and x > 0):
        raise InputError(f"{name} must be a positive finite number, got {value!r}", field=name)
    return x


def _stop_mask(stop_at: Iterable[int], n: int) -> np.ndarray:
    mask = np.zeros(n, bool)
    for i in stop_at:
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or not 0 <= i < n:
            raise InputError(
                f"stop_at must hold waypoint indices in [0, {n}), got {i!r}", field="stop_at"
            )
        mask[int(i)] = True
    return mask


def _deviation(value: object, n: int, name: str = "max_deviation") -> np.ndarray:
    try:
        dev = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"{name} must be a number or {n} numbers (one per waypoint), got {value!r}",
            field=name,
        ) from exc
    if not np.all(np.isfinite(dev) & (dev >= 0)):
        raise InputError(f"{name} must be finite and >= 0, got {value!r}", field=name)
    return dev


@dataclass(frozen=True, eq=False)
class TimingJob:
    """The validated inputs of one :func:`time_path` call (see its parameters)."""

    design: Design
    waypoints: np.ndarray
    limits: JointLimits
    method: str
    assembly_mode: str
    rate: float
    v_cart: float | None
    max_deviation: np.ndarray
    stop: np.ndarray
    check_states: StateChecker | None
    resolution: float
    deadline: float | None
    max_samples: int
    torque: TorqueModel | None = None
    via: np.ndarray | None = None
    via_radius: np.ndarray | None = None
    grid_refine: float | None = None

    def speed_gain(self, path: BlendedPath) -> Callable[[np.ndarray], np.ndarray] | None:
        """|dP/ds| along ``path`` (m/rad) for the Cartesian speed bound, None without one."""
        if self.v_cart is None:
            return None

        def gain(s: np.ndarray) -> np.ndarray:
            q, d1, _ = path.evaluate_all(s)
            return self.gain_at(q, d1)

        return gain

    def gain_at(self, q: np.ndarray, d1: np.ndarray) -> np.ndarray:
        """|dP/ds| (M,), m/rad, at postures q (M, 3) with path tangents d1 (M, 3) (inf where
        a posture does not assemble): :meth:`speed_gain` where the caller has them."""
        _, v, ok = p_velocity(self.design, q, d1, self.assembly_mode)
        return np.where(ok, np.linalg.norm(v, axis=1), np.inf)


def validate_inputs(
    design: Design,
    waypoints: object,
    limits: object,
    method: object,
    assembly_mode: object,
    sample_rate_hz: object,
    max_cartesian_speed: object,
    max_deviation: object,
    stop_at: Iterable[int],
    check_resolution: object,
    check_states: StateChecker | None,
    deadline: float | None,
    max_samples: int | None,
    inertia: Inertia | None = None,
    gravity: object = DEFAULT_GRAVITY,
    via_at: Iterable[int] = (),
    via_radius: object = None,
    grid_refine: object = None,
) -> TimingJob:
    """Step 1 of :func:`planner.timing.time_path`: every argument checked, with a typed error
    naming the field and the rule (the parameters are ``time_path``'s)."""
    if not isinstance(limits, JointLimits):
        raise LimitsError(f"limits must be a JointLimits, got {type(limits).__name__}")
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}", field="method")
    if method == "ruckig":  # Ruckig needs a jerk: the default when none is asked
        limits = limits.with_ruckig_jerk()
    if assembly_mode not in ASSEMBLY_MODES:
        raise InputError(f"assembly_mode must be '+' or '-', got {assembly_mode!r}")
    w = _waypoints(design, waypoints)
    n = w.shape[0]
    rate = _positive("sample_rate_hz", sample_rate_hz)
    resolution = _positive("check_resolution", check_resolution)
    v_cart = None
    if max_cartesian_speed is not None:
        v_cart = _positive("max_cartesian_speed", max_cartesian_speed)
        if not MIN_RATE <= v_cart <= MAX_RATE:
            raise InputError(
                f"max_cartesian_speed must lie in [{MIN_RATE:g}, {MAX_RATE:g}] m/s, got {v_cart}"
            )
    stop = _stop_mask(stop_at, n)
    via = _stop_mask(via_at, n) if via_at else None
    dev_in = _deviation(max_deviation, n)
    radius = None if via_radius is None else _deviation(via_radius, n, "via_radius")
    cap = MAX_OUTPUT_SAMPLES if max_samples is None else min(max_samples, MAX_OUTPUT_SAMPLES)
    torque = None
    if inertia is not None or limits.torque is not None:
        torque = TorqueModel(design, inertia, gravity, str(assembly_mode))  # type: ignore[arg-type]
    tau_max = limits.torque_array
    if torque is not None and tau_max is not None:
        excess = gravity_excess(torque, w[0], tau_max)
        if excess is not None:
            j, value = excess
            raise TimingInfeasibleError(
                f"gravity alone needs |tau{j + 1}| = {value:.6g} N m at the start, above "
                f"limits.torque[{j}] = {tau_max[j]:.6g} N m"
            )
    return TimingJob(
        design,
        w,
        limits,
        str(method),
        str(assembly_mode),
        rate,
        v_cart,
        dev_in,
        stop,
        check_states,
        resolution,
        deadline,
        cap,
        torque,
        via,
        radius,
        None if grid_refine is None else _positive("grid_refine", grid_refine),
    )
