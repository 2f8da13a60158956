"""Straight tool paths (planner.cartesian.plan) against independent routes.

Forward kinematics, kappa(A), the serial measures and link clearance are re-derived here from
the closed forms of docs/conventions.md with numpy alone (nothing from the library's
kinematics), and the distance of P to the polyline is measured on a dense resampling of the
timed trajectory.
"""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest

from planner import Design
from planner.cartesian.plan import (
    CHORD_SHARE,
    chord_deviation_bound,
    inspect_cartesian,
    plan_cartesian,
)
from planner.cartesian.walk import BISECT_TOL
from planner.cartesian.walk import narrow_bracket as _narrow
from planner.geometry import Sphere
from planner.kinematics import WORKING_MODES, inverse_batch
from planner.planning.problem import JointPosture
from planner.validity import Margins


# ---------------------------------------------------------------- independent closed forms
def own_fk(design: Design, q: np.ndarray, assembly_mode: str):
    """(P (M, 3), theta4, theta5, C, D in-plane (M, 2) each, ok) from conventions.md."""
    q = np.atleast_2d(q)
    half = design.L0 / 2
    c = np.stack([-half + design.L1 * np.cos(q[:, 1]), design.L1 * np.sin(q[:, 1])], axis=1)
    d = np.stack([half + design.L1 * np.cos(q[:, 2]), design.L1 * np.sin(q[:, 2])], axis=1)
    m = 0.5 * (c + d)
    cd = d - c
    dist = np.linalg.norm(cd, axis=1)
    h = np.sqrt(np.maximum(design.L2**2 - (dist / 2) ** 2, 0.0))
    n = np.stack([-cd[:, 1], cd[:, 0]], axis=1) / dist[:, None]
    best = None
    for side in (1.0, -1.0):
        p = m + side * h[:, None] * n
        cross = (p - c)[:, 0] * (p - d)[:, 1] - (p - c)[:, 1] * (p - d)[:, 0]
        good = np.sign(cross) == (1 if assembly_mode == "+" else -1)
        best = p if best is None else np.where(good[:, None], p, best)
    p = best
    t4 = np.arctan2(p[:, 1] - c[:, 1], p[:, 0] - c[:, 0])
    t5 = np.arctan2(p[:, 1] - d[:, 1], p[:, 0] - d[:, 0])
    u, w = p[:, 0], p[:, 1]
    p3 = np.stack([w * np.cos(q[:, 0]), u, -w * np.sin(q[:, 0])], axis=1)
    return p3, t4, t5, c, d, dist <= 2 * design.L2


def own_kappa(t4, t5):
    half = np.abs(np.tan((t4 - t5) / 2))
    return np.maximum(half, 1 / half)


def seg_dist(pts, a, b):
    ab = b - a
    t = np.clip((pts - a) @ ab / (ab @ ab), 0, 1)
    return np.linalg.norm(a + t[:, None] * ab - pts, axis=1)


def poly_dist(pts, vertices):
    return np.min([seg_dist(pts, a, b) for a, b in pairwise(vertices)], axis=0)


def start_at(design: Design, p, mode="+-+"):
    ib = inverse_batch(design, np.asarray(p, float))
    k = WORKING_MODES.index(mode)
    assert ib.ok[0, k]
    return JointPosture(ib.q[0, k], "+" if ib.assembly_mode_signs[0, k] > 0 else "-")


DEFAULT = Design.default()
P_MID = np.array([0.45, 0.0, 0.1])


# ---------------------------------------------------------------- solved paths
@pytest.mark.parametrize("method", ["toppra", "ruckig"])
@pytest.mark.parametrize(
    "offsets",
    [
        [[0.0, 0.3, 0.0]],
        [[0.0, 0.12, 0.0], [0.06, 0.12, 0.1]],  # a corner
        [[0.05, 0.1, -0.05], [0.0, 0.2, 0.05], [-0.05, 0.15, 0.1]],
    ],
)
def test_timed_trajectory_keeps_p_within_tolerance(method, offsets):
    start = start_at(DEFAULT, P_MID)
    wp = P_MID + np.asarray(offsets)
    tol = 1e-3
    res = plan_cartesian(
        DEFAULT, start, wp, path_tolerance=tol, timing=method, cartesian_speed=0.25
    )
    assert res.status.value == "solved" and res.fraction == 1.0, res.message
    traj = res.trajectory
    assert traj is not None, res.timing_error
    # ruckig may give way to toppra when its moves stray beyond the blend allowance
    assert traj.method == method or "timed with toppra instead" in res.timing_error
    t = np.linspace(0, traj.duration, 20001)
    q = traj.at(t)[0]
    p, t4, t5, *_, ok = own_fk(DEFAULT, q, start.assembly_mode)
    assert np.all(ok)
    vertices = np.vstack([own_fk(DEFAULT, start.q, start.assembly_mode)[0], wp])
    dev = poly_dist(p, vertices)
    assert dev.max() <= tol, dev.max()
    # the joint path alone stays within the chord share
    w = res.path.waypoints
    dense = np.concatenate([a + np.linspace(0, 1, 200)[:, None] * (b - a) for a, b in pairwise(w)])
    assert poly_dist(own_fk(DEFAULT, dense, start.assembly_mode)[0], vertices).max() <= (
        CHORD_SHARE * tol
    )
    # ends: the start posture and P on the last waypoint, and the tool speed bound
    assert np.allclose(traj.q[0], start.q)
    assert np.linalg.norm(own_fk(DEFAULT, traj.q[-1], start.assembly_mode)[0][0] - wp[-1]) < 1e-9
    assert np.max(traj.p_speed) <= 0.25 * (1 + 1e-3)
    # the library's own measure agrees with ours
    assert res.diagnostics.max_path_deviation <= tol
    assert kappa_ok(own_kappa(t4, t5), Margins().kappa_max)


def kappa_ok(k, kmax):
    return bool(np.all(k <= kmax * (1 + 1e-6)))


def test_chord_bound_is_an_upper_bound_on_random_pieces():
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(300):
        qa = rng.uniform(-3, 3, 3)
        qb = qa + rng.uniform(-0.15, 0.15, 3)
        pa, *_, oka = own_fk(DEFAULT, qa, "+")
        pb, *_, okb = own_fk(DEFAULT, qb, "+")
        if not (oka[0] and okb[0]):
            continue
        wa = np.array([np.hypot(pa[0, 0], pa[0, 2])])
        wb = np.array([np.hypot(pb[0, 0], pb[0, 2])])
        bound = chord_deviation_bound(DEFAULT, qa[None], qb[None], wa, wb, pa, pb, "+")[0]
        t = np.linspace(0, 1, 2001)
        p, *_, ok = own_fk(DEFAULT, qa + t[:, None] * (qb - qa), "+")
        if not np.all(ok) or not np.isfinite(bound):
            continue
        true = seg_dist(p, pa[0], pb[0]).max()
        assert true <= bound + 1e-12
        checked += 1
    assert checked > 100


def _chord_bound_vectorised(design, q_a, q_b, w_a, w_b, line_a, line_b, asm, m=8):
    """chord_deviation_bound as numpy arrays of all pieces at once (its form before it was
    compiled): the library's forward kinematics at t = k / m, the second-derivative bound."""
    from planner.cartesian.chords import second_derivative_bound
    from planner.kinematics import forward_batch

    n = q_a.shape[0]
    t = np.arange(m + 1) / m
    qs = (q_a[:, None, :] + t[None, :, None] * (q_b - q_a)[:, None, :]).reshape(-1, 3)
    fb = forward_batch(design, qs, asm)
    p = fb.p.reshape(n, m + 1, 3)
    ok = np.all(fb.ok.reshape(n, m + 1), axis=1)
    chord = p[:, :1] + t[None, :, None] * (p[:, -1:] - p[:, :1])
    f = np.max(np.linalg.norm(p - chord, axis=2), axis=1)
    ends = np.maximum(
        np.linalg.norm(p[:, 0] - line_a, axis=1), np.linalg.norm(p[:, -1] - line_b, axis=1)
    )
    m2 = second_derivative_bound(design, q_a, q_b, w_a, w_b)
    with np.errstate(invalid="ignore"):
        bound = f + m2 / (8.0 * m * m) + ends
    return np.where(ok & np.isfinite(bound), bound, np.inf)


@pytest.mark.parametrize("design", [DEFAULT, Design(0.6, 0.25, 0.45)])
def test_compiled_chord_bound_equals_the_vectorised_form(design):
    """The compiled chord bound, bit for bit the vectorised numpy form on random pieces, short
    and long (finite bounds, pieces near a parallel singularity where the apex sine may
    vanish, and, on the second design, postures whose loop does not close: inf)."""
    rng = np.random.default_rng(5)
    n = 400
    q_a = rng.uniform(-3, 3, (n, 3))
    q_b = q_a + rng.choice([0.03, 1.0, 10.0], (n, 1)) * rng.uniform(-0.3, 0.3, (n, 3))
    w_a, w_b = rng.uniform(-0.8, 0.8, n), rng.uniform(-0.8, 0.8, n)
    line_a, line_b = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    for asm in ("+", "-"):
        for m in (1, 8):
            got = chord_deviation_bound(
                design, q_a, q_b, w_a, w_b, line_a, line_b, asm, subdivisions=m
            )
            ref = _chord_bound_vectorised(design, q_a, q_b, w_a, w_b, line_a, line_b, asm, m)
            assert np.array_equal(got, ref)
            assert np.isfinite(got).sum() > 50 and np.isinf(got).sum() > 5


# ---------------------------------------------------------------- stopping points
def test_line_into_a_serial_singularity_stops_at_the_margin_sphere():
    """Outward along +y from A: leg A stretches at |AP| = L1 + L2; serial_min is met first
    where |AP|^2 = L1^2 + L2^2 + 2 L1 L2 sqrt(1 - serial_min^2) (law of cosines)."""
    m = Margins()
    start = start_at(DEFAULT, P_MID)
    p0 = own_fk(DEFAULT, start.q, start.assembly_mode)[0][0]
    goal = p0 + np.array([0.0, 0.5, 0.0])
    res = plan_cartesian(DEFAULT, start, goal[None], timing="toppra")
    assert res.status.value == "no_path" and res.fraction < 1
    assert res.stop.rule == "serial_min"
    a = np.array([0.0, -DEFAULT.L0 / 2, 0.0])
    r = math.sqrt(
        DEFAULT.L1**2 + DEFAULT.L2**2 + 2 * DEFAULT.L1 * DEFAULT.L2 * math.sqrt(1 - m.serial_min**2)
    )
    # the crossing of the line with the sphere |AP| = r, by bisection (independent)
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if np.linalg.norm(p0 + mid * (goal - p0) - a) < r else (lo, mid)
    assert res.fraction == pytest.approx(lo, abs=2e-3)
    assert res.fraction <= lo + 1e-9
    assert "serial_min" in res.message and "% along the path" in res.message
    assert "P = (" in res.message
    # the last posture is valid and on the line
    q_end = res.path.waypoints[-1]
    p_end, t4, *_ = own_fk(DEFAULT, q_end, start.assembly_mode)
    assert np.linalg.norm(p_end[0] - res.stop.p) < 1e-9
    assert abs(np.sin(t4[0] - q_end[1])) >= m.serial_min
    assert res.stop.value < m.serial_min
    # the pre-check knows the surfaces: the margin sphere, then the stretched leg
    kinds = [e.kind for e in res.events]
    assert "serial_min" in kinds and "leg_A_stretched" in kinds
    ev = next(e for e in res.events if e.kind == "leg_A_stretched")
    assert np.linalg.norm(ev.p - a) == pytest.approx(DEFAULT.L1 + DEFAULT.L2, abs=1e-9)
    # the partial path is timed and stays on the line
    assert res.trajectory is not None
    t = np.linspace(0, res.trajectory.duration, 5001)
    p, *_ = own_fk(DEFAULT, res.trajectory.at(t)[0], start.assembly_mode)
    assert seg_dist(p, p0, goal).max() <= 1e-3


def test_line_towards_the_axis_stops_at_the_axis_margin():
    """The default design's workspace never touches the axis AB; this one's does."""
    m = Margins()
    design = Design(0.2, 0.3, 0.4)
    start = start_at(design, np.array([0.3, 0.4, 0.1]))
    p0 = own_fk(design, start.q, start.assembly_mode)[0][0]
    goal = np.array([-0.3, 0.4, -0.1])  # through the axis at (0, 0.4, 0)
    res = plan_cartesian(design, start, goal[None], timing="none")
    assert res.stop.rule == "serial_min", res.message
    p_end = res.stop.p
    # the stop is where |w| / (L1 + L2) = serial_min, |w| = distance to the y axis
    margin = np.hypot(p_end[0], p_end[2]) / design.reach
    assert m.serial_min <= margin == pytest.approx(m.serial_min, rel=1e-2)
    assert any(e.kind == "P_on_axis" for e in res.events)
    line = goal - p0
    assert res.fraction == pytest.approx(np.linalg.norm(p_end - p0) / np.linalg.norm(line))


def test_line_into_a_parallel_singularity_stops_at_kappa_max():
    design = Design(0.6, 0.25, 0.45)
    q = np.array([1.0203710958896153, 1.2877112199285161, -1.997682427306367])
    start = JointPosture(q, "+")
    p0 = own_fk(design, q, "+")[0][0]
    direction = np.array([-0.2829635943241514, -0.6170719108927705, 0.7342709725123973])
    goal = p0 + 0.3 * direction
    res = plan_cartesian(design, start, goal[None], timing="none")
    assert res.stop.rule == "kappa_max"
    assert "kappa(A) = " in res.message and "> margins.kappa_max = 10" in res.message
    # independent kappa along the line by our own IK-free route: the joint path's end, and a
    # posture a little further by the library's IK, measured with our FK
    q_end = res.path.waypoints[-1]
    _, t4, t5, *_ = own_fk(design, q_end, "+")
    assert own_kappa(t4, t5)[0] <= 10 * (1 + 1e-9)
    assert own_kappa(t4, t5)[0] > 9.9  # stopped at the margin, not before
    assert res.stop.value > 10
    # every posture of the joint path keeps kappa <= 10 (dense, our FK)
    w = res.path.waypoints
    dense = np.concatenate([a + np.linspace(0, 1, 100)[:, None] * (b - a) for a, b in pairwise(w)])
    _, t4, t5, *_ = own_fk(design, dense, "+")
    assert kappa_ok(own_kappa(t4, t5), 10)
    assert any(e.kind == "kappa_max" and e.entering for e in res.events)


def test_line_into_an_obstacle_stops_at_the_clearance():
    m = Margins()
    start = start_at(DEFAULT, P_MID)
    p0 = own_fk(DEFAULT, start.q, start.assembly_mode)[0][0]
    goal = p0 + np.array([0.0, 0.2, 0.0])
    ball = Sphere(center=p0 + np.array([0.0, 0.15, 0.0]), radius=0.03)
    res = plan_cartesian(DEFAULT, start, goal[None], obstacles=[ball], timing="none")
    assert res.stop.rule == "clearance"
    assert "clearance" in res.message
    # our own clearance at the end posture: links AC, BD, CP, DP against the ball
    q_end = res.path.waypoints[-1]
    p, _, _, c, d, _ = own_fk(DEFAULT, q_end, start.assembly_mode)
    t1 = q_end[0]

    def to3(uw):
        return np.array([uw[1] * np.cos(t1), uw[0], -uw[1] * np.sin(t1)])

    a3, b3 = np.array([0, -DEFAULT.L0 / 2, 0]), np.array([0, DEFAULT.L0 / 2, 0])
    c3, d3 = to3(c[0]), to3(d[0])
    links = [(a3, c3), (b3, d3), (c3, p[0]), (d3, p[0])]
    clear = min(seg_dist(ball.center[None], s, e)[0] for s, e in links)
    clear -= ball.radius + DEFAULT.link_radius
    assert m.clearance <= clear < m.clearance + 2e-3
    assert 0.3 < res.fraction < 0.75


def test_line_out_of_the_workspace_stops_before_leaving_it():
    start = start_at(DEFAULT, P_MID)
    p0 = own_fk(DEFAULT, start.q, start.assembly_mode)[0][0]
    goal = np.array([1.2, 0.0, 0.1])  # far outside: |AP| > L1 + L2
    res = plan_cartesian(DEFAULT, start, goal[None], timing="none")
    assert res.status.value == "no_path"
    leave = [e for e in res.events if e.kind.endswith("stretched") and e.entering]
    assert leave, res.events
    # the analytic exit point is outside reach of both legs from there on
    a = np.array([0.0, -DEFAULT.L0 / 2, 0.0])
    b = -a
    f_exit = leave[0].fraction
    beyond = p0 + (f_exit + 1e-3) * (goal - p0)
    assert max(np.linalg.norm(beyond - a), np.linalg.norm(beyond - b)) > DEFAULT.reach
    assert res.fraction < f_exit
    assert res.stop.rule in ("serial_min", "workspace")


def test_joint_limits_stop_the_line():
    design = Design(
        0.5, 0.2, 0.6, joint_min=(-0.3, -math.pi, -math.pi), joint_max=(0.3, math.pi, math.pi)
    )
    start = start_at(design, P_MID)
    goal = P_MID + np.array([0.0, 0.0, 0.3])  # turns theta1 past -0.3
    res = plan_cartesian(design, start, goal[None], timing="none")
    assert res.stop.rule == "joint_limits"
    assert "theta1 = " in res.message
    q_end = res.path.waypoints[-1]
    assert abs(q_end[0]) == pytest.approx(0.3, abs=1e-5)
    assert np.all(res.path.waypoints[:, 0] >= -0.3)


def test_a_joint_limit_of_pi_is_written_with_the_values_digits():
    """A new user's report: a straight path across theta2 = pi stopped with
    "theta2 = 3.14159266 rad > joint_max[1] = 3.14159 rad", a bound that reads as another
    number than pi. The bound has the value's digits, and the two numbers say the rule."""
    import re

    from planner.cartesian.messages import _joint_limit_text

    for value, bound in ((math.pi + 7e-9, math.pi), (-math.pi - 3e-9, -math.pi), (0.30001, 0.3)):
        text = _joint_limit_text(1, value, bound)
        m = re.fullmatch(
            r"joint_limits: theta2 = (\S+) rad ([<>]) joint_(min|max)\[1\] = (\S+) rad", text
        )
        assert m, text
        shown_value, rel, side, shown_bound = m.groups()
        assert float(shown_value) != float(shown_bound)
        assert (float(shown_value) > float(shown_bound)) == (rel == ">") == (side == "max")
        assert float(shown_bound) == pytest.approx(bound, rel=1e-8)
    assert _joint_limit_text(1, math.pi + 7e-9, math.pi).endswith("= 3.14159265 rad")


def test_invalid_start_and_bad_arguments():
    from planner import InputError

    design = Design(0.5, 0.2, 0.6)
    res = plan_cartesian(design, JointPosture([4.0, 2.0, 1.0], "+"), [[0.3, 0.0, 0.0]])
    assert res.status.value == "invalid_start" and res.fraction == 0.0
    assert "joint_limits" in res.message
    start = start_at(DEFAULT, P_MID)
    with pytest.raises(InputError, match="path_tolerance"):
        plan_cartesian(DEFAULT, start, [[0.4, 0.0, 0.0]], path_tolerance=0.0)
    with pytest.raises(InputError, match="waypoints"):
        plan_cartesian(DEFAULT, start, [[0.4, 0.0]])


def test_precheck_sphere_crossings_match_the_closed_form():
    start = start_at(DEFAULT, P_MID)
    p0 = own_fk(DEFAULT, start.q, start.assembly_mode)[0][0]
    goal = np.array([0.45, 0.8, 0.1])
    events = inspect_cartesian(DEFAULT, start, goal[None])
    b = np.array([0.0, DEFAULT.L0 / 2, 0.0])
    a = -b
    for e in events:
        if e.kind.startswith("leg_"):
            centre = a if "leg_A" in e.kind else b
            r = DEFAULT.reach if "stretched" in e.kind else DEFAULT.L2 - DEFAULT.L1
            assert np.linalg.norm(e.p - centre) == pytest.approx(r, abs=1e-9)
            assert np.linalg.norm(e.p - p0) / np.linalg.norm(goal - p0) == pytest.approx(e.fraction)
    assert [e.fraction for e in events] == sorted(e.fraction for e in events)


@pytest.mark.parametrize("changes", [(0.3137,), (0.4321, 0.6, 0.9)])
def test_narrow_finds_the_first_change_within_the_tolerance(changes):
    """The batched search of a rule's boundary against the boundaries themselves: the
    bracket ends within BISECT_TOL around the first change (the rule flips at each of
    ``changes``), and the posture and rule reported are those at the bracket's end."""
    first = changes[0]

    def classify(s):
        flips = np.sum(s[:, None] >= np.asarray(changes)[None, :], axis=1)
        same = flips % 2 == 0
        return same, np.stack([s, s, s], axis=1), np.where(same, "", "kappa_max")

    a, b, q_b, reason = _narrow(0.0, 1.0, classify, BISECT_TOL)
    assert a < first <= b and b - a <= BISECT_TOL
    assert reason == "kappa_max" and q_b is not None and q_b[0] == b


# ---------------------------------------------------------------- a long robot
#: Links of 1000 m: every initial piece (INITIAL_STEP, 0.05 m of P) turns a joint enough to
#: move a link farther than a motion certificate allows, so thousands of pieces must each be
#: split (the review's 422 "the Cartesian refinement did not converge").
LONG = Design(1000.0, 1000.0, 1000.0)
LONG_START = JointPosture(np.array([0.0, 1.0, 2.0]), "+")


def _certified_and_on_the_line(res, vertices, tol):
    """The answer's joint path: every motion certified by the validity checker, and P (our
    own closed-form kinematics, densely along each joint-space piece) within the chord share
    of the tolerance of the line."""
    from planner.validity import ValidityChecker

    w = res.path.waypoints
    checker = ValidityChecker(LONG, Margins(kappa_max=1e6), (), "+", res.working_mode)
    assert checker.check_path(w, certify=True).valid
    dense = np.concatenate([a + np.linspace(0, 1, 5)[:, None] * (b - a) for a, b in pairwise(w)])
    assert poly_dist(own_fk(LONG, dense, "+")[0], vertices).max() <= CHORD_SHARE * tol


@pytest.mark.parametrize("direction", [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
def test_a_short_line_of_a_long_robot_gets_an_answer(direction):
    p0 = own_fk(LONG, LONG_START.q, "+")[0][0]
    end = p0 + 20.0 * np.asarray(direction)  # 2 % of a link
    res = plan_cartesian(
        LONG, LONG_START, [end], margins=Margins(kappa_max=1e6), timing="none", inspect=False
    )
    assert res.status.value == "solved" and res.fraction == 1.0, res.message
    assert np.linalg.norm(own_fk(LONG, res.path.waypoints[-1], "+")[0][0] - end) < 1e-6
    _certified_and_on_the_line(res, np.vstack([p0, end]), 1e-3)


def test_rounds_running_out_stop_at_the_certified_part(monkeypatch):
    """Past MAX_REFINEMENTS passes the answer is the certified part of the path, a no_path with a stop
    point and its rule, never an error (the old code raised, a 422 for valid input)."""
    import planner.cartesian.certify as certify

    monkeypatch.setattr(certify, "MAX_REFINEMENTS", 2)
    p0 = own_fk(LONG, LONG_START.q, "+")[0][0]
    end = p0 + np.array([0.0, 20.0, 0.0])
    res = plan_cartesian(
        LONG, LONG_START, [end], margins=Margins(kappa_max=1e6), timing="none", inspect=False
    )
    assert res.status.value == "no_path" and 0.0 <= res.fraction < 1.0
    assert res.stop is not None and res.stop.rule and res.stop.fraction == res.fraction
    assert "refinement passes" in res.message, res.message
    if len(res.path.waypoints) > 1:
        _certified_and_on_the_line(res, np.vstack([p0, end]), 1e-3)
    # P stops on the line at the reported fraction
    p_end = own_fk(LONG, res.path.waypoints[-1], "+")[0][0]
    assert np.linalg.norm(p_end - (p0 + res.fraction * (end - p0))) < 1e-6


def test_measures_reuse_the_certificate_and_equal_one_pass(monkeypatch):
    """The answer's measures (min clearance, max kappa(A), min serial margin, joint path
    length) come from the last certificate's own samples plus the waypoints before it
    (``Refinement.path_report``): equal to one fresh pass of ``check_path`` over the whole
    joint path, also where certificates failed and split the path (the head sampled apart),
    and the deviation measured on the timed trajectory equals the one measured through
    its check times."""
    from planner.cartesian import certify
    from planner.cartesian.walk import distance_to_polyline_3d
    from planner.kinematics import forward_batch
    from planner.validity import ValidityChecker

    heads = []
    original = certify.Refinement.path_report

    def spy(self):
        tail = self._report_q
        heads.append(0 if tail is None else len(self.q) - len(tail))
        return original(self)

    monkeypatch.setattr(certify.Refinement, "path_report", spy)
    start = JointPosture([0.0, 2.0, 1.0], "+")
    p0 = forward_batch(DEFAULT, np.asarray(start.q), "+").p[0]
    balls = [Sphere(center=p0 + np.array([0.02, 0.1, 0.05]), radius=0.04)]
    rng = np.random.default_rng(7)
    for _ in range(6):
        goal = p0 + 0.25 * rng.normal(size=3) / math.sqrt(3)
        res = plan_cartesian(DEFAULT, start, goal[None], obstacles=balls, cartesian_speed=0.25)
        if res.path is None:
            continue
        q = res.path.waypoints
        mode = res.working_mode
        ref = ValidityChecker(DEFAULT, Margins(), balls, "+", mode).check_path(q, certify=False)
        dg = res.diagnostics
        assert dg.min_clearance == pytest.approx(ref.min_clearance, rel=1e-12)
        assert dg.max_kappa_A == pytest.approx(ref.max_kappa_A, rel=1e-12)
        assert dg.min_serial_margin == pytest.approx(ref.min_serial_margin, rel=1e-12)
        assert dg.path_length == pytest.approx(ref.length, rel=1e-12)
        if res.trajectory is not None:
            curve = res.trajectory.curve
            pt = forward_batch(DEFAULT, curve.evaluate(curve.check_times(1e-3))[0], "+").p
            dev = float(np.max(distance_to_polyline_3d(res.polyline, pt)))
            assert dg.max_path_deviation == pytest.approx(dev, rel=1e-9)
    assert any(h > 0 for h in heads), heads  # a certificate failed and the head was sampled
    assert any(h == 0 for h in heads), heads  # and one covered the whole path


def test_deviation_along_a_path_equals_its_postures_measured_one_by_one():
    """``max_deviation_along`` (the answer's compiled measure) against two routes: the
    library's own steps (the path's postures, their forward kinematics, the distance to the
    polyline: bit for bit) and this file's closed-form kinematics and distances (to
    round-off), on a blended path with arcs, positions in any order and beyond its ends,
    polylines of one to four vertices, and inf where a posture does not assemble."""
    from planner.cartesian.walk import distance_to_polyline_3d, max_deviation_along
    from planner.kinematics import forward_batch
    from planner.timing.path import ARC, BlendedPath

    rng = np.random.default_rng(11)
    design = Design(0.6, 0.25, 0.45)  # its loop opens: L0 + 2 L1 > 2 L2
    # the last leg opens the loop (C and D more than 2 L2 apart near theta2 = pi, theta3 = 0)
    w = np.array([[0.0, 2.0, 1.0], [0.3, 2.2, 1.1], [0.5, 2.0, 1.4], [0.4, 3.1, 0.0]])
    path = BlendedPath.from_waypoints(w, 0.05)
    assert np.any(path.kind == ARC)
    s = rng.uniform(-0.1, path.length + 0.1, 3000)
    rest = BlendedPath.from_waypoints(w[:1], 0.05)
    infinite = 0
    for k in (1, 2, 4):
        vertices = rng.normal(size=(k, 3)) * 0.3
        for asm in ("+", "-"):
            q = path.evaluate_all(s)[0]
            fb = forward_batch(design, q, asm)
            steps = float(np.max(distance_to_polyline_3d(vertices, fb.p)))
            got = max_deviation_along(design, path, s[::-1], asm, vertices)
            assert got == steps or (math.isinf(got) and math.isinf(steps))
            p = own_fk(design, q, asm)[0]
            if k == 1:
                own = np.linalg.norm(p - vertices[0], axis=1)
            else:
                own = poly_dist(p, vertices)
            if np.all(fb.ok):
                assert got == pytest.approx(float(np.max(own)), rel=1e-12)
            else:
                assert math.isinf(got)
                infinite += 1
            at_rest = max_deviation_along(design, rest, s[:5], asm, vertices)
            p0 = forward_batch(design, w[0], asm).p
            assert at_rest == float(np.max(distance_to_polyline_3d(vertices, p0)))
    assert infinite > 0  # some postures of the other assembly mode do not close the loop
