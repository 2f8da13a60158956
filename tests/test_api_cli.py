"""The CLI commands that mirror the API: ``planner fk`` / ``planner ik`` print the same JSON
as the endpoints; ``planner serve`` takes its settings from the environment."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from planner_cli import app

runner = CliRunner()


def test_fk_prints_what_the_endpoint_answers(api):
    r = runner.invoke(app, ["fk", "--assembly-mode", "-", "--", "0.2", "-1.0", "2.0"])
    assert r.exit_code == 0, r.output
    served = api.post("/v1/fk", json={"q": [0.2, -1.0, 2.0], "assembly_mode": "-"}).json()
    assert json.loads(r.output) == served


def test_ik_with_a_preset_and_an_override(api):
    r = runner.invoke(app, ["ik", "--design", "paper-optimum", "--L1", "0.3", "--working-mode",
                            "any", "--", "0.2", "0.1", "-0.3"])  # fmt: skip
    assert r.exit_code == 0, r.output
    design = {"L0": 0.0, "L1": 0.3, "L2": 0.4}
    served = api.post("/v1/ik", json={"p": [0.2, 0.1, -0.3], "design": design}).json()
    assert json.loads(r.output) == served
    assert len(served["postures"]) >= 1


def test_bad_input_names_the_field_and_exits_2():
    r = runner.invoke(app, ["fk", "0", "1"])
    assert r.exit_code == 2 and "q:" in r.output
    r = runner.invoke(app, ["ik", "--L2", "-1", "0.1", "0.1", "0.1"])
    assert r.exit_code == 2 and "design.L2" in r.output
    r = runner.invoke(app, ["fk", "--design", "tiny", "0", "1", "2"])
    assert r.exit_code == 2 and "--design" in r.output


def test_serve_help_names_the_environment():
    r = runner.invoke(app, ["serve", "--help"])
    assert r.exit_code == 0 and "PLANNER_WORKERS" in r.output
