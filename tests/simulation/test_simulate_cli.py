"""``planner simulate``: a plan request planned and simulated in-process, its bag read back;
a plan's answer simulated from its trajectory; bad input names the field (exit 2)."""

from __future__ import annotations

import json

import numpy as np
from typer.testing import CliRunner

from planner.simulation.bag import read_bag
from planner.wire import SimulateResponse
from planner_cli import app

runner = CliRunner()

REQUEST = {
    "start": {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"},
    "goal": {"q": [0.2, 2.1, 0.9], "assembly_mode": "+"},
}


def test_simulate_a_plan_request_with_a_bag(tmp_path) -> None:
    path, out, bag = tmp_path / "req.json", tmp_path / "out.json", tmp_path / "run.mcap"
    path.write_text(json.dumps(REQUEST))
    r = runner.invoke(app, ["simulate", str(path), "--out", str(out), "--bag", str(bag)])
    assert r.exit_code == 0, r.output
    assert "engine: mujoco" in r.output and "realised duration:" in r.output
    answer = SimulateResponse.model_validate_json(out.read_text())
    back = read_bag(bag)
    assert back.realised is not None and back.trajectory is not None
    np.testing.assert_array_equal(back.realised["q"], answer.q)
    np.testing.assert_array_equal(back.realised["tau"], answer.tau)
    assert answer.trajectory is not None
    np.testing.assert_array_equal(back.trajectory["q"], answer.trajectory.q)
    # the plan's answer, simulated from its trajectory with PD: the same reference
    plan = {"status": "solved", "trajectory": answer.trajectory.model_dump()}
    path.write_text(json.dumps(plan))
    r = runner.invoke(app, ["simulate", str(path), "--controller", "pd", "--out", str(out)])
    assert r.exit_code in (0, 1), r.output
    pd = SimulateResponse.model_validate_json(out.read_text())
    assert pd.controller == "pd" and pd.planned_duration == answer.planned_duration


def test_simulate_bad_input_names_the_field(tmp_path) -> None:
    path = tmp_path / "req.json"
    path.write_text(json.dumps(REQUEST))
    r = runner.invoke(app, ["simulate", str(path), "--controller", "lqr"])
    assert r.exit_code == 2 and "controller.kind" in r.output
    r = runner.invoke(app, ["simulate", str(path), "--rate-hz", "5"])
    assert r.exit_code == 2 and "rate_hz" in r.output
