"""Via chains under ``limits.torque`` re-timed along their own path by toppra with the torque
constraint (issue 39, ``planner.timing.via_retime``), against the uniform slow-down they had.

Oracles: the same call with the re-timing switched off (the uniform slow-down of the
chain: the re-timed chain must be quicker where a torque binds, and never slower), the
torques of the trajectory recomputed on a fine time grid of our own by the inverse dynamics
(``planner.dynamics.inverse_dynamics``, not the timing's torque model), the velocity and
acceleration limits on that grid, finite differences of q against qd, and the exact pass
through the via (its closest approach on the grid, within one grid step of travel)."""

from __future__ import annotations

import numpy as np
import pytest

import planner.timing.parameterize as parameterize
from planner import Design
from planner.dynamics import DEFAULT_GRAVITY, Inertia, inverse_dynamics
from planner.timing import JointLimits, time_path

DESIGN = Design.default()
LIMITS = JointLimits((12.0,) * 3, (400.0,) * 3, torque=(24.0, 12.0, 12.0))
#: A corner passed exactly (a via of radius 0: only a chain of moves passes it).
W = np.array([[0.0, 0.5, 1.0], [0.0, 0.8, 1.0], [0.3, 0.8, 1.3]])


def inertia() -> Inertia:
    base = Inertia.default(DESIGN)
    return Inertia(base.proximal, base.distal, 1.0, base.base_inertia, base.rotor)


def timed(**kwargs):
    return time_path(DESIGN, W, LIMITS, inertia=inertia(), via_at=[1], via_radius=0.0, **kwargs)


def test_the_retimed_chain_is_quicker_and_holds_every_limit(monkeypatch):
    traj = timed()
    monkeypatch.setattr(parameterize, "quicker_retimed", lambda chain, uniform, *a: uniform)
    uniform = timed()
    # measured 0.2765 s against 0.4171 s: the torques bind on part of the chain only
    assert traj.duration <= 0.8 * uniform.duration
    t = np.linspace(0.0, traj.duration, 40_001)
    q, qd, qdd, _ = traj.at(t)
    tau = inverse_dynamics(
        DESIGN, inertia(), q, qd, qdd, assembly_mode="+", gravity=DEFAULT_GRAVITY
    ).tau
    assert np.all(np.max(np.abs(tau), axis=0) <= np.asarray(LIMITS.torque) * (1 + 1e-3))
    assert np.all(np.max(np.abs(qd), axis=0) <= np.asarray(LIMITS.velocity) * (1 + 1e-6))
    assert np.all(np.max(np.abs(qdd), axis=0) <= np.asarray(LIMITS.acceleration) * (1 + 1e-6))
    dt = t[1] - t[0]
    np.testing.assert_allclose((q[2:] - q[:-2]) / (2 * dt), qd[1:-1], atol=1e-3)
    gap = np.linalg.norm(q - W[1], axis=1)
    i = int(np.argmin(gap))
    assert gap[i] <= np.linalg.norm(qd[i]) * dt + 1e-9  # through the vertex itself
    assert np.linalg.norm(qd[i]) > 0.1  # at speed
    assert traj.max_torque_ratio is not None and traj.max_torque_ratio <= 1.0 + 1e-6


def test_without_torque_limits_nothing_changes(monkeypatch):
    free = JointLimits(LIMITS.velocity, LIMITS.acceleration)
    a = time_path(DESIGN, W, free, via_at=[1], via_radius=0.0)
    monkeypatch.setattr(parameterize, "quicker_retimed", lambda chain, uniform, *a: uniform)
    b = time_path(DESIGN, W, free, via_at=[1], via_radius=0.0)
    assert a.duration == pytest.approx(b.duration, rel=1e-12)
