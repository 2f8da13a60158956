"""The independent plan checker (tests/plan_checker.py) itself: its defaults are the library's,
its kinematics and clearance agree with the library and with dense sampling, it accepts real
solved plans of the service (free space, obstacles of every shape, a working-mode change with
and without a stop at the transit, a Cartesian goal, ruckig), and it rejects each tampered
answer for the rule that the tampering broke."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from plan_checker import (
    DEFAULT_DESIGN,
    DEFAULT_LIMITS,
    DEFAULT_MARGINS,
    DEFAULT_MAX_DEVIATION,
    check_plan,
    clearance,
    postures,
)
from planning_factories import point_distance

from planner.design import Design
from planner.geometry import Box, Capsule, Sphere
from planner.kinematics import conditioning, forward_batch, link_points, mode_label
from planner.timing import DEFAULT_MAX_DEVIATION as LIBRARY_MAX_DEVIATION
from planner.timing import JointLimits
from planner.validity import Margins

BUDGET = {"seed": 1, "time_budget_s": 5.0}  # generous: a cold worker must not turn it no_path
SPHERE = {"type": "sphere", "center": [0.549, -0.025, -0.376], "radius": 0.1}
BOX = {
    "type": "box",
    "center": [0.0, 0.0, -0.95],
    "size": [2.0, 2.0, 0.1],
    "quaternion": [0.9990482, 0.0436194, 0.0, 0.0],
}
CAPSULE = {"type": "capsule", "a": [-0.6, 0.75, 0.6], "b": [0.6, 0.75, 0.6], "radius": 0.05}
START = {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"}  # working mode +-+
# a posture of working mode +++ reached from START through one leg-A transit
MODE_GOAL = [2.1628673977784247, -0.6760414321727777, -0.0438376661931823]

SCENES = {
    "free": {"start": START, "goal": {"q": [0.5, 2.2, 1.1], "assembly_mode": "+"}},
    "obstacles": {
        "start": START,
        "goal": {"q": [1.2, 2.3, 1.3], "assembly_mode": "+"},
        "obstacles": [SPHERE, BOX, CAPSULE],
    },
    "mode_change": {"start": START, "goal": {"q": MODE_GOAL, "assembly_mode": "+"}},
    "mode_change_stop": {
        "start": START,
        "goal": {"q": MODE_GOAL, "assembly_mode": "+"},
        "planner": {**BUDGET, "stop_at_transits": True},
    },
    "cartesian": {
        "start": START,
        "goal": {"p": [0.3, 0.1, -0.5], "working_mode": "any"},
        "obstacles": [SPHERE],
        "margins": {"kappa_max": 8.0, "serial_min": 0.04, "clearance": 0.02},
    },
    "ruckig": {
        "start": START,
        "goal": {"q": [1.2, 2.3, 1.3], "assembly_mode": "+"},
        "obstacles": [SPHERE],
        "timing": {"method": "ruckig"},
        "limits": {"velocity": [1.0, 1.5, 2.0], "acceleration": [4.0, 5.0, 6.0]},
    },
    "high_kappa_mode": {  # working mode ++-, where C comes near D
        "start": {"q": [0.0, 0.6, 2.4], "assembly_mode": "+"},
        "goal": {"q": [0.4, 0.5, 2.6], "assembly_mode": "+"},
    },
}


@pytest.fixture(scope="module")
def plans(api):
    """Request and solved response of every scene, from the in-process service."""
    out = {}
    for name, scene in SCENES.items():
        body = {"planner": BUDGET, **copy.deepcopy(scene)}
        r = api.post("/v1/plan", json=body)
        assert r.status_code == 200, r.text
        assert r.json()["status"] == "solved", (name, r.json()["message"])
        out[name] = (body, r.json())
    return out


def test_defaults_are_the_librarys():
    d = Design.default()
    assert DEFAULT_DESIGN == {
        "L0": d.L0,
        "L1": d.L1,
        "L2": d.L2,
        "link_radius": d.link_radius,
        "joint_min": list(d.joint_min),
        "joint_max": list(d.joint_max),
    }
    m = Margins()
    assert DEFAULT_MARGINS == {
        "kappa_max": m.kappa_max,
        "serial_min": m.serial_min,
        "clearance": m.clearance,
    }
    lim = JointLimits.default()
    assert lim.jerk is None  # no jerk asked by default: toppra is not jerk-limited
    assert DEFAULT_LIMITS == {
        "velocity": list(lim.velocity),
        "acceleration": list(lim.acceleration),
        # the jerk a trajectory that reports one (ruckig's) keeps when none is asked
        "jerk": list(lim.with_ruckig_jerk().jerk),
    }
    assert DEFAULT_MAX_DEVIATION == LIBRARY_MAX_DEVIATION


@pytest.mark.parametrize(
    "design",
    [Design.default(), Design.paper_optimum(), Design(0.3, 0.25, 0.4)],
    ids=["default", "paper", "other"],
)
def test_kinematics_agree_with_the_library(design):
    """Points, serial measures, working modes and kappa(A) of the checker's own formulas
    against planner.kinematics, in both assembly modes."""
    wire = {"L0": design.L0, "L1": design.L1, "L2": design.L2}
    q = np.random.default_rng(4).uniform(-math.pi, math.pi, (3000, 3))
    for branch, asm in ((1, "+"), (-1, "-")):
        mine = postures(wire, q, branch)
        ref = forward_batch(design, q, asm)
        np.testing.assert_array_equal(mine.ok, ref.ok)
        ok = ref.ok
        np.testing.assert_allclose(mine.points["P"][ok], ref.p[ok], atol=1e-12)
        pts = link_points(design, ref.q, ref.passive)
        for k, name in enumerate("ABCDP"):
            np.testing.assert_allclose(mine.points[name][ok], pts[ok, k], atol=1e-12)
        np.testing.assert_allclose(mine.measures[ok], ref.serial_measures[ok], atol=1e-12)
        kappa = conditioning(design, ref.q, ref.passive, ref.w).kappa_A
        finite = ok & (kappa < 1e6)
        np.testing.assert_allclose(mine.kappa[finite], kappa[finite], rtol=1e-8)
        assert np.all(np.sign(mine.assembly[ok]) == branch)
        regular = ok & np.all(np.abs(ref.serial_measures) > 1e-6, axis=1)
        for i in np.flatnonzero(regular)[:200]:
            signs = np.sign(mine.measures[i]).astype(int)
            assert mode_label(signs) == mode_label(ref.working_mode_signs[i])


def test_clearance_is_the_minimum_over_densely_sampled_links():
    """The golden-section distance is never above a 0.2 mm sampling of every link (it is the
    minimum) and at most the sampling's own error below it."""
    design = Design.default()
    wire = {"L0": design.L0, "L1": design.L1, "L2": design.L2}
    obstacles = [
        (Sphere([0.3, 0.1, -0.2], 0.15), {"type": "sphere", "center": [0.3, 0.1, -0.2],
                                          "radius": 0.15}),
        (Capsule([-0.4, -0.3, 0.2], [0.5, 0.4, 0.1], 0.05),
         {"type": "capsule", "a": [-0.4, -0.3, 0.2], "b": [0.5, 0.4, 0.1], "radius": 0.05}),
        (Box([0.1, 0.2, 0.4], [0.3, 0.2, 0.5], [0.9, 0.1, -0.3, 0.2]),
         {"type": "box", "center": [0.1, 0.2, 0.4], "size": [0.3, 0.2, 0.5],
          "quaternion": [0.9, 0.1, -0.3, 0.2]}),
    ]  # fmt: skip
    q = np.random.default_rng(8).uniform(-math.pi, math.pi, (300, 3))
    post = postures(wire, q, 1)
    q = q[post.ok]
    post = postures(wire, q, 1)
    ref = forward_batch(design, q, "+")
    pts = link_points(design, ref.q, ref.passive)
    s = np.linspace(0.0, 1.0, 4001)  # links are at most 0.6 m: 0.15 mm apart
    for lib_ob, wire_ob in obstacles:
        exact = clearance(post, [wire_ob], 0.0)
        sampled = np.full(len(q), np.inf)
        for i, j in ((0, 2), (1, 3), (2, 4), (3, 4)):
            x = pts[:, i, None, :] + s[None, :, None] * (pts[:, j] - pts[:, i])[:, None, :]
            d = point_distance(x.reshape(-1, 3), lib_ob).reshape(len(q), -1).min(axis=1)
            sampled = np.minimum(sampled, d)
        assert np.all(exact <= sampled + 1e-12)
        assert np.all(sampled - exact <= 1.6e-4)
        assert (exact < 0).any() and (exact > 0).any()  # both sides of the surface are tried


@pytest.mark.parametrize("name", list(SCENES))
def test_real_plans_pass(plans, name):
    request, response = plans[name]
    report = check_plan(request, response)
    assert report.ok, report
    assert report.postures_checked > 100
    if name.startswith("mode_change"):
        (transit,) = response["path"]["transits"]
        at = postures(DEFAULT_DESIGN, np.array([transit["q"]]), 1)
        assert abs(at.measures[0, 1]) < 1e-6  # the leg-A measure vanishes there (exempt) ...
        assert report.worst["serial"] >= 0.05  # ... and every other measure keeps the margin
    if name == "obstacles":
        assert report.worst["clearance"] >= 0.01


def test_unsolved_answers_are_not_checked():
    report = check_plan({"start": START, "goal": START}, {"status": "no_path", "path": None})
    assert not report.checked and not report.ok
    report = check_plan(
        {"start": START, "goal": START},
        {"status": "no_path", "path": {"waypoints": [[0, 0, 0]] * 2}},
    )
    assert report.checked and "carries a path" in str(report)


# ----------------------------------------------------------------- tampered answers
def _straight_line_collision():
    """A posture on the straight START -> obstacle-goal motion with a link inside the
    sphere, found with the library's kinematics and point distances (not the checker)."""
    design = Design.default()
    a, b = np.array(START["q"]), np.array(SCENES["obstacles"]["goal"]["q"])
    q = a + (b - a) * np.linspace(0, 1, 201)[:, None]
    fb = forward_batch(design, q, "+")
    pts = link_points(design, fb.q, fb.passive)
    s = np.linspace(0, 1, 201)
    sphere = Sphere(SPHERE["center"], SPHERE["radius"])
    worst = np.full(len(q), np.inf)
    for i, j in ((0, 2), (1, 3), (2, 4), (3, 4)):
        x = pts[:, i, None, :] + s[None, :, None] * (pts[:, j] - pts[:, i])[:, None, :]
        d = point_distance(x.reshape(-1, 3), sphere).reshape(len(q), -1).min(axis=1)
        worst = np.minimum(worst, d)
    k = int(np.argmin(worst))
    assert worst[k] < -0.02  # deep inside
    return q[k].tolist()


def _into_obstacle(req, resp):
    resp["path"]["waypoints"][1] = _straight_line_collision()


def _beyond_kappa(req, resp):
    design = Design.default()
    q_bad = np.array([0.2, 0.05, math.pi - 0.05])  # C and D 0.1 m apart: kappa(A) ~ 12
    fb = forward_batch(design, q_bad, "+")
    assert conditioning(design, fb.q, fb.passive, fb.w).kappa_A[0] > 11
    assert mode_label(fb.working_mode_signs[0]) == "++-"  # the plan's own mode
    w = resp["path"]["waypoints"]
    resp["path"]["waypoints"] = [w[0], q_bad.tolist(), *w[1:]]
    resp["path"]["segments"][0]["end_index"] += 1
    resp["trajectory"] = None


def _transit_folded(req, resp):
    assert resp["path"]["transits"][0]["kind"] == "leg_A_stretched"
    resp["path"]["transits"][0]["kind"] = "leg_A_folded"


def _transit_other_leg(req, resp):
    resp["path"]["transits"][0]["kind"] = "leg_B_stretched"


def _transit_flipped_wrong(req, resp):
    resp["path"]["transits"][0]["flipped"] = "B"


def _theta1_full_turn(req, resp):
    # the same posture, literally a full turn further: outside the +-pi limits
    resp["path"]["waypoints"][1][0] += 2 * math.pi


def _limit_narrowed(req, resp):
    # the same path, but the request's robot stops theta1 short of a waypoint
    q1 = max(w[0] for w in resp["path"]["waypoints"])
    req["design"] = {"joint_min": [-math.pi] * 3, "joint_max": [q1 - 1e-3, math.pi, math.pi]}


def _mode_mislabelled(req, resp):
    assert resp["path"]["segments"][0]["working_mode"] == "+-+"
    resp["path"]["segments"][0]["working_mode"] = "+++"


def _mode_change_mislabelled(req, resp):
    # both segments say +++: no sign flips at the transit
    resp["path"]["segments"][0]["working_mode"] = resp["path"]["segments"][1]["working_mode"]


def _segments_not_meeting(req, resp):
    resp["path"]["segments"][1]["start_index"] += 1


def _start_moved(req, resp):
    resp["path"]["waypoints"][0][2] += 1e-6


def _cartesian_goal_missed(req, resp):
    resp["path"]["waypoints"][-1][1] += 1e-3
    resp["trajectory"] = None


def _qd_scaled(req, resp):
    resp["trajectory"]["qd"] = [[1.3 * v for v in row] for row in resp["trajectory"]["qd"]]


def _time_reversed(req, resp):
    t = resp["trajectory"]["t"]
    t[3], t[4] = t[4], t[3]


def _trajectory_sample_into_obstacle(req, resp):
    q = resp["trajectory"]["q"]
    k = len(q) // 2
    q[k] = _straight_line_collision()


MUTATIONS = [
    ("obstacles", _into_obstacle, "link clearance falls to"),
    ("high_kappa_mode", _beyond_kappa, "kappa(A) reaches"),
    ("mode_change", _transit_folded, "is leg_A_folded but leg A is stretched"),
    ("mode_change", _transit_other_leg, "kind leg_B_stretched does not flip 'A'"),
    ("mode_change", _transit_flipped_wrong, "does not flip exactly the 'B' sign"),
    ("obstacles", _theta1_full_turn, "leaves the joint limits"),
    ("free", _limit_narrowed, "leaves the joint limits"),
    ("obstacles", _mode_mislabelled, "< serial_min 0.05 for working mode +++"),
    ("mode_change", _mode_change_mislabelled, "does not flip exactly"),
    ("mode_change", _segments_not_meeting, "is not where segment 0 ends"),
    ("free", _start_moved, "is not the start"),
    ("cartesian", _cartesian_goal_missed, "from the Cartesian goal"),
    ("ruckig", _qd_scaled, "q and qd disagree"),
    ("free", _time_reversed, "time axis does not increase"),
    ("obstacles", _trajectory_sample_into_obstacle, "trajectory: link clearance falls to"),
]


@pytest.mark.parametrize(
    ("scene", "mutate", "expected"), MUTATIONS, ids=[m[1].__name__.strip("_") for m in MUTATIONS]
)
def test_tampered_answers_are_rejected(plans, scene, mutate, expected):
    request, response = copy.deepcopy(plans[scene])
    assert check_plan(request, response).ok  # the untouched plan passes
    mutate(request, response)
    report = check_plan(request, response)
    assert report.checked and not report.ok
    assert expected in str(report), report
