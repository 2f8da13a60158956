"""How close the timings come to their optimum (issue 36): velocity-only TOPPRA against its
own finer-grid optimum, and torque-limited timing (both methods) against the usual practice,
the velocity-only trajectory slowed uniformly until its torques hold.

Oracles: the finer grid is the same solver on a grid 4x finer (``TOPPRA_REFINE`` and ``TOPPRA_ARC_REFINE``) (the profile
converges as the grid shrinks); the uniform slow-down is computed here from the inverse
dynamics alone (``tau`` of the motion less ``tau`` at rest, and the closed form of the
largest c with ``|c^2 dyn + gravity| <= limit``), on 4001 samples of the velocity-only
trajectory."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import planner.timing.parameterize as parameterize
from planner import Design
from planner.dynamics import Inertia, inverse_dynamics
from planner.timing import JointLimits, time_path


def _random_path(rng: np.random.Generator) -> np.ndarray:
    q0 = np.array([0.0, 2.0, 1.0])
    return np.vstack([q0, q0 + np.cumsum(rng.uniform(-0.5, 0.5, (3, 3)), axis=0)])


def _random_limits(rng: np.random.Generator, **extra) -> JointLimits:
    return JointLimits(
        velocity=tuple(rng.uniform(1.5, 3.0, 3)),
        acceleration=tuple(rng.uniform(5.0, 15.0, 3)),
        jerk=(400.0,) * 3,
        **extra,
    )


def test_velocity_only_toppra_is_within_half_a_percent_of_a_finer_grid(monkeypatch):
    rng = np.random.default_rng(36)
    design = Design.default()
    for _ in range(5):
        w, limits = _random_path(rng), _random_limits(rng)
        coarse = time_path(design, w, limits, method="toppra", max_deviation=0.05).duration
        monkeypatch.setattr(parameterize, "TOPPRA_REFINE", 4 * parameterize.TOPPRA_REFINE)
        monkeypatch.setattr(parameterize, "TOPPRA_ARC_REFINE", 4 * parameterize.TOPPRA_ARC_REFINE)
        fine = time_path(design, w, limits, method="toppra", max_deviation=0.05).duration
        monkeypatch.undo()
        assert coarse <= fine * 1.005, (coarse, fine)


def _uniform_slow_down(design, inertia, traj, torque: np.ndarray) -> float:
    """The duration of ``traj`` slowed uniformly just enough that |tau| <= torque at 4001
    samples (closed form per sample and joint), s."""
    t = np.linspace(0.0, traj.duration, 4001)
    q, qd, qdd, _ = traj.at(t)
    total = inverse_dynamics(design, inertia, q, qd, qdd).tau
    rest = inverse_dynamics(design, inertia, q, 0 * qd, 0 * qdd).tau
    dyn = total - rest
    assert np.all(np.abs(rest) <= torque)
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(
            dyn > 0, (torque - rest) / dyn, np.where(dyn < 0, (torque + rest) / -dyn, np.inf)
        )
    c = min(1.0, float(np.sqrt(np.min(room))))
    return traj.duration / c


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_torque_limited_timing_is_never_slower_than_a_uniform_slow_down(method):
    """Random paths, designs and torque limits (30-90 % of the velocity-only trajectory's
    peak torque per joint, above gravity's): the torque-limited timing is at most 0.2 %
    (the fit's margin inside the limits, and the check's grid) slower than the velocity-only
    trajectory slowed uniformly until its torques hold, and its torques hold."""
    rng = np.random.default_rng(3605 if method == "toppra" else 3606)
    for _ in range(5):
        design = Design(*rng.uniform([0.2, 0.2, 0.45], [0.3, 0.3, 0.65]), link_radius=0.01)
        inertia = Inertia.default(design)
        w, limits = _random_path(rng), _random_limits(rng)
        free = time_path(design, w, limits, method=method, max_deviation=0.05)
        t = np.linspace(0.0, free.duration, 2001)
        q, qd, qdd, _ = free.at(t)
        tau = inverse_dynamics(design, inertia, q, qd, qdd).tau
        rest = inverse_dynamics(design, inertia, q, 0 * qd, 0 * qdd).tau
        peak, hold = np.max(np.abs(tau), axis=0), np.max(np.abs(rest), axis=0)
        torque = np.maximum(rng.uniform(0.3, 0.9, 3) * peak, 1.05 * hold + 1e-3)
        with_torque = replace(limits, torque=tuple(float(x) for x in torque))
        limited = time_path(design, w, with_torque, method=method, max_deviation=0.05)
        floor = _uniform_slow_down(design, inertia, free, torque)
        assert limited.duration <= floor * 1.002, (limited.duration, floor)
        assert limited.max_torque_ratio is not None and limited.max_torque_ratio <= 1.0 + 1e-6
