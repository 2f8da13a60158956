"""Speed scaling and the controller's shape of a trajectory, over HTTP, the client and the CLI:
``limits.velocity_scaling`` / ``acceleration_scaling`` against the closed-form trapezoid of a
rest-to-rest move at the velocity limit; ``timing.format`` "points" and "arrays" carrying the
same samples on /v1/plan, /v1/cartesian and /v1/timing; the client's conversions and its CSV
read back with the standard ``csv`` module (not the library's reader); ``planner plan
--csv`` and ``planner cartesian``."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import httpx
import numpy as np
import pytest
from typer.testing import CliRunner

from planner.client import PlannerClient, to_arrays, to_points, write_csv
from planner.wire import CartesianResponse, PlanResponse, TrajectoryModel, TrajectoryPointsModel
from planner_cli import app

START = {"q": [-0.2187, 2.8609, 0.2807], "assembly_mode": "+"}
#: A move of theta1 alone by D = 3 rad (the plane turns; P stays valid all along).
MOVE = [[-1.5, 2.0, 1.0], [1.5, 2.0, 1.0]]
D = 3.0
V, A = 2.0, 8.0  # the default limits, rad/s and rad/s^2
#: Relative error allowed on a duration (toppra's grid).
DURATION_RTOL = 1e-2

runner = CliRunner()


def _trapezoid(distance: float, v: float, a: float) -> float:
    """Rest-to-rest duration with a cruise at v (distance >= v^2 / a): d / v + v / a."""
    assert distance >= v * v / a
    return distance / v + v / a


def _timing(api, **limits) -> dict:
    r = api.post("/v1/timing", json={"waypoints": MOVE, "limits": limits, "sample_rate_hz": 500})
    assert r.status_code == 200 and r.json()["status"] == "solved", r.text
    return r.json()["trajectory"]


# ---------------------------------------------------------------------------- scaling
@pytest.mark.parametrize(
    ("vs", "as_"), [(1.0, 1.0), (0.5, 1.0), (1.0, 0.5), (0.5, 0.25), (0.3, 0.3)]
)
def test_scaling_matches_the_closed_form_trapezoid_on_v1_timing(api, vs, as_):
    traj = _timing(api, velocity_scaling=vs, acceleration_scaling=as_)
    expected = _trapezoid(D, V * vs, A * as_)
    assert traj["duration"] == pytest.approx(expected, rel=DURATION_RTOL)
    qd, qdd = np.abs(np.asarray(traj["qd"])), np.abs(np.asarray(traj["qdd"]))
    assert qd[:, 0].max() <= V * vs * (1 + 1e-6)
    assert qd[:, 0].max() >= V * vs * (1 - 1e-3)  # it does cruise at the scaled limit
    assert qdd[:, 0].max() <= A * as_ * (1 + 1e-6)


def test_velocity_scaling_half_doubles_a_time_scaled_move(api):
    """Velocity by c and acceleration by c^2 is a time scaling: every duration grows by 1 / c
    (here exactly 2, from 1.75 s to 3.5 s)."""
    full = _timing(api)["duration"]
    half = _timing(api, velocity_scaling=0.5, acceleration_scaling=0.25)["duration"]
    assert full == pytest.approx(_trapezoid(D, V, A), rel=DURATION_RTOL)
    assert half / full == pytest.approx(2.0, rel=DURATION_RTOL)


def test_scaling_applies_to_plans_and_cartesian_paths(api):
    plan = {"start": {"q": MOVE[0], "assembly_mode": "+"},
            "goal": {"q": MOVE[1], "assembly_mode": "+"}, "planner": {"seed": 1}}  # fmt: skip
    full = api.post("/v1/plan", json=plan).json()
    half = api.post("/v1/plan", json={**plan, "limits": {"velocity_scaling": 0.5}}).json()
    assert len(full["path"]["waypoints"]) == 2  # the direct move: one trapezoid
    assert full["trajectory"]["duration"] == pytest.approx(_trapezoid(D, V, A), rel=DURATION_RTOL)
    assert half["trajectory"]["duration"] == pytest.approx(
        _trapezoid(D, V / 2, A), rel=DURATION_RTOL
    )
    line = {"start": START, "waypoints": [[0.45, 0.3, 0.1]]}
    scaled = {"velocity_scaling": 0.5, "acceleration_scaling": 0.25}
    t_full = api.post("/v1/cartesian", json=line).json()["trajectory"]["duration"]
    t_half = api.post("/v1/cartesian", json={**line, "limits": scaled}).json()["trajectory"]
    assert t_half["duration"] / t_full == pytest.approx(2.0, rel=DURATION_RTOL)
    assert np.abs(np.asarray(t_half["qd"])).max() <= V / 2 * (1 + 1e-6)


# ---------------------------------------------------------------------------- formats
def _same_samples(arrays: dict, points: dict) -> None:
    assert points["duration"] == arrays["duration"]
    assert points["joint_names"] == ["theta1", "theta2", "theta3"]
    pts = points["points"]
    assert [p["time_from_start"] for p in pts] == arrays["t"]
    assert [p["positions"] for p in pts] == arrays["q"]
    assert [p["velocities"] for p in pts] == arrays["qd"]
    assert [p["accelerations"] for p in pts] == arrays["qdd"]
    assert "t" not in points and "q" not in points


@pytest.mark.parametrize("route", ["plan", "cartesian", "timing"])
def test_points_and_arrays_carry_the_same_samples(api, route):
    if route == "plan":
        body = {"start": START, "goal": {"p": [0.45, 0.3, 0.1]}, "planner": {"seed": 1}}
        arrays = api.post("/v1/plan", json=body).json()["trajectory"]
        body["timing"] = {"format": "points"}
        points = api.post("/v1/plan", json=body).json()["trajectory"]
    elif route == "cartesian":
        body = {"start": START, "waypoints": [[0.45, 0.3, 0.1]]}
        arrays = api.post("/v1/cartesian", json=body).json()["trajectory"]
        body["timing"] = {"format": "points"}
        points = api.post("/v1/cartesian", json=body).json()["trajectory"]
    else:
        arrays = api.post("/v1/timing", json={"waypoints": MOVE}).json()["trajectory"]
        body = {"waypoints": MOVE, "format": "points"}
        points = api.post("/v1/timing", json=body).json()["trajectory"]
    _same_samples(arrays, points)
    # the client converts either way, float for float
    a, p = TrajectoryModel.model_validate(arrays), TrajectoryPointsModel.model_validate(points)
    assert to_points(a).model_dump() == p.model_dump()
    back = to_arrays(p)
    assert (back.t, back.q, back.qd, back.qdd) == (a.t, a.q, a.qd, a.qdd)
    assert to_arrays(a) is a and to_points(p) is p


def test_responses_parse_either_format():
    arrays = {
        "duration": 1.0,
        "t": [0.0, 1.0],
        "q": [[0, 0, 0], [1, 1, 1]],
        "qd": [[0, 0, 0]] * 2,
        "qdd": [[0, 0, 0]] * 2,
    }
    points = to_points(TrajectoryModel.model_validate(arrays)).model_dump()
    for traj, cls in ((arrays, TrajectoryModel), (points, TrajectoryPointsModel)):
        for model in (PlanResponse, CartesianResponse):
            extra = {"fraction": 1.0} if model is CartesianResponse else {}
            parsed = model.model_validate({"status": "solved", "trajectory": traj, **extra})
            assert type(parsed.trajectory) is cls


# ---------------------------------------------------------------------------- CSV
def _read_plain_csv(path: Path) -> tuple[str, list[str], np.ndarray]:
    lines = path.read_text().splitlines()
    rows = list(csv.reader(lines[1:]))
    return lines[0], rows[0], np.array([[float(x) for x in r] for r in rows[1:]])


@pytest.mark.parametrize("form", ["arrays", "points"])
def test_csv_round_trip_gives_back_the_same_numbers(api, tmp_path, form):
    body = {"start": START, "waypoints": [[0.45, 0.3, 0.1]], "timing": {"format": form}}
    traj = CartesianResponse.model_validate(api.post("/v1/cartesian", json=body).json()).trajectory
    write_csv(traj, tmp_path / "t.csv")
    units, header, data = _read_plain_csv(tmp_path / "t.csv")
    assert units.startswith("#") and "rad/s^2" in units and " s" in units
    assert header[:4] == ["t", "theta1", "theta2", "theta3"]
    assert header[4:10] == ["dtheta1", "dtheta2", "dtheta3", "ddtheta1", "ddtheta2", "ddtheta3"]
    a = to_arrays(traj)
    assert data[:, 0].tolist() == a.t
    assert data[:, 1:4].tolist() == a.q
    assert data[:, 4:7].tolist() == a.qd
    assert data[:, 7:10].tolist() == a.qdd


def test_ruckig_csv_has_the_jerk_columns(api, tmp_path):
    body = {
        "start": START,
        "goal": {"q": [0.3, 2.6, 0.5], "assembly_mode": "+"},
        "timing": {"method": "ruckig"},
        "planner": {"seed": 1},
    }
    traj = PlanResponse.model_validate(api.post("/v1/plan", json=body).json()).trajectory
    write_csv(traj, tmp_path / "r.csv")
    _, header, data = _read_plain_csv(tmp_path / "r.csv")
    assert header[-3:] == ["dddtheta1", "dddtheta2", "dddtheta3"]
    assert data[:, -3:].tolist() == traj.jerk


# ---------------------------------------------------------------------------- client, CLI
def _forwarding(api) -> httpx.MockTransport:
    """A transport handing each request to the in-process service."""

    def handle(request: httpx.Request) -> httpx.Response:
        r = api.request(
            request.method,
            request.url.path,
            content=request.content,
            headers={"content-type": "application/json"},
        )
        return httpx.Response(r.status_code, content=r.content, headers=r.headers)

    return httpx.MockTransport(handle)


def test_client_cartesian_returns_the_services_answer(api):
    with PlannerClient("http://planner.test", transport=_forwarding(api)) as client:
        answer = client.cartesian(
            start=START, waypoints=np.array([[0.45, 0.3, 0.1]]), timing={"format": "points"}
        )
        served = api.post(
            "/v1/cartesian",
            json={"start": START, "waypoints": [[0.45, 0.3, 0.1]], "timing": {"format": "points"}},
        ).json()
        assert answer.status == "solved" and answer.fraction == 1.0
        assert isinstance(answer.trajectory, TrajectoryPointsModel)
        assert (
            answer.trajectory.model_dump()
            == TrajectoryPointsModel.model_validate(served["trajectory"]).model_dump()
        )
        short = client.cartesian({"start": START, "waypoints": [[1.2, 0.3, 0.1]]})
        assert short.status == "no_path" and 0 < short.fraction < 1 and short.stop is not None


def test_cli_plan_writes_the_trajectory_csv(tmp_path):
    body = {
        "start": START,
        "goal": {"q": [0.3, 2.6, 0.5], "assembly_mode": "+"},
        "planner": {"seed": 1},
    }
    (tmp_path / "req.json").write_text(json.dumps(body))
    out, table = tmp_path / "full.json", tmp_path / "traj.csv"
    r = runner.invoke(
        app, ["plan", str(tmp_path / "req.json"), "-o", str(out), "--csv", str(table)]
    )
    assert r.exit_code == 0, r.output
    assert f"trajectory CSV: {table}" in r.stdout
    full = PlanResponse.model_validate_json(out.read_text())
    _, header, data = _read_plain_csv(table)
    assert header[0] == "t" and data[:, 0].tolist() == full.trajectory.t
    assert data[:, 1:4].tolist() == full.trajectory.q


def test_cli_cartesian_follows_the_line_and_names_the_stop(api, tmp_path):
    table = tmp_path / "c.csv"
    r = runner.invoke(
        app,
        [
            "cartesian",
            *map(str, START["q"]),
            "0.45",
            "0.3",
            "0.1",
            "--speed",
            "0.25",
            "--csv",
            str(table),
        ],
    )
    assert r.exit_code == 0, r.output
    lines = r.stdout.splitlines()
    assert lines[0] == "status: solved" and "fraction: 1" in lines
    served = api.post(
        "/v1/cartesian",
        json={"start": START, "waypoints": [[0.45, 0.3, 0.1]], "limits": {"cartesian_speed": 0.25}},
    ).json()
    _, _, data = _read_plain_csv(table)
    assert data[:, 0].tolist() == served["trajectory"]["t"]
    assert any(line.startswith("  max_path_deviation: ") for line in lines)
    # a line out of reach: exit 1, the rule and the point named
    r = runner.invoke(app, ["cartesian", *map(str, START["q"]), "1.2", "0.3", "0.1"])
    assert r.exit_code == 1
    assert r.stdout.splitlines()[0] == "status: no_path"
    assert any(line.startswith("stopped by: ") for line in r.stdout.splitlines())
    # bad input: exit 2 naming the field
    r = runner.invoke(app, ["cartesian", "0", "2", "1", "0.4"])
    assert r.exit_code == 2 and "numbers" in r.output
    r = runner.invoke(
        app, ["cartesian", *map(str, START["q"]), "0.4", "0", "0", "--velocity-scaling", "2"]
    )
    assert r.exit_code == 2 and "limits.velocity_scaling" in r.output


def test_client_cartesian_validates_locally_before_sending():
    from planner.client import InvalidRequestError

    def refuse(request: httpx.Request) -> httpx.Response:  # pragma: no cover - never called
        raise AssertionError("sent")

    with PlannerClient("http://planner.test", transport=httpx.MockTransport(refuse)) as client:
        with pytest.raises(InvalidRequestError) as err:
            client.cartesian(start=START, waypoints=[[0.4, 0.0, 0.0]], path_tolerance=0)
    assert err.value.status_code is None
    assert err.value.detail[0]["loc"] == ["path_tolerance"]
