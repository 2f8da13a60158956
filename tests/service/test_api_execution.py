"""Execution on the wire: a moving start, replacement mid-motion, POST /v1/stop.

Random splices on random running trajectories (both methods), each answer checked by finite
differences and by the independent plan checker (tests/plan_checker.py, a moving start:
the first sample is the running state at ``at``, the lead-in held to every validity rule
and limit); bad input is a 422 naming the field.
"""

from __future__ import annotations

import numpy as np
import pytest
from plan_checker import check_plan

from planner.endpoints.plan import plan
from planner.endpoints.sequence import sequence
from planner.wire import PlanRequest, SequenceRequest

CENTRE = np.array([0.0, 2.0, 1.0])
LIMITS = {"velocity": [2.0] * 3, "acceleration": [8.0] * 3, "jerk": [200.0] * 3}


def _posture(q) -> dict:
    return {"q": [float(x) for x in q], "assembly_mode": "+"}


def _solved(body: dict) -> dict:
    response = plan(PlanRequest.model_validate(body)).model_dump(mode="json")
    assert response["status"] == "solved", response["message"]
    return response


def _fd_limits(traj: dict, jerk: bool) -> None:
    t = np.asarray(traj["t"])
    q, qd, qdd = (np.asarray(traj[k]) for k in ("q", "qd", "qdd"))
    dt = np.diff(t)[:, None]
    slack = 1 + 1e-6
    assert np.all(np.abs(np.diff(q, axis=0)) <= 2.0 * dt * slack + 1e-12)
    assert np.all(np.abs(np.diff(qd, axis=0)) <= 8.0 * dt * slack + 1e-12)
    if jerk:
        assert np.all(np.abs(np.diff(qdd, axis=0)) <= 200.0 * dt * slack + 1e-9)


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_random_splices_are_continuous_valid_and_within_the_limits(method):
    rng = np.random.default_rng(7 if method == "toppra" else 8)
    timing = {"method": method, "sample_rate_hz": 250}
    for _ in range(3):
        first = CENTRE + rng.uniform(-0.3, 0.3, 3)
        running = _solved(
            {
                "start": _posture(CENTRE),
                "goal": _posture(first),
                "timing": timing,
                "planner": {"seed": 1},
            }
        )["trajectory"]
        k = int(rng.integers(1, len(running["t"]) - 1))
        at = running["t"][k]
        request = {
            "replace": {"trajectory": running, "at": at},
            "goal": _posture(CENTRE + rng.uniform(-0.3, 0.3, 3)),
            "timing": timing,
            "planner": {"seed": 1},
        }
        answer = _solved(request)
        traj = answer["trajectory"]
        assert traj["t"][0] == at
        for key in ("q", "qd", "qdd"):  # the splice: the running state itself
            gap = np.max(np.abs(np.asarray(traj[key][0]) - np.asarray(running[key][k])))
            assert gap <= 1e-9, key
        _fd_limits(traj, jerk=method == "ruckig")
        lead = answer["diagnostics"]["lead_in"]
        state = {key: running[key][k] for key in ("q", "qd", "qdd")}
        checked = {**request, "start": {**_posture(state["q"]), **state}}
        report = check_plan(checked, answer, start_state=state, lead_in_s=lead["duration"])
        assert report.checked and report.ok, str(report)


def test_a_moving_start_on_plan_begins_in_that_state():
    start = {**_posture(CENTRE), "qd": [0.8, -0.4, 0.3], "qdd": [1.0, 0.0, -1.0]}
    body = {"start": start, "goal": _posture(CENTRE + 0.25), "timing": {"method": "ruckig"}}
    answer = _solved(body)
    traj = answer["trajectory"]
    assert traj["t"][0] == 0.0
    for key in ("q", "qd", "qdd"):
        np.testing.assert_allclose(traj[key][0], start[key], atol=1e-9, rtol=0)
    report = check_plan(
        body, answer, start_state=start, lead_in_s=answer["diagnostics"]["lead_in"]["duration"]
    )
    assert report.ok, str(report)


def test_a_sequence_replaces_on_the_running_clock():
    running = _solved({"start": _posture(CENTRE), "goal": _posture(CENTRE + 0.3)})["trajectory"]
    at = running["t"][len(running["t"]) // 2]
    body = {
        "replace": {"trajectory": running, "at": at},
        "targets": [{"goal": _posture(CENTRE - 0.2)}, {"goal": _posture(CENTRE + 0.1)}],
    }
    answer = sequence(SequenceRequest.model_validate(body)).model_dump(mode="json")
    assert answer["status"] == "solved", answer["message"]
    assert answer["trajectory"]["t"][0] == at and answer["legs"][0]["start_time"] == at
    i = len(running["t"]) // 2
    np.testing.assert_array_equal(answer["trajectory"]["qd"][0], running["qd"][i])


def _running() -> dict:
    return _solved({"start": _posture(CENTRE), "goal": _posture(CENTRE + 0.3)})["trajectory"]


@pytest.mark.parametrize(
    ("change", "loc"),
    [
        ({"start": {**_posture(CENTRE), "qd": [2.5, 0.0, 0.0]}}, ["body", "start", "qd"]),
        ({"replace": {"at": 99.0}}, ["body", "replace", "at"]),
        ({"replace": {"trajectory": {"t": [0.0, 0.0]}}}, ["body", "replace", "trajectory", "t"]),
        ({"start": _posture(CENTRE + 1e-3), "replace": {}}, ["body", "start"]),
    ],
)
def test_bad_execution_input_is_a_422_naming_the_field(api, change, loc):
    running = _running()
    body: dict = {"start": _posture(CENTRE), "goal": _posture(CENTRE + 0.2)}
    if "replace" in change:
        body.pop("start")
        replace = {"trajectory": running, "at": running["t"][3]}
        bad = change["replace"]
        if "trajectory" in bad:
            replace["trajectory"] = {**running, **bad["trajectory"]}
            n = len(bad["trajectory"]["t"])
            replace["trajectory"].update({k: running[k][:n] for k in ("q", "qd", "qdd")})
        if "at" in bad:
            replace["at"] = bad["at"]
        body["replace"] = replace
    if "start" in change:
        body["start"] = change["start"]
    r = api.post("/v1/plan", json=body)
    assert r.status_code == 422, r.text
    assert any(item["loc"][: len(loc)] == loc for item in r.json()["detail"]), r.text


def test_stop_brakes_to_rest_from_the_running_state(api):
    running = _running()
    k = len(running["t"]) // 3
    r = api.post("/v1/stop", json={"trajectory": running, "at": running["t"][k]})
    assert r.status_code == 200, r.text
    answer = r.json()
    assert answer["status"] == "solved", answer["message"]
    stop = answer["trajectory"]
    assert stop["t"][0] == running["t"][k]
    for key in ("q", "qd", "qdd"):
        np.testing.assert_allclose(stop[key][0], running[key][k], atol=1e-9, rtol=0)
        assert key == "q" or not np.any(stop[key][-1])
    _fd_limits(stop, jerk=True)
    r = api.post("/v1/stop", json={"trajectory": running, "at": -1.0})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "at"]
    r = api.post("/v1/stop", json={"trajectory": {**running, "q": running["q"][:-1]}, "at": 0.1})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "trajectory", "q"]


def test_timing_and_cartesian_take_a_moving_start(api):
    start = {"qd": [0.6, 0.3, 0.15], "qdd": [0.0, 0.0, 0.0]}  # along the first segment
    step = np.array([0.4, 0.2, 0.1])
    body = {"waypoints": [CENTRE.tolist(), (CENTRE + step).tolist()], "start": start}
    answer = api.post("/v1/timing", json=body).json()
    assert answer["status"] == "solved", answer["message"]
    traj = answer["trajectory"]
    np.testing.assert_allclose(traj["qd"][0], start["qd"], atol=1e-9, rtol=0)
    _fd_limits(traj, jerk=False)
    r = api.post("/v1/timing", json={**body, "start": {"qd": [0.0, 9.0, 0.0]}})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "start", "qd"]
    fk = api.post("/v1/fk", json={"q": list(CENTRE), "assembly_mode": "+"}).json()
    p = np.asarray(fk["postures"][0]["p"])
    cart = {
        "start": {**_posture(CENTRE), "qd": [0.0, 0.0, 0.0], "qdd": [0.0, 0.0, 0.0]},
        "waypoints": [(p + np.array([0.0, 0.02, 0.0])).tolist()],
    }
    assert api.post("/v1/cartesian", json=cart).json()["status"] == "solved"
    cart["start"]["qd"] = [3.0, 0.0, 0.0]
    r = api.post("/v1/cartesian", json=cart)
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "start", "qd"]


def test_the_client_and_the_cli_stop(tmp_path):
    import json

    import httpx
    from typer.testing import CliRunner

    from planner.client import PlannerClient
    from planner_cli import app

    running = _running()
    seen: list[dict] = []

    def answer(request: httpx.Request) -> httpx.Response:
        seen.append(json.loads(request.content))
        return httpx.Response(200, json={"status": "solved", "along_path": False})

    with PlannerClient("http://x", transport=httpx.MockTransport(answer)) as client:
        got = client.stop(running, at=running["t"][5], limits={"velocity": [1.5] * 3})
    assert got.status == "solved"
    assert seen[0]["trajectory"]["t"] == running["t"] and seen[0]["at"] == running["t"][5]
    assert seen[0]["limits"]["velocity"] == [1.5] * 3 and "duration" not in seen[0]["trajectory"]
    request = tmp_path / "stop.json"
    request.write_text(json.dumps({"trajectory": running, "at": running["t"][5]}))
    r = CliRunner().invoke(app, ["stop", str(request)])
    assert r.exit_code == 0 and r.stdout.splitlines()[0] == "status: solved"
    request.write_text(json.dumps({"trajectory": running, "at": 99.0}))
    r = CliRunner().invoke(app, ["stop", str(request)])
    assert r.exit_code == 2 and "at" in r.output
