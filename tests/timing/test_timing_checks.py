"""The dense re-check and the bounded repair: a trajectory leaving the valid set is repaired
or refused with a typed error, never returned silently; bad arguments are named."""

from __future__ import annotations

import itertools
import time

import numpy as np
import pytest
from timing_factories import box_checker, fine_times, kappa_checker, random_walk

from planner import Design, InputError, conditioning, forward_batch
from planner.exceptions import TimingDeadlineError, TrajectoryCheckError
from planner.timing import DEFAULT_CHECK_RESOLUTION, JointLimits, time_path
from planner.timing.checks import dense_check
from planner.timing.path import BlendedPath
from planner.timing.toppra_method import solve_toppra
from planner.timing.trajectory import ToppraCurve

DESIGN = Design.default()
LIMITS = JointLimits.default()
# A right-angle corner at (1, 0, 0.5): the 0.05 blend cuts through the box, the polyline
# does not (it runs along y = 0, then x = 1).
CORNER = np.array([[0.0, 0.0, 0.5], [1.0, 0.0, 0.5], [1.0, 1.0, 0.5]])
BLEND_BOX = box_checker([0.95, 0.01, -4.0], [0.99, 0.05, 4.0])


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_blend_entering_a_forbidden_box_is_repaired(method):
    free = time_path(DESIGN, CORNER, LIMITS, method=method)
    q_free, _, _, _ = free.at(fine_times(free.duration))
    assert not np.all(BLEND_BOX(q_free))  # the unrepaired blend does enter the box
    traj = time_path(DESIGN, CORNER, LIMITS, method=method, check_states=BLEND_BOX)
    assert traj.repairs >= 1
    q, _, _, _ = traj.at(fine_times(traj.duration, 50001))
    assert np.all(BLEND_BOX(q))
    assert traj.max_deviation_q < free.max_deviation_q


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_a_box_only_stopping_avoids_makes_the_corner_a_stop(method):
    check = box_checker([0.9, 1e-4, -4.0], [1.0 - 1e-4, 0.1, 4.0])
    traj = time_path(DESIGN, CORNER, LIMITS, method=method, check_states=check)
    assert traj.repairs == 3
    q, qd, _, _ = traj.at(fine_times(traj.duration, 50001))
    assert np.all(check(q))
    i = np.argmin(np.linalg.norm(q - CORNER[1], axis=1))
    assert np.linalg.norm(q[i] - CORNER[1]) < 1e-3 and np.linalg.norm(qd[i]) < 0.05


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_invalid_planned_segment_is_refused(method):
    check = box_checker([0.4, -0.1, 0.4], [0.6, 0.1, 0.6])  # on the first segment
    with pytest.raises(TrajectoryCheckError, match="path itself is invalid") as err:
        time_path(DESIGN, CORNER, LIMITS, method=method, check_states=check)
    assert err.value.rule == "validity"
    assert 0.4 <= err.value.q[0] <= 0.6


def test_dense_check_catches_what_the_output_samples_miss():
    # A thin slab crossed between two 10 Hz samples: the dense check must still see it.
    w = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    path = BlendedPath.from_waypoints(w, 0.0)
    curve = ToppraCurve(path, solve_toppra(path, LIMITS))
    t_out = np.arange(0, curve.duration, 0.1)
    q_out = curve.evaluate(t_out)[0][:, 0]
    mid = np.argmax(np.diff(q_out))
    x0 = q_out[mid] + 0.3 * (q_out[mid + 1] - q_out[mid])
    slab = box_checker([x0, -1, -1], [x0 + 0.005, 1, 1])
    assert np.all(slab(curve.evaluate(t_out)[0]))  # the output samples miss it
    report = dense_check(
        curve,
        design=DESIGN,
        assembly_mode="+",
        waypoints=w,
        limits=LIMITS,
        resolution=0.004,
        extra_times=t_out,
        check_states=slab,
        max_cartesian_speed=None,
    )
    assert not report.ok and np.any(report.bad_state)
    assert np.all(
        (report.q[report.bad_state, 0] >= x0) & (report.q[report.bad_state, 0] <= x0 + 0.005)
    )
    # The consecutive checked postures are at most the resolution apart.
    assert np.max(np.linalg.norm(np.diff(report.q, axis=0), axis=1)) <= 0.004 + 1e-12
    # And a limit exceeded by the curve is reported.
    slow = JointLimits(velocity=(0.5,) * 3, acceleration=(8.0,) * 3)
    report = dense_check(
        curve,
        design=DESIGN,
        assembly_mode="+",
        waypoints=w,
        limits=slow,
        resolution=0.01,
        extra_times=t_out,
        check_states=None,
        max_cartesian_speed=None,
    )
    assert not report.limits_ok and report.worst_limit[0] == "velocity"


def test_a_toppra_curve_is_checked_for_validity_at_the_resolution_and_the_samples():
    """With ``validity_times`` (a toppra curve's :meth:`ToppraCurve.validity_times`, what
    ``time_path`` passes), the rules are asked at postures at most the resolution apart in
    joint space (measured here on the postures asked, sorted by time) and at every output
    sample, not at the grid's sub-samples that the limits need: fewer postures asked, and a
    thin slab between two output samples still caught; without it, every check time."""
    w = np.array([[0.0, 0.0, 0.0], [1.0, 0.6, 0.2], [1.6, 0.1, 0.9]])
    path = BlendedPath.from_waypoints(w, 0.05)
    curve = ToppraCurve(path, solve_toppra(path, LIMITS))
    t_out = np.arange(0, curve.duration, 0.1)
    resolution = 0.01
    every = curve.check_times(resolution)
    at = curve.validity_times(resolution)
    assert np.all(np.isin(at, every)) and len(at) < len(every)  # the same floats
    asked: list[np.ndarray] = []

    def record(q):
        asked.append(np.array(q))
        return np.ones(len(q), dtype=bool)

    kwargs = dict(
        design=DESIGN,
        assembly_mode="+",
        waypoints=w,
        limits=LIMITS,
        resolution=resolution,
        extra_times=t_out,
        max_cartesian_speed=None,
    )
    report = dense_check(curve, check_states=record, validity_times=at, **kwargs)
    assert not report.bad_state.any()
    q_at = curve.evaluate(np.union1d(at, t_out))[0]
    np.testing.assert_array_equal(asked[0], q_at)  # in time order
    assert np.max(np.linalg.norm(np.diff(q_at, axis=0), axis=1)) <= resolution + 1e-12
    dense_check(curve, check_states=record, **kwargs)
    assert len(asked[1]) == len(report.t) > len(asked[0])
    dense_check(curve, check_states=record, validity_times=at[1:] - 1e-9, **kwargs)
    assert len(asked[2]) == len(report.t)  # times not among the check times: every posture
    # a slab crossed between two output samples and between two sub-samples is caught
    q_out = curve.evaluate(t_out)[0][:, 0]
    mid = int(np.argmax(np.diff(q_out)))
    x0 = q_out[mid] + 0.3 * (q_out[mid + 1] - q_out[mid])
    slab = box_checker([x0, -1, -1], [x0 + 0.012, 1, 1])
    assert np.all(slab(curve.evaluate(t_out)[0]))
    report = dense_check(curve, check_states=slab, validity_times=at, **kwargs)
    assert report.bad_state.any() and set(report.state_rule[report.bad_state]) == {"validity"}


@pytest.mark.parametrize("design", [Design.default(), Design(0.6, 0.25, 0.45)])
def test_the_compiled_pass_of_a_toppra_curve_equals_the_steps(design):
    """The re-check of a toppra curve in one compiled pass (profile, postures, rates, P and
    its velocity, joint limits, deviation from the plan and P's, ratios) gives the report of
    the generic steps bit for bit: the same curve behind ``TimeScaledCurve(curve, 1.0)``,
    which evaluates the same times through ``evaluate`` and ``plan_segments``. Blended
    corners farther from the plan than allowed, postures outside the joint limits and, on
    the second design, postures whose loop opens (assembly)."""
    from planner.timing.trajectory import TimeScaledCurve

    rng = np.random.default_rng(2)
    opened = 0
    named: set[str] = set()
    for _ in range(6):
        w = np.cumsum(rng.uniform(-0.8, 0.8, (5, 3)), axis=0) + np.array([0.0, 2.0, 1.0])
        path = BlendedPath.from_waypoints(w, 0.1)
        curve = ToppraCurve(path, solve_toppra(path, LIMITS))
        kwargs = dict(
            design=design,
            assembly_mode="+",
            waypoints=w,
            limits=LIMITS,
            resolution=0.01,
            extra_times=np.arange(0, curve.duration, 0.01),
            check_states=kappa_checker(design, 30.0),
            max_cartesian_speed=0.3,
            deviation_limit=np.full(5, 0.05),
        )
        fused = dense_check(curve, **kwargs)
        steps = dense_check(TimeScaledCurve(curve, 1.0), **kwargs)
        assert fused.limit_ratio == steps.limit_ratio
        assert (fused.max_deviation_q, fused.max_deviation_p) == (
            steps.max_deviation_q,
            steps.max_deviation_p,
        )
        for a, b in ((fused.t, steps.t), (fused.q, steps.q), (fused.bad_state, steps.bad_state)):
            assert np.array_equal(a, b)
        assert list(fused.state_rule) == list(steps.state_rule)
        opened += int(np.sum(fused.state_rule == "assembly"))
        named.update(fused.state_rule)
    assert {"deviation", "joint_limits", ""} <= named  # blends too far, joints beyond limits
    if design.L0 + 2 * design.L1 > 2 * design.L2:
        assert opened > 0


@pytest.mark.parametrize("design", [Design.default(), Design(0.6, 0.25, 0.45)])
def test_the_fit_ratios_equal_their_numpy_steps(design):
    """``fit_ratios`` (the time-scale fit's compiled pass) against the fit's numpy steps at
    the same positions: the profile's rates, the path's postures, the ratios to the limits,
    and the largest |dP/ds| sd (inf |dP/ds| where a loop opens; NaN where that meets sd = 0)
    bit for bit."""
    from planner.timing.checks import fit_ratios
    from planner.timing.trajectory import p_velocity

    rng = np.random.default_rng(8)
    kinds = set()
    for _ in range(8):
        w = np.cumsum(rng.uniform(-0.8, 0.8, (5, 3)), axis=0) + np.array([0.0, 2.0, 1.0])
        path = BlendedPath.from_waypoints(w, 0.1)
        curve = ToppraCurve(path, solve_toppra(path, LIMITS))
        s = curve.check_path_positions(0.01, ordered=False)
        _, sd, sdd = curve.profile.at_path(s)
        q, d1, d2 = path.evaluate_all(s)
        r_v = np.max(np.abs(d1 * sd[:, None]) / LIMITS.velocity_array)
        r_a = np.max(np.abs(d1 * sdd[:, None] + d2 * (sd**2)[:, None]) / LIMITS.acceleration_array)
        _, v, ok = p_velocity(design, q, d1, "+")
        with np.errstate(invalid="ignore"):  # inf * 0 where a loop opens at rest
            peak = np.max(np.where(ok, np.linalg.norm(v, axis=1), np.inf) * sd)
        got = fit_ratios(curve, s, design, "+", LIMITS)
        assert got[:2] == (r_v, r_a)
        assert got[2] == peak or (np.isnan(got[2]) and np.isnan(peak))
        kinds.add("nan" if np.isnan(peak) else "inf" if np.isinf(peak) else "finite")
    assert "finite" in kinds
    if design.L0 + 2 * design.L1 > 2 * design.L2:
        assert kinds - {"finite"}, kinds  # a posture whose loop opens


def test_kappa_checker_passes_on_a_well_conditioned_path():
    design = Design.paper_optimum()
    # Postures with theta4 - theta5 near pi/2 (kappa(A) ~ 1) for the paper optimum.
    w = np.array([[0.0, 0.3, 2.2], [0.3, 0.5, 2.3], [0.5, 0.4, 2.5], [0.8, 0.6, 2.4]])
    check = kappa_checker(design, 5.0)
    assert np.all(check(w))
    traj = time_path(design, w, LIMITS, check_states=check)
    q, _, _, _ = traj.at(fine_times(traj.duration, 5001))
    batch = forward_batch(design, q, "+")
    kappa = conditioning(design, batch.q, batch.passive, batch.w).kappa_A
    assert batch.ok.all() and kappa.max() <= 5.0


def test_deadline_in_the_past_raises_timeout():
    with pytest.raises(TimingDeadlineError):
        time_path(DESIGN, CORNER, LIMITS, deadline=time.monotonic() - 1.0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"waypoints": np.array([[0.0, 0.0, np.nan]])}, "waypoints must be finite"),
        ({"waypoints": np.zeros((3, 2))}, "waypoints must have shape"),
        ({"waypoints": np.array([[0.0, 0.0, 4.0]])}, r"waypoints\[0\].*outside the joint limits"),
        ({"method": "spline"}, "method must be one of"),
        ({"stop_at": [7]}, "stop_at must hold waypoint indices"),
        ({"sample_rate_hz": 0.0}, "sample_rate_hz must be a positive"),
        ({"check_resolution": float("nan")}, "check_resolution must be a positive"),
        ({"max_cartesian_speed": -1.0}, "max_cartesian_speed must be a positive"),
        ({"max_deviation": -0.1}, "max_deviation must be finite and >= 0"),
        ({"assembly_mode": "x"}, "assembly_mode"),
        ({"check_states": lambda q: np.ones(3, bool)}, "check_states must return"),
    ],
)
def test_bad_arguments_are_named(kwargs, match):
    args = {"waypoints": CORNER, **kwargs}
    with pytest.raises(InputError, match=match):
        time_path(DESIGN, args.pop("waypoints"), LIMITS, **args)


def test_random_paths_with_a_box_inside_a_corner_are_never_returned_invalid():
    """The dense re-check puts consecutive checked postures at most ``check_resolution``
    apart, so every posture is within half of it of a checked one (module docstring of
    :mod:`planner.timing.checks`): a rule checked with that margin holds everywhere. The
    timing is given the box grown by the half resolution; no posture of a fine time grid,
    independent of the check times, may enter the box itself."""
    half = DEFAULT_CHECK_RESOLUTION / 2
    repaired = 0
    for seed in range(8):
        w = random_walk(seed, n=6)
        k = 1 + seed % 4
        y1 = (w[k] - w[k - 1]) / np.linalg.norm(w[k] - w[k - 1])
        y2 = (w[k + 1] - w[k]) / np.linalg.norm(w[k + 1] - w[k])
        inward = (y2 - y1) / np.linalg.norm(y2 - y1)
        centre = w[k] + 0.03 * inward  # where the 0.05 blend passes, off the polyline
        check = box_checker(centre - 0.008, centre + 0.008)
        grown = box_checker(centre - 0.008 - half, centre + 0.008 + half)
        dense = np.concatenate([np.linspace(a, b, 2000) for a, b in itertools.pairwise(w)])
        if not np.all(grown(dense)):
            continue
        for method in ("toppra", "ruckig"):
            try:
                traj = time_path(DESIGN, w, LIMITS, method=method, check_states=grown)
            except TrajectoryCheckError:
                continue  # refused with a typed error: allowed
            q, _, _, _ = traj.at(fine_times(traj.duration, 20001))
            assert np.all(check(q))
            repaired += traj.repairs > 0
    assert repaired >= 4  # the repair path was exercised


def test_too_many_output_samples_is_an_input_error():
    slow = JointLimits(velocity=(1e-3,) * 3, acceleration=(1e-3,) * 3)
    with pytest.raises(InputError, match="sample_rate_hz"):
        time_path(DESIGN, CORNER, slow, sample_rate_hz=1000.0)


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_near_duplicate_and_tiny_segments_end_exactly(method):
    offsets = np.array(
        [[0, 0, 0], [1e-11, 1e-11, 1e-11], [0.5, 0, 0], [0.5, 1e-7, 0], [0.5, 0.4, 0.1],
         [0.5, 0.4, 0.1 + 1e-10]]
    )  # fmt: skip
    w = np.array([0.2, 0.3, 0.4]) + offsets
    traj = time_path(DESIGN, w, LIMITS, method=method)
    assert np.array_equal(traj.q[0], w[0]) and np.array_equal(traj.q[-1], w[-1])
    q, qd, _, _ = traj.at(np.array([traj.duration]))
    np.testing.assert_allclose(q[0], w[-1], atol=1e-12)
    np.testing.assert_allclose(qd[0], 0.0, atol=1e-9)


def test_dense_check_flags_postures_farther_than_the_allowance():
    path = BlendedPath.from_waypoints(CORNER, 0.05)
    curve = ToppraCurve(path, solve_toppra(path, LIMITS))
    common = dict(
        design=DESIGN,
        assembly_mode="+",
        waypoints=CORNER,
        limits=LIMITS,
        resolution=0.01,
        extra_times=np.zeros(0),
        check_states=None,
        max_cartesian_speed=None,
    )
    loose = dense_check(curve, deviation_limit=np.array([0.0, 0.05, 0.0]), **common)
    assert not loose.bad_state.any()
    # The arc's farthest point from the two segments: r (1 - cos(a/2)), r = l = 0.05 / tan(pi/8)
    r = 0.05 / np.tan(np.pi / 8)
    assert loose.max_deviation_q == pytest.approx(r * (1 - np.cos(np.pi / 4)), rel=1e-4)
    tight = dense_check(curve, deviation_limit=np.array([0.0, 0.02, 0.0]), **common)
    flagged = tight.state_rule == "deviation"
    assert flagged.any() and np.all(tight.bad_state == flagged)
    # Exactly the postures farther than 0.02 from the two segments are flagged.
    q = tight.q
    dist = np.minimum(
        np.hypot(q[:, 1], q[:, 2] - 0.5) * (q[:, 0] <= 1) + (q[:, 0] > 1) * 9,
        np.hypot(q[:, 0] - 1, q[:, 2] - 0.5),
    )
    np.testing.assert_array_equal(flagged, dist > 0.02 + 1e-9)
