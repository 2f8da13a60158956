"""Dynamic identification: the regressor against the product's inverse dynamics, the base
parameters against their closed-form grouping, and bad input."""

from __future__ import annotations

import numpy as np
import pytest

from planner import Design
from planner.dynamics import Inertia, LinkInertia, inverse_dynamics
from planner.dynamics.identify import (
    STANDARD_NAMES,
    identify_inertia,
    regressor,
    standard_parameters,
)
from planner.exceptions import InputError

DESIGN = Design.default()
GRAVITY = (0.7, -2.0, -9.81)
TRUE = Inertia(
    proximal=LinkInertia(0.7, 0.3, 0.004, 0.0075),
    distal=LinkInertia(1.1, 0.65, 0.02, 0.001),
    payload_mass=0.8,
    base_inertia=0.03,
    rotor=(0.002, 0.001, 0.003),
)


def _motions(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """n random states near the default posture (all assemble, far from singular)."""
    rng = np.random.default_rng(seed)
    q = np.array([0.0, 2.0, 1.0]) + rng.uniform(-0.6, 0.6, size=(n, 3))
    q[:, 0] = rng.uniform(-3.0, 3.0, size=n)
    return q, rng.normal(0, 2.0, size=(n, 3)), rng.normal(0, 10.0, size=(n, 3))


def test_regressor_times_parameters_is_the_inverse_dynamics() -> None:
    q, qd, qdd = _motions(200, 1)
    y, ok = regressor(DESIGN, q, qd, qdd, gravity=GRAVITY)
    assert ok.all()
    for inertia in (TRUE, Inertia.default(DESIGN)):
        tau = inverse_dynamics(DESIGN, inertia, q, qd, qdd, gravity=GRAVITY).tau
        np.testing.assert_allclose(
            y @ standard_parameters(DESIGN, inertia), tau, atol=1e-10 * np.abs(tau).max()
        )


def _grouped(design: Design, inertia: Inertia, prior: Inertia) -> dict[str, float]:
    """The base parameters in closed form (docs/calibration.md), with the held ones (masses
    of the proximal and distal links, payload, rotor[0], rotor[2]) at ``prior``: the payload
    is half a point mass at each distal tip, the distal mass a point mass at C on each
    proximal link, rotor[0] adds to the base inertia; and a proximal link's kinetic energy
    about its pivot, ``(J (qd_j^2 + qd1^2) + (I_axial - J) qd1^2 cos^2 theta_j) / 2``, makes
    the column of J that of rotor[1] + rotor[2] + 2 base - I_axial, so rotor[2]'s departure
    d3 moves to J (+d3), rotor[1] (-d3), base (-2 d3) and I_axial (+d3)."""
    phi, phi0 = standard_parameters(design, inertia), standard_parameters(design, prior)
    p = dict(zip(STANDARD_NAMES, phi - phi0, strict=True))  # the departures from the prior
    l1, l2 = design.L1, design.L2
    d = dict(zip(STANDARD_NAMES, phi, strict=True))
    m2 = p["distal.mass"] + p["payload.mass"] / 2
    d3 = p["rotor[2]"]
    return {
        "base.inertia": d["base.inertia"] + p["rotor[0]"] - 2 * d3,
        "proximal.first_moment": d["proximal.first_moment"] + m2 * l1,
        "proximal.I_pivot": d["proximal.I_pivot"] + m2 * l1**2 + d3,
        "proximal.I_axial": d["proximal.I_axial"] + d3,
        "distal.first_moment": d["distal.first_moment"] + p["payload.mass"] / 2 * l2,
        "distal.I_pivot": d["distal.I_pivot"] + p["payload.mass"] / 2 * l2**2,
        "distal.I_axial": d["distal.I_axial"],
        "rotor[1]": d["rotor[1]"] - d3,
    }


def test_base_parameters_from_exact_inverse_dynamics() -> None:
    """Data: the product's inverse_dynamics of TRUE at 300 random states (exact, no noise)."""
    q, qd, qdd = _motions(300, 2)
    tau = inverse_dynamics(DESIGN, TRUE, q, qd, qdd, gravity=GRAVITY).tau
    prior = Inertia.default(DESIGN)
    result = identify_inertia(DESIGN, q, qd, qdd, tau, gravity=GRAVITY, prior=prior)
    assert sorted(result.unidentified) == sorted(
        ["distal.mass", "payload.mass", "rotor[0]", "rotor[2]", "proximal.mass"]
    )
    expected = _grouped(DESIGN, TRUE, prior)
    assert set(result.base_parameters) == set(expected)
    for name, value in expected.items():
        assert result.base_parameters[name] == pytest.approx(value, abs=1e-6), name
    assert result.residual_rms < 1e-9 * np.abs(tau).max()
    assert result.notes == []
    # the identified inertia is a design.inertia: same torques, anywhere
    q2, qd2, qdd2 = _motions(50, 3)
    np.testing.assert_allclose(
        inverse_dynamics(DESIGN, result.inertia, q2, qd2, qdd2, gravity=GRAVITY).tau,
        inverse_dynamics(DESIGN, TRUE, q2, qd2, qdd2, gravity=GRAVITY).tau,
        atol=1e-8,
    )


def test_friction() -> None:
    q, qd, qdd = _motions(300, 4)
    viscous, coulomb = np.array([0.1, 0.05, 0.2]), np.array([0.3, 0.2, 0.1])
    tau = inverse_dynamics(DESIGN, TRUE, q, qd, qdd, gravity=GRAVITY).tau
    tau = tau + viscous * qd + coulomb * np.sign(qd)
    result = identify_inertia(DESIGN, q, qd, qdd, tau, gravity=GRAVITY, friction=True)
    assert result.friction is not None
    np.testing.assert_allclose(result.friction[0], viscous, atol=1e-9)
    np.testing.assert_allclose(result.friction[1], coulomb, atol=1e-9)


def test_rest_only_names_what_it_cannot_see() -> None:
    """At rest only gravity acts: the inertias are unidentified, named, held; no 500."""
    q, _, _ = _motions(100, 5)
    zero = np.zeros_like(q)
    tau = inverse_dynamics(DESIGN, TRUE, q, zero, zero, gravity=GRAVITY).tau
    result = identify_inertia(DESIGN, q, zero, zero, tau, gravity=GRAVITY)
    for name in ("proximal.I_axial", "distal.I_axial", "rotor[1]", "base.inertia"):
        assert name in result.unidentified
    assert np.isfinite(result.condition_number)
    assert result.residual_rms < 1e-9


def test_bad_input_is_named() -> None:
    q, qd, qdd = _motions(10, 6)
    tau = np.zeros((10, 3))
    with pytest.raises(InputError) as err:
        identify_inertia(DESIGN, q[:2], qd[:2], qdd[:2], tau[:2])
    assert err.value.field_path == ("tau",)
    bad = q.copy()
    bad[4] = [0.0, 1.0, 1.0]  # the paper's optimum (L0 = 0, L1 = L2): C = D, singular
    with pytest.raises(InputError) as err:
        identify_inertia(Design.paper_optimum(), bad, qd, qdd, tau)
    assert err.value.field_path == ("q", 4)
    tau_nan = tau.copy()
    tau_nan[3, 1] = np.nan
    with pytest.raises(InputError) as err:
        identify_inertia(DESIGN, q, qd, qdd, tau_nan)
    assert err.value.field_path == ("tau",)
