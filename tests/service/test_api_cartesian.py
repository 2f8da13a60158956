"""``POST /v1/cartesian`` over HTTP, held to independent routes: the tool point's deviation
from the polyline by the test's own kinematics (:mod:`plan_checker`, numpy only) over a dense
resampling of the timed trajectory; the stopping point of lines into a serial singularity, a
parallel one, an obstacle and out of the workspace against closed forms and the checker's
own kappa(A) and clearance; every rule of a plan re-checked on the path and trajectory
(:func:`plan_checker.check_plan`); the bad values of every field answered 422 by name."""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest
from plan_checker import (
    DEFAULT_DESIGN,
    DEFAULT_LIMITS,
    DEFAULT_MARGINS,
    check_plan,
    clearance,
    postures,
)

#: A start of the default robot from which P moves freely about (P ~ (0.45, 0, 0.1)).
START = {"q": [-0.2187, 2.8609, 0.2807], "assembly_mode": "+"}
#: The design of the parallel-singularity case: |CD| = 2 L2 is reachable (L0 < 2 (L2 - L1)).
PARALLEL_DESIGN = {"L0": 0.6, "L1": 0.25, "L2": 0.45}
#: Where the stopping point may sit from the exact crossing, m (bisection 1e-8 m plus the
#: pull-back that certifies the last motion).
STOP_TOL = 2e-5


def _design(request: dict) -> dict:
    return {**DEFAULT_DESIGN, **(request.get("design") or {})}


def _p_of(request: dict, q) -> np.ndarray:
    """P of joint vectors (N, 3), by the checker's own direct kinematics."""
    branch = 1 if request["start"]["assembly_mode"] == "+" else -1
    return postures(_design(request), np.atleast_2d(np.asarray(q, float)), branch).points["P"]


def _vertices(request: dict) -> np.ndarray:
    return np.vstack([_p_of(request, request["start"]["q"]), request["waypoints"]])


def _distance_to_polyline(vertices: np.ndarray, points: np.ndarray) -> np.ndarray:
    best = np.full(len(points), np.inf)
    for a, b in pairwise(vertices):
        ab = b - a
        t = np.clip((points - a) @ ab / max(float(ab @ ab), 1e-300), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(points - (a + t[:, None] * ab), axis=1))
    return best


def _arc_length(vertices: np.ndarray, p: np.ndarray) -> float:
    """Arc length along the polyline of a point on it (the nearest segment's)."""
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(vertices, axis=0), axis=1))])
    d = _distance_to_polyline(vertices[:2], p[None])
    k = 0
    for i, (a, b) in enumerate(pairwise(vertices)):
        dk = _distance_to_polyline(np.array([a, b]), p[None])
        if dk <= d:
            d, k = dk, i
    return float(cum[k] + np.linalg.norm(p - vertices[k]))


def _resampled(traj: dict, factor: int = 4) -> np.ndarray:
    """The trajectory's joints linearly interpolated ``factor`` times between samples (the
    chord of a sample interval h strays at most amax h^2 / 8 from the motion)."""
    q = np.asarray(traj["q"], float)
    s = np.linspace(0.0, 1.0, factor, endpoint=False)
    dense = (q[:-1, None, :] + s[None, :, None] * (q[1:] - q[:-1])[:, None, :]).reshape(-1, 3)
    return np.vstack([dense, q[-1:]])


def _checked_as_plan(request: dict, answer: dict) -> None:
    """Every rule of a plan, re-checked by the checker on the path and its trajectory: the
    path is posed as a plan to the point where it ends, in the start's working mode."""
    limits = {
        "velocity": [
            v * (request.get("limits") or {}).get("velocity_scaling", 1.0)
            for v in DEFAULT_LIMITS["velocity"]
        ],
        "acceleration": [
            a * (request.get("limits") or {}).get("acceleration_scaling", 1.0)
            for a in DEFAULT_LIMITS["acceleration"]
        ],
    }
    end = _p_of(request, answer["path"]["waypoints"][-1])[0]
    posed = {
        **{k: request[k] for k in ("design", "margins", "obstacles") if k in request},
        "start": request["start"],
        "goal": {"p": end.tolist(), "working_mode": answer["working_mode"]},
        "limits": limits,
    }
    report = check_plan(posed, {**answer, "status": "solved"})
    assert report.ok, str(report)


def _post(api, body: dict) -> dict:
    r = api.post("/v1/cartesian", json=body)
    assert r.status_code == 200, r.text
    return r.json()


# ---------------------------------------------------------------------------- deviation
@pytest.mark.parametrize("tolerance", [1e-3, 2e-4])
def test_timed_trajectory_keeps_p_within_the_path_tolerance(api, tolerance):
    body = {
        "start": START,
        "waypoints": [[0.45, 0.3, 0.1], [0.4, 0.25, -0.05]],
        "path_tolerance": tolerance,
        "timing": {"method": "toppra", "sample_rate_hz": 1000},
        "limits": {"cartesian_speed": 0.25},
    }
    answer = _post(api, body)
    assert answer["status"] == "solved" and answer["fraction"] == 1.0, answer["message"]
    assert answer["stop"] is None
    vertices = _vertices(body)
    p = _p_of(body, _resampled(answer["trajectory"]))
    deviation = _distance_to_polyline(vertices, p)
    assert float(deviation.max()) <= tolerance
    # the service's own measure is of the same trajectory, on fewer instants
    assert answer["diagnostics"]["max_path_deviation"] <= float(deviation.max()) + 1e-6
    # P goes the whole way: from the start's P to the last waypoint, passing each waypoint
    assert np.linalg.norm(p[-1] - vertices[-1]) < 1e-6
    assert float(np.min(np.linalg.norm(p - vertices[1], axis=1))) <= tolerance
    # one working mode all along, and every rule of a plan holds
    segments = answer["path"]["segments"]
    assert len(segments) == 1 and segments[0]["working_mode"] == answer["working_mode"]
    _checked_as_plan(body, answer)


def test_tool_speed_is_held_where_the_joint_limits_allow(api):
    body = {"start": START, "waypoints": [[0.45, 0.3, 0.1]], "limits": {"cartesian_speed": 0.2}}
    traj = _post(api, body)["trajectory"]
    t, p = np.asarray(traj["t"]), _p_of(body, traj["q"])
    speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / np.diff(t)
    assert float(speed.max()) <= 0.2 * (1 + 1e-3)
    # the cruise of a 0.3 m line at 0.2 m/s: the duration is at least 0.3 / 0.2 s
    assert traj["duration"] >= 0.3 / 0.2


# ---------------------------------------------------------------------------- stopping
def _line_sphere(p0: np.ndarray, p1: np.ndarray, centre: np.ndarray, radius: float) -> float:
    """Arc length from p0 along the segment p0 -> p1 where |P - centre| = radius (the first
    crossing), from the quadratic."""
    d = (p1 - p0) / np.linalg.norm(p1 - p0)
    f = p0 - centre
    b, c = float(f @ d), float(f @ f) - radius**2
    roots = [-b - math.sqrt(b * b - c), -b + math.sqrt(b * b - c)]
    return min(r for r in roots if r > 0)


def _stopped(api, body: dict, rule: str) -> tuple[dict, np.ndarray, float]:
    """The answer of a line that stops short: ``no_path`` with ``fraction`` < 1, the rule
    named in ``stop`` and ``message``, the path ending on the polyline at the stopping point
    (own kinematics) at the share ``fraction`` of its length, every rule held up to there.
    Returns the answer, the end's P and its arc length."""
    answer = _post(api, body)
    assert answer["status"] == "no_path", answer["message"]
    stop = answer["stop"]
    assert stop["rule"] == rule, answer["message"]
    assert 0.0 < answer["fraction"] < 1.0 and stop["fraction"] == answer["fraction"]
    assert rule in answer["message"] and "% along the path" in answer["message"]
    vertices = _vertices(body)
    end = _p_of(body, answer["path"]["waypoints"][-1])[0]
    assert np.linalg.norm(end - np.asarray(stop["p"])) < 1e-6
    assert float(_distance_to_polyline(vertices, end[None])[0]) < 1e-6
    s_end = _arc_length(vertices, end)
    length = float(np.sum(np.linalg.norm(np.diff(vertices, axis=0), axis=1)))
    assert s_end / length == pytest.approx(answer["fraction"], abs=1e-9)
    _checked_as_plan(body, answer)
    # the timed part ends on the stopping point, at rest
    assert np.linalg.norm(_p_of(body, answer["trajectory"]["q"][-1])[0] - end) < 1e-9
    return answer, end, s_end


def test_a_line_into_a_serial_singularity_stops_at_the_serial_margin(api):
    # P towards A: leg A folds where |AP| = L2 - L1; the margin serial_min = 0.05 of
    # |sin(theta4 - theta2)| is the sphere |AP|^2 = L1^2 + L2^2 - 2 L1 L2 sqrt(1 - 0.05^2)
    d = DEFAULT_DESIGN
    a = np.array([0.0, -d["L0"] / 2, 0.0])
    design = {"joint_min": [-2 * math.pi] * 3, "joint_max": [2 * math.pi] * 3}
    body = {"design": design, "start": START}
    p0 = _p_of(body, START["q"])[0]
    target = a + 0.1 * (p0 - a) / np.linalg.norm(p0 - a)
    body["waypoints"] = [target.tolist()]
    answer, _, s_end = _stopped(api, body, "serial_min")
    smin = DEFAULT_MARGINS["serial_min"]
    radius = math.sqrt(d["L1"] ** 2 + d["L2"] ** 2 - 2 * d["L1"] * d["L2"] * math.sqrt(1 - smin**2))
    assert s_end == pytest.approx(_line_sphere(p0, target, a, radius), abs=STOP_TOL)
    assert answer["stop"]["value"] == pytest.approx(smin, abs=1e-6)
    post = postures(_design(body), np.array([answer["path"]["waypoints"][-1]]), 1)
    # own measure: on the valid side, close to the margin (it grows like the square root of
    # the distance to the fold, so the pull-back of the last motion shows here)
    assert smin <= abs(post.measures[0, 1]) <= smin + 5e-4


def test_a_line_out_of_the_workspace_stops_where_the_leg_is_stretched(api):
    # |AP| <= L1 + L2: with a tiny serial margin the line stops on the sphere of that radius
    d = DEFAULT_DESIGN
    a = np.array([0.0, -d["L0"] / 2, 0.0])
    body = {"start": START, "waypoints": [[1.2, 0.3, 0.1]], "margins": {"serial_min": 1e-4}}
    p0 = _p_of(body, START["q"])[0]
    answer, end, s_end = _stopped(api, body, "workspace")
    radius = d["L1"] + d["L2"]
    assert s_end == pytest.approx(
        _line_sphere(p0, np.array([1.2, 0.3, 0.1]), a, radius), abs=STOP_TOL
    )
    assert np.linalg.norm(end - a) == pytest.approx(radius, abs=STOP_TOL)
    assert "out of reach" in answer["message"]


def test_a_line_into_a_parallel_singularity_stops_at_kappa_max(api):
    body = {
        "design": PARALLEL_DESIGN,
        "start": {"q": [0.3, 2.0, 1.1], "assembly_mode": "+"},
        "timing": {"method": "toppra"},
    }
    p0 = _p_of(body, body["start"]["q"])[0]
    body["waypoints"] = [[0.3 * p0[0], p0[1], 0.3 * p0[2]]]  # towards the axis: |CD| -> 2 L2
    answer, _, _ = _stopped(api, body, "kappa_max")
    kappa = postures(_design(body), np.array([answer["path"]["waypoints"][-1]]), 1).kappa[0]
    kmax = DEFAULT_MARGINS["kappa_max"]
    # own kappa(A) at the stop: below the margin, within the pull-back of the last motion
    assert kmax * (1 - 1e-3) <= kappa <= kmax * (1 + 1e-9)
    assert answer["stop"]["value"] > kmax


def test_a_line_into_an_obstacle_stops_at_the_clearance(api):

    target = [0.45, 0.3, 0.1]
    ball = {"type": "sphere", "center": target, "radius": 0.05}
    body = {"start": START, "waypoints": [target], "obstacles": [ball]}
    answer, _, _ = _stopped(api, body, "clearance")
    post = postures(_design(body), np.array([answer["path"]["waypoints"][-1]]), 1)
    gap = float(clearance(post, [ball], DEFAULT_DESIGN["link_radius"])[0])
    # own clearance: on the valid side, within the pull-back of the last motion
    assert DEFAULT_MARGINS["clearance"] <= gap <= DEFAULT_MARGINS["clearance"] + 1e-4
    assert "clearance" in answer["message"]


def test_an_invalid_start_has_fraction_0_and_no_path(api):
    # kappa(A) of the start is above a margin of 1.0001 (own kappa first)
    assert postures(DEFAULT_DESIGN, np.array([START["q"]]), 1).kappa[0] > 1.0001
    body = {"start": START, "waypoints": [[0.4, 0, 0]], "margins": {"kappa_max": 1.0001}}
    answer = _post(api, body)
    assert answer["status"] == "invalid_start" and answer["fraction"] == 0.0
    assert "kappa" in answer["message"]
    assert answer["path"] is None and answer["trajectory"] is None


# ---------------------------------------------------------------------------- 422
@pytest.mark.parametrize(
    ("change", "loc", "words"),
    [
        ({"waypoints": []}, ["body", "waypoints"], "at least 1"),
        ({"waypoints": [[0.4, 0.0]]}, ["body", "waypoints", 0], "at least 3"),
        ({"waypoints": [[0.4, 0.0, "a"]]}, ["body", "waypoints", 0, 2], "number"),
        ({"waypoints": [[1e4, 1e4, -1e4]]}, ["body", "waypoints"], "more than 100 (L1 + L2)"),
        ({"path_tolerance": 0}, ["body", "path_tolerance"], "greater than or equal"),
        ({"path_tolerance": 0.5}, ["body", "path_tolerance"], "less than or equal"),
        ({"path_tolerance": "1e-3"}, ["body", "path_tolerance"], "number"),
        ({"timing": {"format": "csv"}}, ["body", "timing", "format"], "'arrays' or 'points'"),
        ({"timing": {"method": "fast"}}, ["body", "timing", "method"], "'toppra'"),
        ({"timing": {"max_deviation": 0.1}}, ["body", "timing", "max_deviation"], "not permitted"),
        ({"limits": {"velocity_scaling": 0}}, ["body", "limits", "velocity_scaling"], "greater"),
        ({"limits": {"velocity_scaling": 1.5}}, ["body", "limits", "velocity_scaling"], "less"),
        (
            {"limits": {"acceleration_scaling": -0.5}},
            ["body", "limits", "acceleration_scaling"],
            "greater",
        ),
        (
            {"limits": {"acceleration_scaling": True}},
            ["body", "limits", "acceleration_scaling"],
            "number",
        ),
        ({"goal": {"p": [0.4, 0, 0]}}, ["body", "goal"], "not permitted"),
    ],
)
def test_bad_values_are_422_naming_the_field_and_the_rule(api, change, loc, words):
    body = {"start": START, "waypoints": [[0.45, 0.3, 0.1]], **change}
    r = api.post("/v1/cartesian", json=body)
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert any(d["loc"] == loc and words in d["msg"] for d in detail), detail


def test_too_many_samples_is_422_naming_the_rate(api_with):
    body = {"start": START, "waypoints": [[0.45, 0.3, 0.1]], "timing": {"sample_rate_hz": 9000}}
    small = api_with(max_trajectory_samples=100)  # the session's service, read per request
    r = small.post("/v1/cartesian", json=body)
    assert r.status_code == 422, r.text
    item = r.json()["detail"][0]
    assert item["loc"] == ["body", "timing", "sample_rate_hz"] and "lower the rate" in item["msg"]


def test_a_trajectory_beyond_the_librarys_sample_cap_is_422_naming_the_rate(api):
    # 0.3 m at 1 um/s: 3e5 s at 100 Hz, far more samples than any answer may carry
    body = {"start": START, "waypoints": [[0.45, 0.3, 0.1]], "limits": {"cartesian_speed": 1e-6}}
    r = api.post("/v1/cartesian", json=body)
    assert r.status_code == 422, r.text
    item = r.json()["detail"][0]
    assert item["loc"] == ["body", "timing", "sample_rate_hz"] and "lower the rate" in item["msg"]


def test_the_route_is_documented_with_its_errors(api):
    op = api.get("/openapi.json").json()["paths"]["/v1/cartesian"]["post"]
    assert {"200", "422", "503", "504"} <= set(op["responses"])
    schemas = api.get("/openapi.json").json()["components"]["schemas"]
    request = schemas["CartesianRequest"]["properties"]
    assert {
        "design",
        "start",
        "waypoints",
        "path_tolerance",
        "obstacles",
        "scene",
        "margins",
        "timing",
        "limits",
        "gravity",
    } == set(request)
    response = schemas["CartesianResponse"]["properties"]
    assert {"status", "message", "fraction", "path", "trajectory", "diagnostics"} <= set(response)
    assert "max_path_deviation" in schemas["CartesianDiagnosticsModel"]["properties"]
    assert "proven_infeasible" in schemas["DiagnosticsModel"]["properties"]


def test_the_worker_warm_up_runs_a_straight_path_through_its_timing(monkeypatch):
    """The service's warm-up runs one job of each kind, a Cartesian one included, and that one
    goes the whole way (planning and timing), so no request pays their first calls."""
    import planner_api.metrics as metrics
    from planner.endpoints import cartesian as jobs
    from planner_api import warmup

    seen: list = []
    monkeypatch.setattr(metrics, "run_measured", lambda job, body, **_: seen.append((job, body)))
    warmup._run_jobs()
    assert [job.__name__ for job, _ in seen] == ["plan", "plan", "cartesian", "fk", "ik"]
    answer = jobs.cartesian(seen[2][1])
    assert answer.status == "solved" and answer.trajectory is not None


def test_a_short_line_of_a_long_robot_is_an_answer_not_a_422(api):
    """The review's request: a design with 1000 m links and a line of 20 m (2 % of a link);
    it used to be a 422 "the Cartesian refinement did not converge". Now a 200 whose path
    reaches the waypoint, every rule of a plan re-checked on it."""
    design = {"L0": 1000.0, "L1": 1000.0, "L2": 1000.0}
    start = {"q": [0.0, 1.0, 2.0], "assembly_mode": "+"}
    body = {"design": design, "start": start, "margins": {"kappa_max": 1e6}}
    p0 = _p_of(body, [start["q"]])[0]
    body["waypoints"] = [(p0 + np.array([0.0, 20.0, 0.0])).tolist()]
    body["timing"] = {"method": "none"}
    answer = _post(api, body)
    assert answer["status"] == "solved" and answer["fraction"] == 1.0, answer["message"]
    end = _p_of(body, answer["path"]["waypoints"][-1])[0]
    assert np.linalg.norm(end - body["waypoints"][0]) < 1e-6
    _checked_as_plan(body, answer)
