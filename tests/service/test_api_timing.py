"""POST /v1/timing: a client-supplied joint path timed and checked.

Checked against independent routes: the closed-form trapezoidal duration of a straight
rest-to-rest move, finite differences of the returned q, /v1/fk for P, and the limits.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

PATH = [[0.0, 0.5, 1.0], [0.4, 0.9, 1.2], [0.8, 0.6, 1.5]]
#: Mode-change design: the straight segment between these waypoints leaves the region where
#: the loop closes (|CD| > 2 L2 in the middle) although both waypoints assemble.
OPEN_DESIGN = {"L0": 0.6, "L1": 0.25, "L2": 0.45}
OPEN_PATH = [[0.0, 1.6, -0.82], [0.0, 1.73, 0.68]]


def _timing(api, **body):
    r = api.post("/v1/timing", json=body)
    assert r.status_code == 200, r.text
    return r.json()


def _trapezoid_duration(distance: float, v: float, a: float) -> float:
    """Time-optimal rest-to-rest duration over ``distance`` with |speed| <= v, |acc| <= a."""
    if distance >= v * v / a:
        return distance / v + v / a
    return 2.0 * math.sqrt(distance / a)


@pytest.mark.parametrize(("delta", "v", "a"), [([0.6, -0.3, 0.2], 2.0, 8.0),
                                                ([0.05, 0.02, 0.0], 1.0, 3.0)])  # fmt: skip
def test_straight_move_takes_the_closed_form_time(api, delta, v, a):
    q0 = np.array([0.1, 0.8, 1.6])
    q1 = q0 + delta
    out = _timing(
        api,
        waypoints=[q0.tolist(), q1.tolist()],
        limits={"velocity": [v] * 3, "acceleration": [a] * 3},
    )
    assert out["status"] == "solved"
    # along a straight line the joint with the largest travel binds: scale to path length
    d = np.abs(np.array(delta))
    length = float(np.linalg.norm(delta))
    v_path = min(v * length / x for x in d if x > 0)
    a_path = min(a * length / x for x in d if x > 0)
    expected = _trapezoid_duration(length, v_path, a_path)
    # never faster than the optimum; the library keeps a 0.1 % margin on the limits
    assert expected * (1 - 1e-9) <= out["trajectory"]["duration"] <= expected * 1.002
    # no jerk asked (absent): toppra is not jerk-limited (issue 39: no default filled in)
    assert out["trajectory"]["jerk"] is None


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_trajectory_holds_limits_and_is_consistent(api, method):
    limits = {"velocity": [1.5, 2.0, 2.5], "acceleration": [6.0, 8.0, 10.0],
              "jerk": [150.0, 200.0, 250.0]}  # fmt: skip
    out = _timing(api, waypoints=PATH, method=method, limits=limits, sample_rate_hz=500)
    assert out["status"] == "solved", out["message"]
    tr = out["trajectory"]
    assert tr["method"] == method
    t, q, qd, qdd = (np.array(tr[k]) for k in ("t", "q", "qd", "qdd"))
    assert t[0] == 0.0 and t[-1] == pytest.approx(tr["duration"])
    assert np.allclose(q[0], PATH[0], atol=1e-12) and np.allclose(q[-1], PATH[-1], atol=1e-9)
    assert np.allclose(qd[[0, -1]], 0.0, atol=1e-9)
    tol = 1 + 1e-6
    assert np.all(np.abs(qd) <= np.array(limits["velocity"]) * tol)
    assert np.all(np.abs(qdd) <= np.array(limits["acceleration"]) * tol)
    # the jerk asked holds with both methods, also by finite differences of qdd
    assert np.all(np.abs(np.array(tr["jerk"])) <= np.array(limits["jerk"]) * tol)
    fd_jerk = np.abs(np.diff(qdd, axis=0) / np.diff(t)[:, None])
    assert np.all(fd_jerk <= np.array(limits["jerk"]) * tol)
    # qd is the derivative of q: central differences at 500 Hz
    fd = (q[2:] - q[:-2]) / (t[2:] - t[:-2])[:, None]
    assert np.max(np.abs(fd - qd[1:-1])) < 0.05
    # P is the forward kinematics of q (through the /v1/fk endpoint), in assembly mode '+'
    for k in np.linspace(0, len(t) - 1, 5).astype(int):
        fk = api.post("/v1/fk", json={"q": q[k].tolist(), "assembly_mode": "+"}).json()
        assert np.allclose(fk["postures"][0]["p"], tr["p"][k], atol=1e-9)
    assert tr["max_deviation_q"] <= 0.05 + 1e-9
    assert out["diagnostics"]["timing_time_s"] > 0


def test_stop_at_rests_on_the_waypoint(api):
    out = _timing(api, waypoints=PATH, stop_at=[1], sample_rate_hz=1000)
    tr = out["trajectory"]
    q, qd = np.array(tr["q"]), np.array(tr["qd"])
    k = int(np.argmin(np.linalg.norm(q - PATH[1], axis=1)))
    assert np.linalg.norm(q[k] - PATH[1]) < 2e-3 and np.linalg.norm(qd[k]) < 0.1


def test_a_segment_leaving_the_assembly_region_is_invalid_path(api):
    out = _timing(api, design=OPEN_DESIGN, waypoints=OPEN_PATH)
    assert out["status"] == "invalid_path" and out["trajectory"] is None
    err = out["diagnostics"]["timing_error"]
    assert err["type"] == "TrajectoryCheckError" and err["q"] is not None


def test_validity_rules_apply_margins_and_obstacles(api):
    ok = _timing(api, waypoints=PATH, margins={"kappa_max": 50, "serial_min": 0.01})
    assert ok["status"] == "solved", ok["message"]
    # a sphere around P of the middle waypoint (P from /v1/fk): that waypoint is named
    p_mid = api.post("/v1/fk", json={"q": PATH[1], "assembly_mode": "+"}).json()["postures"][0]
    sphere = {"type": "sphere", "center": p_mid["p"], "radius": 0.05}
    out = _timing(api, waypoints=PATH, obstacles=[sphere])
    assert out["status"] == "invalid_path" and "waypoints[1]" in out["message"]
    assert out["diagnostics"]["timing_error"]["index"] == 1
    # a sphere on the straight segment between two waypoints, clear of both: the dense
    # re-check finds it (the blend may cut the corner, so use a two-waypoint path)
    mid_q = (np.array(PATH[0]) + np.array(PATH[1])) / 2
    p_seg = api.post("/v1/fk", json={"q": mid_q.tolist(), "assembly_mode": "+"}).json()
    sphere = {"type": "sphere", "center": p_seg["postures"][0]["p"], "radius": 0.01}
    out = _timing(api, waypoints=PATH[:2], obstacles=[sphere])
    assert out["status"] == "invalid_path"
    assert out["diagnostics"]["timing_error"]["type"] == "TrajectoryCheckError"
    # a margin the path cannot meet anywhere
    tight = _timing(api, waypoints=PATH, margins={"serial_min": 0.99})
    assert tight["status"] == "invalid_path" and "waypoints[0]" in tight["message"]


def test_bad_validity_fields_are_422(api):
    for change, loc in [
        ({"margins": {"kappa_max": 1.0}}, ["body", "margins", "kappa_max"]),
        (
            {"obstacles": [{"type": "sphere", "center": [0, 0, 0], "radius": -1}]},
            ["body", "obstacles", 0, "sphere", "radius"],
        ),
        ({"working_mode": "+x+"}, ["body", "working_mode"]),
    ]:
        r = api.post("/v1/timing", json={"waypoints": PATH, **change})
        assert r.status_code == 422, r.text
        assert loc in [item["loc"] for item in r.json()["detail"]], r.text


@pytest.mark.parametrize(
    ("change", "loc"),
    [
        ({"limits": {"velocity": [1, 0, 1]}}, ["body", "limits", "velocity", 1]),
        ({"limits": {"velocity": [1e-300, 1, 1]}}, ["body", "limits", "velocity", 0]),
        ({"limits": {"cartesian_speed": 1e-200}}, ["body", "limits", "cartesian_speed"]),
        ({"limits": {"velocity": [1, 1]}}, ["body", "limits", "velocity"]),
        ({"limits": {"acceleration": [1, -2, 1]}}, ["body", "limits", "acceleration", 1]),
        ({"limits": {"jerk": [1, 1, "NaN"]}}, ["body", "limits", "jerk", 2]),
        ({"limits": {"cartesian_speed": 0}}, ["body", "limits", "cartesian_speed"]),
        ({"limits": {"speed": [1, 1, 1]}}, ["body", "limits", "speed"]),
        ({"method": "bang-bang"}, ["body", "method"]),
        ({"sample_rate_hz": 0}, ["body", "sample_rate_hz"]),
        ({"sample_rate_hz": 1e9}, ["body", "sample_rate_hz"]),
        ({"assembly_mode": "x"}, ["body", "assembly_mode"]),
        ({"waypoints": [[0, 1, 2]]}, ["body", "waypoints"]),
        ({"waypoints": [[0, 1, 2], [0, 1]]}, ["body", "waypoints", 1]),
        ({"waypoints": [[0, 1, 2], [0, 1, "Infinity"]]}, ["body", "waypoints", 1, 2]),
        ({"waypoints": [[0, 1, 2], [0, 1, 3.3]]}, ["body", "waypoints", 1, 2]),  # beyond +-pi
        ({"stop_at": [3]}, ["body", "stop_at"]),
        ({"stop_at": [-1]}, ["body", "stop_at", 0]),
        ({"max_deviation": -0.1}, ["body", "max_deviation"]),
        ({"design": {"L2": 0}}, ["body", "design", "L2"]),
        ({"trajectory": []}, ["body", "trajectory"]),
    ],
)
def test_bad_timing_requests_are_422_naming_the_field(api, change, loc):
    r = api.post("/v1/timing", json={"waypoints": PATH, **change})
    assert r.status_code == 422, r.text
    assert loc in [item["loc"] for item in r.json()["detail"]]


def test_waypoint_that_does_not_assemble_is_named(api):
    # paper optimum (L0 = 0, L1 = L2): theta2 = theta3 puts C on D, no assembly
    body = {"design": {"L0": 0.0, "L1": 0.4, "L2": 0.4},
            "waypoints": [[0.0, 0.5, 1.5], [0.0, 0.9, 0.9]]}  # fmt: skip
    r = api.post("/v1/timing", json=body)
    assert r.status_code == 422
    (item,) = r.json()["detail"]
    assert item["loc"] == ["body", "waypoints", 1] and item["type"] == "assembly_error"


def test_too_many_samples_is_422_naming_the_rate(api):
    # a slow move at a high rate: more output samples than the library allows
    body = {
        "waypoints": [[0, 0.5, 1.0], [3.0, 0.5, 1.0]],
        "sample_rate_hz": 10_000,
        "limits": {"velocity": [0.001] * 3},
    }
    r = api.post("/v1/timing", json=body)
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "sample_rate_hz"]


def test_first_waypoint_on_a_serial_singularity_names_the_waypoint(api):
    """Leg A stretched (|AP| = L1 + L2, built from the conventions' formulas): the working mode
    to check against is undetermined, and the 422 names waypoints[0], not working_mode."""
    l0, l1, l2 = 0.5, 0.2, 0.6
    t2 = 1.2  # C and P on the ray from A at angle t2
    pu, pw = -l0 / 2 + (l1 + l2) * math.cos(t2), (l1 + l2) * math.sin(t2)
    du = pu - l0 / 2
    dist_b = math.hypot(du, pw)  # leg B reaches P: |BP| between L2 - L1 and L1 + L2
    assert l2 - l1 < dist_b < l1 + l2
    phi = math.atan2(pw, du)
    alpha = math.acos((l1**2 + dist_b**2 - l2**2) / (2 * l1 * dist_b))
    t3 = phi + alpha
    q0 = [0.0, t2, t3]
    assembly = (
        "+"
        if math.sin(math.atan2(pw - l1 * math.sin(t3), pu - l0 / 2 - l1 * math.cos(t3)) - t2) > 0
        else "-"
    )
    r = api.post(
        "/v1/timing",
        json={
            "waypoints": [q0, [0.1, t2 - 0.1, t3]],
            "assembly_mode": assembly,
            "margins": {"kappa_max": 100},
        },
    )
    assert r.status_code == 422, r.text
    assert ["body", "waypoints", 0] in [d["loc"] for d in r.json()["detail"]], r.text
    assert "serial singularity" in r.text
