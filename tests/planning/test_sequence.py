"""Task sequences (:func:`planner.solve_sequence`): one trajectory through many targets.

Oracles independent of the sequence code: the trajectory's curve evaluated on a fine grid of
our own (rest at the stops, speed at the pass-throughs, closest approach within the blend),
the kinematics (P of the arrival posture), a validity checker built here for each sample's
own working mode, the velocity limits, and, for the mode choice, brute force over every
assignment (each planned and timed as a "fixed" sequence)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from planner import Design, SequenceTarget, solve_sequence
from planner.exceptions import InputError
from planner.geometry import Sphere
from planner.kinematics import WORKING_MODES, forward_batch, mode_label
from planner.planning import CartesianTarget, JointPosture, PlanStatus
from planner.sequence import MAX_SEQUENCE_TARGETS
from planner.sequence.mode_search import leg_lower_bound
from planner.timing import JointLimits, time_path
from planner.validity import Margins, ValidityChecker

DESIGN = Design.default()
START = JointPosture([0.0, 2.0, 1.0])
BASE = np.array([0.35, -0.1, -0.45])
LIMITS = JointLimits.default()


def at(dx: float, dy: float, dz: float) -> np.ndarray:
    """A point offset from BASE, m."""
    return BASE + np.array([dx, dy, dz])


def pick_place(stop_corners: bool, blend: float = 0.0) -> list[SequenceTarget]:
    """Up, across, down (a small pick-and-place cycle from BASE)."""
    return [
        SequenceTarget(CartesianTarget(at(0, 0, 0.05)), stop=stop_corners, blend=blend),
        SequenceTarget(CartesianTarget(at(0, 0.3, 0.05)), stop=stop_corners, blend=blend),
        SequenceTarget(CartesianTarget(at(0, 0.3, 0.0))),
    ]


def valid_everywhere(design, q, obstacles, margins) -> np.ndarray:
    """Each posture valid by the checker of its own working mode (built here)."""
    fb = forward_batch(design, q, "+")
    ok = fb.ok.copy()
    labels = [mode_label(s) if o else "" for s, o in zip(fb.working_mode_signs, fb.ok, strict=True)]
    for mode in set(labels) - {""}:
        sel = np.array([lab == mode for lab in labels])
        chk = ValidityChecker(design, margins, obstacles, "+", mode)
        ok[sel] = chk.is_valid(q[sel])
    return ok


@pytest.fixture(scope="module")
def solved():
    obstacles = [Sphere(center=(0.35, 0.1, -0.7), radius=0.1)]
    out = {}
    for name, targets in (
        ("stops", pick_place(True)),
        ("blend", pick_place(False, 0.05)),
        ("exact", pick_place(False)),
    ):
        out[name] = solve_sequence(
            DESIGN, START, targets, cycle=True, objective="fixed", obstacles=obstacles
        )
    return out, obstacles


@pytest.mark.parametrize("name", ["stops", "blend", "exact"])
def test_one_trajectory_through_every_target(solved, name):
    results, obstacles = solved
    r = results[name]
    assert r.solved, r.message
    traj = r.trajectory
    assert np.all(np.diff(traj.t) > 0)  # strictly increasing, no stamp repeated between legs
    assert traj.t[0] == 0.0 and traj.t[-1] == pytest.approx(r.cycle_time)
    assert len(r.legs) == 4 and [leg.target_index for leg in r.legs] == [0, 1, 2, 3]
    for a, b in itertools.pairwise(r.legs):
        assert b.start_time == a.end_time and a.end_time < b.end_time
    assert r.legs[0].start_time == 0.0 and r.legs[-1].end_time == pytest.approx(r.cycle_time)
    t = np.linspace(0.0, r.cycle_time, 20001)
    q, qd = traj.curve.evaluate(t)[:2]
    assert np.all(np.abs(qd) <= LIMITS.velocity_array * (1 + 1e-6))
    assert np.all(valid_everywhere(DESIGN, q, obstacles, Margins()))
    targets = pick_place(name == "stops", 0.05 if name == "blend" else 0.0)
    for i, leg in enumerate(r.legs[:3]):
        p = np.asarray(targets[i].goal.p)
        q_arr = np.asarray(leg.plan.path.waypoints[-1])
        np.testing.assert_allclose(forward_batch(DESIGN, q_arr[None], "+").p[0], p, atol=1e-9)
        qk, qdk = traj.curve.evaluate(np.array([leg.end_time]))[:2]
        stop = targets[i].stop or i == 2
        if stop:
            np.testing.assert_allclose(qk[0], q_arr, atol=1e-9)
            assert np.all(np.abs(qdk[0]) <= 1e-9)
        else:
            # passing through: moving there, and the closest approach within the blend
            assert np.linalg.norm(qdk[0]) > 0.05
            nearest = float(np.min(np.linalg.norm(q - q_arr, axis=1)))
            assert nearest <= targets[i].blend + 1e-3
            # and it does not come to rest anywhere near it
            window = np.abs(t - leg.end_time) < 0.05
            assert np.min(np.linalg.norm(qd[window], axis=1)) > 0.01


def test_passing_through_blended_corners_is_faster_than_stopping(solved):
    results, _ = solved
    assert results["blend"].cycle_time < results["stops"].cycle_time


def test_planning_only_gives_legs_without_times():
    from planner.timing import TimingOptions

    r = solve_sequence(
        DESIGN, START, pick_place(True), objective="fixed", timing=TimingOptions(method="none")
    )
    assert r.status is PlanStatus.SOLVED and r.trajectory is None
    assert all(math.isnan(leg.end_time) for leg in r.legs)
    assert math.isnan(r.cycle_time)


def test_bad_input_names_the_field_and_the_target():
    with pytest.raises(InputError) as e:
        solve_sequence(DESIGN, START, [])
    assert e.value.field_path == ("targets",)
    many = [SequenceTarget(JointPosture([0.0, 2.0, 1.0]))] * (MAX_SEQUENCE_TARGETS + 1)
    with pytest.raises(InputError, match=f"at most {MAX_SEQUENCE_TARGETS}"):
        solve_sequence(DESIGN, START, many)
    with pytest.raises(InputError) as e:
        SequenceTarget(CartesianTarget(BASE), blend=-0.1)
    assert e.value.field_path == ("blend",)
    for bad in (-0.01, math.inf, math.nan):
        with pytest.raises(InputError) as e:
            SequenceTarget(CartesianTarget(BASE), stop=False, blend_radius=bad)
        assert e.value.field_path == ("blend_radius",)
    with pytest.raises(InputError, match="not both") as e:
        SequenceTarget(CartesianTarget(BASE), stop=False, blend=0.01, blend_radius=0.01)
    assert e.value.field_path == ("blend_radius",)
    targets = pick_place(False, 0.05)
    with pytest.raises(InputError) as e:
        solve_sequence(DESIGN, START, targets, objective="fastest")
    assert e.value.field_path == ("objective",)


def test_an_unreachable_target_names_its_index():
    targets = pick_place(True)
    targets[1] = SequenceTarget(CartesianTarget([3.0, 0.0, 0.0]))
    for objective in ("fixed", "time"):
        r = solve_sequence(DESIGN, START, targets, objective=objective)
        assert r.status is PlanStatus.UNREACHABLE
        assert r.message.startswith("target 1:")
        assert len(r.legs) == 2 and r.legs[0].plan.solved


def test_an_invalid_start_is_the_first_legs_status():
    # a sphere around the start's P: the start breaks the clearance rule
    p_start = forward_batch(DESIGN, START.q[None], "+").p[0]
    obstacles = [Sphere(center=p_start, radius=0.02)]
    for objective in ("fixed", "time"):
        r = solve_sequence(
            DESIGN, START, pick_place(True), cycle=True, objective=objective, obstacles=obstacles
        )
        assert r.status is PlanStatus.INVALID_START
        assert r.message.startswith("target 0:")


def test_leg_lower_bound_is_the_time_optimal_single_joint_move():
    # one joint moving: the bound is exactly the trapezoid (toppra's straight rest-to-rest
    # profile is time-optimal, less its fit margin); three joints: never above the timed motion
    for d in (0.05, 0.5, 2.0):
        qa, qb = np.array([0.0, 2.0, 1.0]), np.array([d, 2.0, 1.0])
        timed = time_path(DESIGN, np.array([qa, qb]), LIMITS).duration
        bound = leg_lower_bound(qa, qb, LIMITS, stop_a=True, stop_b=True)
        # the timing keeps 1e-3 inside the limits (its fit margin): within 0.2 %, never above
        assert bound <= timed and bound == pytest.approx(timed, rel=2e-3)
    rng = np.random.default_rng(3)
    for _ in range(5):
        qa = np.array([0.0, 2.0, 1.0])
        w = qa + np.cumsum(rng.uniform(-0.3, 0.3, (4, 3)), axis=0)
        w = np.vstack([qa, w])
        timed = time_path(DESIGN, w, LIMITS).duration
        assert leg_lower_bound(w[0], w[-1], LIMITS, stop_a=True, stop_b=True) <= timed + 1e-9


def _brute_force(targets, cycle, design=DESIGN, start=START, **kwargs):
    """Every assignment of the eight working modes (both sides of the axis), each planned and
    timed as a "fixed" sequence: the cycle time of each (inf where it fails)."""
    out = {}
    for modes in itertools.product(WORKING_MODES, repeat=len(targets)):
        fixed = [
            SequenceTarget(CartesianTarget(t.goal.p, m), t.stop, t.blend)
            for t, m in zip(targets, modes, strict=True)
        ]
        r = solve_sequence(design, start, fixed, cycle=cycle, objective="fixed", **kwargs)
        out[modes] = r.cycle_time if r.solved else math.inf
    return out


@pytest.mark.parametrize("stop", [True, False])
def test_modes_chosen_for_time_are_the_brute_force_optimum(stop):
    targets = [
        SequenceTarget(CartesianTarget(at(0, 0, 0.05)), stop=stop, blend=0.03),
        SequenceTarget(CartesianTarget(at(0, 0.3, 0.0))),
    ]
    brute = _brute_force(targets, cycle=True)
    finite = sorted((v, k) for k, v in brute.items() if math.isfinite(v))
    assert len(finite) >= 2
    r = solve_sequence(DESIGN, START, targets, cycle=True, objective="time")
    assert r.solved, r.message
    assert r.cycle_time == pytest.approx(finite[0][0], rel=1e-9)
    assert r.diagnostics.modes[:2] == finite[0][1]
    assert r.diagnostics.extra["gap_s"] == 0.0
    # never slower than the best single mode for every target
    single = min(brute[(m, m)] for m in WORKING_MODES)
    assert r.cycle_time <= single + 1e-9
    # the runner-up named in the message is a real assignment's cycle time
    runner_modes, runner_time = r.diagnostics.runner_up
    assert runner_time == pytest.approx(brute[tuple(runner_modes[:2])], rel=1e-9)
    assert "runner-up" in r.message and "working modes chosen for time" in r.message
    # fewer assignments evaluated than brute force
    assert r.diagnostics.estimates < len(brute)


def test_the_mode_choice_for_time_crosses_the_axis_where_that_is_quicker():
    """Issue 36: the quickest cycle leaves the start's side of the axis AB (the second target
    in -+- from a start in ++-, through a transit with P on the axis). The search considers
    both sides: its answer is brute force's best over all 64 assignments, and its proven gap
    is 0."""
    design = Design(0.2631, 0.3318, 0.4083, link_radius=0.01)
    start = JointPosture([-1.5538, 0.7407, -2.9145], "-")
    kwargs = {
        "margins": Margins(kappa_max=10, serial_min=0.05, clearance=0.01),
        "limits": JointLimits(velocity=(2, 2, 2), acceleration=(10, 10, 10)),
    }
    targets = [
        SequenceTarget(CartesianTarget(np.array(p)))
        for p in ([0.0055, -0.2827, 0.3529], [0.0055, -0.5047, 0.3529])
    ]
    brute = _brute_force(targets, True, design, start, **kwargs)
    best_time, best_modes = min((v, k) for k, v in brute.items())
    assert best_modes[0][0] != best_modes[1][0]  # the best assignment crosses the axis
    r = solve_sequence(design, start, targets, cycle=True, objective="time", **kwargs)
    assert r.solved, r.message
    assert r.cycle_time == pytest.approx(best_time, rel=1e-9)
    assert r.diagnostics.modes[:2] == best_modes
    assert r.diagnostics.extra["gap_s"] == 0.0
    assert r.diagnostics.estimates < sum(math.isfinite(v) for v in brute.values())


def test_a_target_where_the_path_turns_back_is_a_stop():
    # out and back along one line: the middle target cannot be passed at speed
    out = SequenceTarget(JointPosture([0.3, 2.0, 1.0]), stop=False, blend=0.1)
    for method in ("toppra", "ruckig"):
        from planner.timing import TimingOptions

        r = solve_sequence(DESIGN, START, [out], cycle=True, timing=TimingOptions(method=method))
        assert r.solved, r.message
        assert r.diagnostics.stopped_targets == (0,)
        assert "turns back" in r.message
        qk, qdk = r.trajectory.curve.evaluate(np.array([r.legs[0].end_time]))[:2]
        np.testing.assert_allclose(qk[0], [0.3, 2.0, 1.0], atol=1e-9)
        assert np.all(np.abs(qdk[0]) <= 1e-9)


def test_a_sequence_that_does_not_move_has_a_zero_cycle():
    r = solve_sequence(DESIGN, START, [SequenceTarget(JointPosture(START.q))], cycle=True)
    assert r.solved and r.cycle_time == 0.0
    assert [(leg.start_time, leg.end_time) for leg in r.legs] == [(0.0, 0.0), (0.0, 0.0)]


def test_torque_limits_bound_the_sequence_and_lengthen_it():
    """With an inertial model the joined trajectory carries its torques; a torque limit below
    what the free cycle needs is met (recomputed here by the inverse dynamics at the samples)
    and makes the cycle longer. No gravity: the robot's inertia alone sets the torques, so
    any fraction of the free cycle's peak is a limit some profile meets."""
    from dataclasses import replace

    from planner.dynamics import Inertia, inverse_dynamics

    inertia = Inertia.default(DESIGN)
    G0 = (0.0, 0.0, 0.0)
    targets = pick_place(stop_corners=True)
    free = solve_sequence(DESIGN, START, targets, objective="fixed", inertia=inertia, gravity=G0)
    assert free.status is PlanStatus.SOLVED and free.trajectory.tau is not None
    traj = free.trajectory
    need = np.abs(inverse_dynamics(DESIGN, inertia, traj.q, traj.qd, traj.qdd, gravity=G0).tau).max(
        axis=0
    )
    np.testing.assert_allclose(np.abs(traj.tau).max(axis=0), need, rtol=1e-6)
    limit = 0.6 * need
    slow = solve_sequence(
        DESIGN,
        START,
        targets,
        objective="fixed",
        inertia=inertia,
        gravity=G0,
        limits=replace(LIMITS, torque=tuple(float(x) for x in limit)),
    )
    assert slow.status is PlanStatus.SOLVED, slow.message
    t = slow.trajectory
    tau = inverse_dynamics(DESIGN, inertia, t.q, t.qd, t.qdd, gravity=G0).tau
    assert np.all(np.abs(tau) <= limit * (1 + 1e-3) + 1e-9)
    assert slow.cycle_time > free.cycle_time * 1.02


@pytest.mark.parametrize("late_by", [1.0, 0.0])
def test_a_mode_search_whose_deadline_passed_ends_as_a_timeout(late_by):
    """The mode search (a Cartesian target in working mode "any") whose deadline passes
    before its first assignment is planned answers as a sequence whose budget ran out,
    status ``timeout`` (as the fixed objective's does), not an AssertionError; and the same
    through the service's job (its answer, never a 500)."""
    import time

    from planner.endpoints import JobBudget
    from planner.endpoints.sequence import sequence as sequence_job
    from planner.wire import SequenceRequest

    targets = pick_place(stop_corners=True)
    deadline = time.monotonic() - late_by
    for objective in ("time", "fixed"):
        result = solve_sequence(DESIGN, START, targets, objective=objective, deadline=deadline)
        assert result.status is PlanStatus.TIMEOUT and not result.solved, objective
        assert "deadline" in result.message, result.message
    body = {
        "start": {"q": list(START.q), "assembly_mode": "+"},
        "targets": [{"goal": {"p": list(t.goal.p), "working_mode": "any"}} for t in targets],
    }
    answer = sequence_job(SequenceRequest.model_validate(body), JobBudget(deadline=deadline))
    assert answer.status == "timeout" and "deadline" in answer.message


def test_a_target_no_candidate_reaches_in_its_own_mode_is_answered_by_the_plans():
    """A target fixed to a working mode that cannot reach it, beside an "any" one, leaves the
    mode search no assignment: the targets as given answer (which one, and why)."""
    targets = [
        SequenceTarget(CartesianTarget(at(0, 0, 0.05))),
        SequenceTarget(CartesianTarget(at(0, 0.3, 0.0), "---")),
    ]
    result = solve_sequence(DESIGN, START, targets)
    assert result.status is PlanStatus.UNREACHABLE and "target 1" in result.message
