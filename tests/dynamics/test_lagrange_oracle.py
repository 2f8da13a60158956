"""The optimal-control yardstick of ``benchmarks/cycle_optimum.py`` checked against the
product, and the product's inverse dynamics against a second derivation.

``benchmarks/_closed_chain_ocp.py`` derives the closed chain's torques by Lagrange's equations
(CasADi's symbolic derivatives of the bodies' energies, passive angles by circle
intersection, angular velocities from rotation matrices); the product projects Newton-Euler
wrenches by hand-written velocity Jacobians. They share no code, so agreement to rounding
checks both; and the optimum it solves must be no slower than the product's own timing of
one path (the optimum may choose any path) while its torques hold between the nodes.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from _closed_chain_ocp import dense_samples, lagrangian_model, minimum_time

from planner import Design
from planner.dynamics import Inertia, inverse_dynamics
from planner.kinematics import forward_batch
from planner.timing import JointLimits, time_path
from planner.validity import Margins

GRAVITY = (0.4, -1.1, -9.81)  # off the axes, so that every component is exercised


@pytest.mark.parametrize("assembly_mode", ["+", "-"])
@pytest.mark.parametrize(
    "design", [Design.default(), Design.paper_optimum(), Design(0.3, 0.3, 0.5)]
)
def test_lagrange_equals_the_product_inverse_dynamics(design: Design, assembly_mode: str) -> None:
    """At 100 random states (postures that assemble away from the parallel singularity, any
    rates), with a payload and every inertia term nonzero, the two derivations agree to
    1e-9 relative to the largest torque."""
    rng = np.random.default_rng(5)
    base = Inertia.default(design)
    inertia = Inertia(base.proximal, base.distal, 1.3, 0.02, (1e-3, 2e-3, 3e-3))
    model = lagrangian_model(design, inertia, GRAVITY, assembly_mode)
    q = rng.uniform(-1.2, 1.2, (400, 3)) + np.array([0.0, 1.0, 2.0])
    ok = inverse_dynamics(design, inertia, q, q * 0, q * 0, assembly_mode=assembly_mode).ok
    q = q[ok][:100]
    assert len(q) == 100
    qd, qdd = rng.normal(size=q.shape) * 2, rng.normal(size=q.shape) * 20
    tau = inverse_dynamics(
        design, inertia, q, qd, qdd, assembly_mode=assembly_mode, gravity=GRAVITY
    ).tau
    lag = np.array([np.asarray(model.tau(*s)).ravel() for s in zip(q, qd, qdd, strict=True)])
    assert np.max(np.abs(lag - tau)) <= 1e-9 * np.max(np.abs(tau))
    point = np.array([np.asarray(model.point(x)).ravel() for x in q])
    assert np.allclose(point, forward_batch(design, q, assembly_mode).p, atol=1e-12)


def test_the_optimum_is_no_slower_than_the_product_and_its_torques_hold() -> None:
    """One rest-to-rest move of the default design under torque limits that bind: the
    optimum (any path through the same end points, same limits and margins) takes at most
    the product's time on the straight joint-space line, and between its nodes the
    product's inverse dynamics finds the torques within 3 % of the limits (only the nodes
    are constrained)."""
    design = Design.default()
    inertia = Inertia.default(design)
    q0, q1 = np.array([0.9, -0.1, 1.25]), np.array([0.2, 0.2, 1.0])
    velocity, acceleration, torque = (12.0,) * 3, (400.0,) * 3, (14.0, 6.0, 6.0)
    limits = JointLimits(velocity, acceleration, torque=torque)
    product = time_path(design, np.array([q0, q1]), limits, inertia=inertia)
    signs = forward_batch(design, q0[None, :], "+").working_mode_signs[0]
    mode = "".join("+" if x > 0 else "-" for x in signs)
    margins = Margins()
    model = lagrangian_model(design, inertia, (0.0, 0.0, -9.81), "+")
    best = minimum_time(
        model,
        np.array([q0, q1]),
        [True, True],
        [mode],
        velocity=np.array(velocity),
        acceleration=np.array(acceleration),
        torque=np.array(torque),
        joint_limits=design.joint_limits,
        kappa_max=margins.kappa_max,
        serial_min=margins.serial_min,
        guess_durations=np.array([product.duration]),
        nodes=12,
    )
    assert best.solved, best.status
    assert best.total <= product.duration * (1 + 1e-6)
    assert best.total >= 0.5 * product.duration  # the same physics: not an absurd optimum
    _, q, qd, qdd = dense_samples(best)
    tau = inverse_dynamics(design, inertia, q, qd, qdd).tau
    assert np.max(np.abs(tau) / torque) <= 1.03
    assert np.max(np.abs(tau) / torque) >= 0.97  # the torques bind: a minimum time
