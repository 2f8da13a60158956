"""``POST /v1/sequence`` over HTTP, held to independent routes: every leg's path re-checked by
the test's own plan checker (:func:`plan_checker.check_plan`, numpy only: the rules, the
obstacles, the goal reached); the one trajectory's samples by the checker's kinematics
(clearance, kappa(A), velocity limits), strictly increasing times, rest at the stops and
speed at the pass-throughs read from the samples themselves; the bad inputs of the issue
answered 422 by name, an unreachable target by its index; the client and the CLI."""

from __future__ import annotations

import json
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

START = {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"}
BASE = [0.35, -0.1, -0.45]
OBSTACLES = [{"type": "sphere", "center": [0.35, 0.1, -0.7], "radius": 0.1}]


def point(dx: float, dy: float, dz: float) -> list[float]:
    return [BASE[0] + dx, BASE[1] + dy, BASE[2] + dz]


def body(stop_corners: bool = True, blend: float = 0.05, **extra) -> dict:
    corner = {"stop": stop_corners, "blend": 0.0 if stop_corners else blend}
    return {
        "start": START,
        "targets": [
            {"goal": {"p": point(0, 0, 0.05)}, **corner},
            {"goal": {"p": point(0, 0.3, 0.05)}, **corner},
            {"goal": {"p": point(0, 0.3, 0.0)}},
        ],
        "cycle": True,
        "obstacles": OBSTACLES,
        "timing": {"sample_rate_hz": 200},
        **extra,
    }


def check_sequence(request: dict, answer: dict) -> None:
    """Every rule of the answer, by the test's own routes."""
    assert answer["status"] == "solved", answer["message"]
    legs = answer["legs"]
    goals = [t["goal"] for t in request["targets"]] + (
        [request["start"]] if request["cycle"] else []
    )
    assert [leg["target_index"] for leg in legs] == list(range(len(goals)))
    q_prev = request["start"]["q"]
    for leg, goal in zip(legs, goals, strict=True):
        plan_request = {
            "start": {"q": q_prev, "assembly_mode": "+"},
            "goal": goal,
            "obstacles": request["obstacles"],
        }
        report = check_plan(plan_request, {"status": "solved", "path": leg["path"]})
        assert report.ok, str(report)
        q_prev = leg["path"]["waypoints"][-1]
    traj = answer["trajectory"]
    t, q, qd = (np.asarray(traj[k], float) for k in ("t", "q", "qd"))
    assert np.all(np.diff(t) > 0)
    assert t[-1] == pytest.approx(answer["cycle_time"])
    assert np.all(np.abs(qd) <= np.asarray(DEFAULT_LIMITS["velocity"]) * (1 + 1e-6))
    post = postures(DEFAULT_DESIGN, q, 1)
    assert np.all(post.ok)
    assert np.all(clearance(post, request["obstacles"], DEFAULT_DESIGN["link_radius"]) >= 0)
    assert np.max(post.kappa) <= DEFAULT_MARGINS["kappa_max"] * (1 + 1e-9)
    for a, b in pairwise(legs):
        assert b["start_time"] == a["end_time"] < b["end_time"]
    stops = [t_.get("stop", True) for t_ in request["targets"]] + [True]
    stops[len(request["targets"]) - 1] |= not request["cycle"]
    for leg, stop in zip(legs, stops, strict=False):
        i = int(np.argmin(np.abs(t - leg["end_time"])))
        if stop:  # a stop is one of the samples, at rest on the leg's last waypoint
            assert t[i] == pytest.approx(leg["end_time"], abs=1e-9)
            assert np.all(np.abs(qd[i]) <= 1e-9)
            np.testing.assert_allclose(q[i], leg["path"]["waypoints"][-1], atol=1e-9)
        else:
            assert np.linalg.norm(qd[i]) > 0.05
            near = np.min(np.linalg.norm(q - leg["path"]["waypoints"][-1], axis=1))
            assert near <= 0.05 + 0.02  # the blend, within the samples' spacing


def test_a_cycle_of_stops_and_one_passing_through_corners(api):
    answers = {}
    for stop in (True, False):
        request = body(stop, objective="fixed")
        r = api.post("/v1/sequence", json=request)
        assert r.status_code == 200, r.text
        check_sequence(request, r.json())
        answers[stop] = r.json()
    assert answers[False]["cycle_time"] < answers[True]["cycle_time"]


def test_modes_for_time_are_named_in_the_message(api):
    request = body(True)
    answer = api.post("/v1/sequence", json=request).json()
    check_sequence(request, answer)
    assert "working modes chosen for time" in answer["message"]
    assert "runner-up" in answer["message"]
    d = answer["diagnostics"]
    assert d["assignments_evaluated"] >= 2 and d["optimality_gap_s"] == 0.0
    assert d["runner_up_cycle_time"] >= answer["cycle_time"]
    assert len(d["modes"]) == 4 and all(d["modes"][:3])


@pytest.mark.parametrize(
    ("change", "loc"),
    [
        ({"targets": []}, ["body", "targets"]),
        ({"targets": [{"goal": {"p": BASE}}] * 65}, ["body", "targets"]),
        (
            {"targets": [{"goal": {"p": BASE}, "stop": False, "blend": -0.1}]},
            ["body", "targets", 0, "blend"],
        ),
        ({"objective": "fastest"}, ["body", "objective"]),
        (
            {"targets": [{"goal": {"p": BASE, "tolerance": 0.01}}]},
            ["body", "targets", 0, "goal", "tolerance"],
        ),
    ],
)
def test_bad_input_is_a_422_naming_the_field(api, change, loc):
    r = api.post("/v1/sequence", json={**body(), **change})
    assert r.status_code == 422, r.text
    assert any(d["loc"][: len(loc)] == loc for d in r.json()["detail"]), r.text


def test_a_blend_larger_than_half_its_leg_shrinks_to_fit(api):
    """Never a 422: the blend shrinks to half the shorter adjacent leg, diagnostics.blends
    gives asked and used, the message names the target."""
    request = body(False, blend=0.05, objective="fixed")
    request["targets"][0]["blend"] = 2.0
    r = api.post("/v1/sequence", json=request)
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["status"] == "solved", out["message"]
    first = out["diagnostics"]["blends"][0]
    assert first["target_index"] == 0 and first["unit"] == "rad" and first["asked"] == 2.0
    assert 0 < first["used"] < 2.0
    assert f"target 0 2 -> {first['used']:.4g} rad" in out["message"]


def test_blend_and_blend_radius_together_is_a_422_at_blend_radius(api):
    request = body(False, blend=0.05, objective="fixed")
    request["targets"][0]["blend_radius"] = 0.01
    r = api.post("/v1/sequence", json=request)
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["loc"][:4] == ["body", "targets", 0, "blend_radius"]
    assert "not both" in r.json()["detail"][0]["msg"]
    for bad in (-0.01, "x"):
        request["targets"][0].pop("blend")
        request["targets"][0]["blend_radius"] = bad
        r = api.post("/v1/sequence", json=request)
        assert r.status_code == 422, r.text
        assert r.json()["detail"][0]["loc"][:4] == ["body", "targets", 0, "blend_radius"]
        request["targets"][0]["blend"] = 0.05


def test_the_service_limit_on_targets(api_with):
    r = api_with(max_sequence_targets=2).post("/v1/sequence", json=body())
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "targets"]
    assert "PLANNER_MAX_SEQUENCE_TARGETS" in r.json()["detail"][0]["msg"]


def test_an_unreachable_target_names_its_index(api):
    request = body()
    request["targets"][1]["goal"] = {"p": [3.0, 0.0, 0.0]}
    answer = api.post("/v1/sequence", json=request).json()
    assert answer["status"] == "unreachable"
    assert answer["message"].startswith("target 1:")
    assert [leg["status"] for leg in answer["legs"]] == ["solved", "unreachable"]
    assert answer["trajectory"] is None and answer["cycle_time"] is None


def test_client_and_cli(api, tmp_path, monkeypatch):
    import httpx

    from planner.client import PlannerClient

    transport = httpx.MockTransport(
        lambda req: httpx.Response(
            200,
            content=api.post(
                "/v1/sequence", content=req.content, headers={"content-type": "application/json"}
            ).content,
            headers={"content-type": "application/json"},
        )
    )
    with PlannerClient("http://test", transport=transport) as client:
        answer = client.sequence(**body(objective="fixed"))
    assert answer.status == "solved" and answer.cycle_time > 0
    assert len(answer.legs) == 4

    from typer.testing import CliRunner

    from planner_cli.app import app

    path = tmp_path / "seq.json"
    path.write_text(json.dumps(body(objective="fixed")))
    out = tmp_path / "answer.json"
    result = CliRunner().invoke(app, ["sequence", str(path), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "cycle time:" in result.output and "target 3: solved" in result.output
    assert json.loads(out.read_text())["cycle_time"] == pytest.approx(answer.cycle_time)


def test_a_mode_change_lists_its_transits_per_leg_as_a_plan_does(api):
    """Each leg's ``path.transits`` is /v1/plan's shape, and ``transit_times`` (one per
    transit, within the leg's span) say when the trajectory crosses them."""
    start = {"q": [0.90975316, -0.10880946, 1.24575975], "assembly_mode": "+"}
    request = {
        "start": start,
        "targets": [
            {"goal": {"p": [0.35, -0.15, -0.43], "working_mode": "+-+"}},
            {"goal": {"p": [0.35, -0.15, -0.45], "working_mode": "+++"}},
        ],
        "objective": "fixed",
    }
    answer = api.post("/v1/sequence", json=request).json()
    assert answer["status"] == "solved", answer["message"]
    plan = api.post("/v1/plan", json={"start": start, "goal": request["targets"][0]["goal"]}).json()
    assert set(plan["path"]["transits"][0]) == set(answer["legs"][0]["path"]["transits"][0])
    t = np.asarray(answer["trajectory"]["t"])
    q = np.asarray(answer["trajectory"]["q"])
    for leg in answer["legs"]:
        transits = leg["path"]["transits"]
        assert transits and len(leg["transit_times"]) == len(transits)
        for tr, tc in zip(transits, leg["transit_times"], strict=True):
            assert leg["start_time"] <= tc <= leg["end_time"]
            # the sampled trajectory is near the transit posture around that time
            k = int(np.argmin(np.abs(t - tc)))
            assert np.linalg.norm(q[k] - np.asarray(tr["q"])) <= 0.05 + 2.0 * 0.01
