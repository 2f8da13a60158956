"""The simulated robot (planner.simulation) against independent oracles: closed-form
polynomials for the reference, the product's forward kinematics for MuJoCo's P, the
controllers' known behaviour (a perfect model with computed torque tracks to the engine's
accuracy; a PD alone lags and sags under gravity), the saturation bound at every step."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest
from simulation_factories import Q0, Q1, move_reference, quintic_move, there_and_back

from planner import Design, forward_batch
from planner.dynamics import Inertia, inverse_dynamics
from planner.exceptions import InputError
from planner.simulation import Controller, Reference, find_stops, simulate

DESIGN = Design.default()
#: distal links too short to assemble at the test motions' postures
SHORT = dataclasses.replace(DESIGN, L2=0.3)


def test_the_reference_reproduces_a_quintic_between_its_samples() -> None:
    """Samples of one quintic per joint (q, qd, qdd in closed form) at uneven times: the
    reference between them is that quintic (1e-9), held at rest after the end."""
    rng = np.random.default_rng(3)
    c = rng.normal(size=(6, 3))

    def poly(t: np.ndarray, d: int) -> np.ndarray:
        return sum(
            np.outer(np.prod(np.arange(i - d + 1, i + 1)) * t ** (i - d), c[i]) for i in range(d, 6)
        )

    t = np.cumsum(rng.uniform(0.05, 0.2, 8))
    ref = Reference(t, poly(t, 0), poly(t, 1), poly(t, 2))
    x = np.linspace(t[0], t[-1], 97)
    q, qd, qdd = ref.at(x)
    for got, d in ((q, 0), (qd, 1), (qdd, 2)):
        np.testing.assert_allclose(got, poly(x, d), rtol=1e-9, atol=1e-9)
    q, qd, _ = ref.at(np.array([t[-1] + 1.0]))
    np.testing.assert_allclose(q[0], poly(t[-1:], 0)[0])
    assert np.all(qd == 0)


def test_stops_are_the_rests_of_the_reference() -> None:
    ref = there_and_back(dwell=0.1)
    stops = find_stops(ref)
    assert len(stops) == 2 and stops[-1].final and not stops[0].final
    assert stops[0].arrive == pytest.approx(0.3) and stops[0].leave == pytest.approx(0.4)


def test_computed_torque_with_a_perfect_model_tracks_and_pd_lags() -> None:
    """The same motion: computed torque follows P to < 1 um (the engine's and the loop's
    softness, measured ~0.3 um) and settles at once; PD alone is > 100x worse (it fights
    gravity and inertia with its error) and sags under gravity at the end."""
    ref = move_reference()
    ct = simulate(DESIGN, ref, hold_s=0.1)
    pd = simulate(DESIGN, ref, controller=Controller("pd"), hold_s=0.1)
    assert ct.tracking.p_max_mm < 1e-3
    assert ct.assembly_kept and ct.settle_times == (0.0,)
    assert ct.realised_duration == pytest.approx(ct.planned_duration)
    assert pd.tracking.p_max_mm > 100 * ct.tracking.p_max_mm
    assert pd.tracking.p_max_mm > 1.0
    assert pd.settle_times == (None,) and pd.realised_duration is None
    assert ct.engine == f"mujoco {mujoco.__version__}"
    # the recorded samples: the motion at 1 kHz, then the hold until settled (50 samples)
    assert ct.t[0] == 0.0 and np.allclose(np.diff(ct.t), 1e-3)
    assert 0.3 + 0.049 - 1e-9 <= ct.t[-1] <= 0.3 + 0.1 + 1e-9


def test_realised_p_is_the_products_forward_kinematics_of_the_realised_q() -> None:
    """MuJoCo's P (the closed loop's tips) against the product's forward kinematics of the
    realised actuated joints in the reference's assembly mode, at every sample, to 2e-8 m
    (the loop's constraint is soft: under load its tips part by a few nm, measured 4e-9 m);
    with the assembly mode '-' too (the loop closed where the product puts it)."""
    for mode, q0, q1 in (
        ("+", Q0, Q1),
        ("-", np.array([0.2, 2.4, 0.5]), np.array([0.0, 2.6, 0.7])),
    ):
        assert forward_batch(DESIGN, np.stack([q0, q1]), mode).ok.all()
        sim = simulate(
            DESIGN, move_reference(q0=q0, q1=q1, duration=0.2), hold_s=0.0, assembly_mode=mode
        )
        p = forward_batch(DESIGN, sim.q, mode).p
        np.testing.assert_allclose(sim.p, p, atol=2e-8)
        assert sim.assembly_kept and sim.tracking.p_max_mm < 1e-2


def test_a_static_posture_under_gravity_is_held_still() -> None:
    """A one-sample reference held for 0.2 s with gravity off-axis: computed torque holds it
    to 1e-7 rad, its torque the product's gravity torque; with zero gains and no
    feed-forward (pd, kp = kd = 0) the arm falls, so the check can fail."""
    g = (0.7, -2.0, -9.81)
    ref = Reference(np.array([0.0]), Q0[None], np.zeros((1, 3)), np.zeros((1, 3)))
    sim = simulate(DESIGN, ref, gravity=g, hold_s=0.2)
    assert np.max(np.abs(sim.q - Q0)) < 1e-7
    assert np.max(np.abs(sim.qd)) < 1e-5
    tau_g = inverse_dynamics(
        DESIGN, Inertia.default(DESIGN), Q0, np.zeros(3), np.zeros(3), gravity=g
    ).tau[0]
    np.testing.assert_allclose(sim.tau, np.tile(tau_g, (sim.t.size, 1)), atol=1e-4)
    limp = simulate(
        DESIGN, ref, gravity=g, hold_s=0.2, controller=Controller("pd", kp=(0, 0, 0), kd=(0, 0, 0))
    )
    assert np.max(np.abs(limp.q - Q0)) > 1e-2


def test_saturation_is_honoured_at_every_step() -> None:
    """Torque limits below what the motion needs: every applied torque within its limit,
    saturation counted, and the tracking error grows accordingly."""
    ref = move_reference()
    free = simulate(DESIGN, ref, hold_s=0.05)
    need = np.max(np.abs(free.tau), axis=0)
    limits = tuple(0.6 * need)
    sim = simulate(DESIGN, ref, torque_limits=limits, hold_s=0.05)
    assert np.all(np.abs(sim.tau) <= np.asarray(limits) + 1e-12)
    assert sim.saturated > 0 and free.saturated == 0
    assert sim.tracking.p_max_mm > 100 * free.tracking.p_max_mm


def test_settle_times_at_each_stop() -> None:
    """A move, a 0.1 s dwell, a move back: computed torque is settled at both stops at once;
    PD with stiff gains settles during the dwell (a settle time inside it) or not at all,
    never before the arrival."""
    ref = there_and_back()
    ct = simulate(DESIGN, ref, hold_s=0.2)
    assert ct.settle_times == (0.0, 0.0)
    pd = simulate(DESIGN, ref, hold_s=0.2, settle_tolerance_mm=5.0, controller=Controller("pd"))
    for s in pd.settle_times:
        assert s is None or s >= 0.0
    assert pd.tracking.p_max_mm > 5.0 and pd.settle_times[0] != 0.0


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: Controller("lqr"), "kind"),
        (lambda: Controller("pd", kp=(1, -1, 1)), "kp"),
        (lambda: simulate(DESIGN, move_reference(), rate_hz=5.0), "rate_hz"),
        (lambda: simulate(DESIGN, move_reference(), torque_limits=(1, 0, 1)), "torque"),
        (lambda: simulate(DESIGN, move_reference(), hold_s=-1.0), "hold_s"),
        (lambda: simulate(DESIGN, move_reference(duration=30.0, rate_hz=10), rate_hz=10_000),
         "rate_hz"),
        (lambda: simulate(SHORT, move_reference()), "q"),  # does not assemble there
        (lambda: Reference([0.0, 0.0], np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 3))), "t"),
        (lambda: Reference([0.0, 1.0], np.zeros((2, 3)), np.zeros((1, 3)), np.zeros((2, 3))), "qd"),
    ],
)  # fmt: skip
def test_bad_input_names_its_field(call, field) -> None:
    with pytest.raises(InputError) as info:
        call()
    assert info.value.field_path[0] == field, info.value


def test_a_trajectory_on_another_clock_runs_the_same() -> None:
    """A trajectory whose clock starts at 5 s (a replacement's starts at its ``at``): the
    same run, its instants and stops shifted, its durations and measures unchanged."""
    t, q, qd, qdd = quintic_move(duration=0.1)
    zero = simulate(DESIGN, Reference(t, q, qd, qdd), hold_s=0.06)
    late = simulate(DESIGN, Reference(t + 5.0, q, qd, qdd), hold_s=0.06)
    np.testing.assert_allclose(late.t, zero.t + 5.0, atol=1e-12)
    np.testing.assert_allclose(late.q, zero.q, atol=1e-12)
    assert late.stops[-1].arrive == pytest.approx(5.1)
    assert late.planned_duration == pytest.approx(zero.planned_duration)
    assert late.realised_duration == pytest.approx(zero.realised_duration)
