"""What a new user meets at the API: a static gravity query without qd/qdd and with one
posture, a partial inertia completed from the defaults, an unreachable goal's reason said
once, and a solved timing that says what it did."""

from __future__ import annotations

import math

import numpy as np

from planner import Design
from planner.dynamics import Inertia, inverse_dynamics
from planner.dynamics.inertia import ALUMINIUM_DENSITY, DEFAULT_TUBE_RADIUS, tube_inertia

START = {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"}


def test_dynamics_static_query_of_one_posture(api):
    """``{"q": [0, 2, 1]}`` alone: the torques that hold the posture against gravity (one row),
    equal to the library's with zero rates and to the N x 3 form with explicit zeros."""
    single = api.post("/v1/dynamics", json={"q": [0, 2, 1]})
    assert single.status_code == 200, single.text
    body = single.json()
    assert np.shape(body["tau"]) == (1, 3) and np.shape(body["mass_matrix"]) == (1, 3, 3)
    zeros = {"q": [[0, 2, 1]], "qd": [[0, 0, 0]], "qdd": [[0, 0, 0]]}
    assert api.post("/v1/dynamics", json=zeros).json()["tau"] == body["tau"]
    design = Design.default()
    ref = inverse_dynamics(
        design, Inertia.default(design), np.array([0, 2.0, 1.0]), np.zeros(3), np.zeros(3)
    ).tau[0]
    np.testing.assert_allclose(body["tau"][0], ref, rtol=1e-12, atol=1e-12)
    # N postures without rates: one row each
    two = api.post("/v1/dynamics", json={"q": [[0, 2, 1], [0.4, 2.2, 1.1]]}).json()
    assert np.shape(two["tau"]) == (2, 3) and two["tau"][0] == body["tau"][0]
    # a short posture is still a 422 naming q
    bad = api.post("/v1/dynamics", json={"q": [0, 2]})
    assert bad.status_code == 422 and bad.json()["detail"][0]["loc"] == ["body", "q"]
    assert (
        "one posture is 3 numbers (theta1, theta2, theta3), got 2" in bad.json()["detail"][0]["msg"]
    )


def test_partial_inertia_takes_the_rest_from_the_defaults(api):
    """``proximal.mass`` alone is the default tube made of a material of that mass (its
    moments scale with it; built here as a denser tube), the other parts the defaults."""
    design = Design.default()
    default = Inertia.default(design)
    radius = design.link_radius or DEFAULT_TUBE_RADIUS
    density = ALUMINIUM_DENSITY * 0.9 / default.proximal.mass
    proximal = tube_inertia(design.L1, radius, "proximal", density=density)
    inertia = Inertia(
        proximal, default.distal, default.payload_mass, default.base_inertia, default.rotor
    )
    q, qd, qdd = [0.3, 2.1, 0.9], [0.4, -0.3, 0.2], [1.0, -2.0, 0.5]
    body = {"q": [q], "qd": [qd], "qdd": [qdd], "design": {"inertia": {"proximal": {"mass": 0.9}}}}
    r = api.post("/v1/dynamics", json=body)
    assert r.status_code == 200, r.text
    ref = inverse_dynamics(design, inertia, np.array(q), np.array(qd), np.array(qdd)).tau[0]
    np.testing.assert_allclose(r.json()["tau"][0], ref, rtol=1e-9, atol=1e-12)
    default_tau = api.post("/v1/dynamics", json={"q": [q], "qd": [qd], "qdd": [qdd]}).json()
    assert not np.allclose(default_tau["tau"][0], ref)
    # com alone moves the centre of mass only; a bad one is still named
    r = api.post("/v1/dynamics", json={"q": q, "design": {"inertia": {"distal": {"com": 0.8}}}})
    assert r.status_code == 200, r.text
    bad = {"q": q, "design": {"inertia": {"distal": {"I_perp": 0.001, "I_axial": 0.01}}}}
    r = api.post("/v1/dynamics", json=bad)
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"][:5] == ["body", "design", "inertia", "distal", "I_axial"]


def test_unreachable_goal_says_its_reason_once(api):
    d = Design.default()
    for mode in ("any", "+-+"):
        goal = {"p": [2.0, 0.0, 0.0], "working_mode": mode}
        answer = api.post("/v1/plan", json={"start": START, "goal": goal}).json()
        assert answer["status"] == "unreachable"
        r = math.dist((2, 0, 0), (0, -d.L0 / 2, 0))
        assert answer["message"] == (
            "the goal point is unreachable in every working mode: P is out of reach of leg A "
            f"(|AP| = {r:.6g} m > L1 + L2 = {d.L1 + d.L2:.6g} m) and of leg B (|BP| = "
            f"{r:.6g} m > L1 + L2 = {d.L1 + d.L2:.6g} m)"
        )
        assert answer["message"].count("working mode") == 1


def test_solved_timing_says_what_it_did(api):
    body = {"waypoints": [[0, 2, 1], [0.3, 2.1, 1.2], [0.5, 2.0, 1.0]]}
    answer = api.post("/v1/timing", json=body).json()
    assert answer["status"] == "solved"
    traj = answer["trajectory"]
    assert answer["message"] == (
        f"timed with toppra: 3 waypoints in {traj['duration']:.6g} s, {len(traj['t'])} samples"
    )
    limited = api.post("/v1/timing", json={**body, "limits": {"torque": [30, 30, 30]}}).json()
    ratio = limited["diagnostics"]["max_torque_ratio"]
    assert limited["message"].endswith(f", max |tau|/limit {ratio:.4g}")
