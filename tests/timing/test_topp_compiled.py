"""The compiled TOPP-RA passes (planner.timing.topp_compiled) against toppra itself (a peer
library solving the same discretised problem with its seidel LP solver): the same path
velocities on random blended paths, with and without a bound on the speed of P, and the
same refusal of a section that no profile can follow."""

from __future__ import annotations

import numpy as np
import pytest

import planner.timing.toppra_method as tm
from planner import Design
from planner.timing.limits import JointLimits
from planner.timing.path import BlendedPath
from planner.timing.topp_compiled import topp_profile
from planner.timing.trajectory import p_velocity

DESIGN = Design.default()
LIMITS = JointLimits.default()


def _gain(path: BlendedPath):
    def gain(s: np.ndarray) -> np.ndarray:
        q, d1, _ = path.evaluate_all(s)
        _, v, ok = p_velocity(DESIGN, q, d1, "+")
        return np.where(ok, np.linalg.norm(v, axis=1), np.inf)

    return gain


@pytest.mark.parametrize("seed", range(4))
def test_compiled_profile_equals_toppra(seed, monkeypatch):
    rng = np.random.default_rng(seed)
    for _ in range(10):
        n = int(rng.integers(2, 25))
        step = float(rng.choice([0.02, 0.1, 0.4]))
        w = np.array([0.0, 2.0, 1.0]) + np.cumsum(rng.normal(size=(n, 3)) * step, axis=0)
        dev = float(rng.choice([0.0, 0.001, 0.01, 0.05]))
        path = BlendedPath.from_waypoints(w, dev, None, tm.min_blend_radius(LIMITS))
        v_cart = rng.choice([None, 0.25, 1.0])
        kw = {
            "speed_gain": _gain(path) if v_cart else None,
            "max_cartesian_speed": v_cart,
            "refine": float(rng.choice([1.0, 4.0])),
        }
        compiled = tm.solve_toppra(path, LIMITS, **kw)
        with monkeypatch.context() as m:
            m.setattr(tm, "_compiled_profile", lambda *a, **k: None)  # toppra's own solve
            reference = tm.solve_toppra(path, LIMITS, **kw)
        np.testing.assert_array_equal(compiled.s, reference.s)
        np.testing.assert_allclose(compiled.sd, reference.sd, rtol=1e-9, atol=1e-12)
        assert compiled.duration == pytest.approx(reference.duration, rel=1e-9)


def test_a_straight_rest_to_rest_is_the_trapezoid():
    """One straight piece under one acceleration and velocity bound: the profile's grid
    values lie on the closed-form trapezoid sd = min(sqrt(2 a s), v, sqrt(2 a (L - s)))
    (toppra's forward margin TINY aside)."""
    s = np.linspace(0.0, 2.0, 201)
    d1 = np.tile([1.0, 0.0, 0.0], (s.shape[0], 1))
    sd, code = topp_profile(
        s, d1, np.zeros_like(d1), np.array([2.0, 1.0, 1.0]), np.full(201, 1.5**2)
    )
    assert code == 0 and sd is not None
    exact = np.minimum(np.minimum(np.sqrt(4.0 * s), 1.5), np.sqrt(4.0 * (2.0 - s)))
    np.testing.assert_allclose(sd, exact, atol=1e-4)


def test_an_uncontrollable_section_is_refused():
    """An end velocity the acceleration bound cannot reach from rest: x = sd^2 grows by at
    most 2 a L = 0.2 over the section, so an end at sd = 5 (x = 25) is not controllable from
    the start at rest (toppra: FailUncontrollable)."""
    s = np.linspace(0.0, 0.1, 11)
    d1 = np.tile([1.0, 0.0, 0.0], (s.shape[0], 1))
    sd, code = topp_profile(
        s, d1, np.zeros_like(d1), np.array([1.0, 1.0, 1.0]), np.full(11, 100.0), sd_end=5.0
    )
    assert sd is None and code in (1, 2)
