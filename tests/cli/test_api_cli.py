"""The CLI commands that mirror the API: ``planner fk`` / ``planner ik`` print the same JSON
as the endpoints (``ik`` says why no posture reaches a point, and exits 1); ``planner serve``
takes its settings from the environment."""

from __future__ import annotations

import json
import math

from typer.testing import CliRunner

from planner import Design
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


def test_ik_out_of_reach_says_why_and_exits_1(api):
    """No posture: the JSON the endpoint answers (an empty list), the reason on stderr, and
    exit status 1, a Unix tool's "no answer" (as grep finding nothing), which the help says."""
    r = runner.invoke(app, ["ik", "5", "5", "5"])
    assert r.exit_code == 1
    assert json.loads(r.stdout) == api.post("/v1/ik", json={"p": [5, 5, 5]}).json()
    assert json.loads(r.stdout) == {"postures": []}
    d = Design.default()
    ap, bp = math.dist((5, 5, 5), (0, -d.L0 / 2, 0)), math.dist((5, 5, 5), (0, d.L0 / 2, 0))
    assert r.stderr.strip() == (
        "error: no posture reaches P = (5, 5, 5) in any working mode: P is out of reach of "
        f"leg A (|AP| = {ap:.6g} m > L1 + L2 = {d.L1 + d.L2:.6g} m) and of leg B "
        f"(|BP| = {bp:.6g} m > L1 + L2 = {d.L1 + d.L2:.6g} m)"
    )
    # inside the inner shell of both legs (|L2 - L1| = 0.4 m with the default design)
    r = runner.invoke(app, ["ik", "0", "0.1", "0"])
    assert r.exit_code == 1
    assert "|AP| = 0.35 m < |L2 - L1| = 0.4 m" in r.stderr
    assert "|BP| = 0.15 m < |L2 - L1| = 0.4 m" in r.stderr
    help_text = " ".join(runner.invoke(app, ["ik", "--help"]).stdout.replace("│", " ").split())
    assert "Exit status: 0 one posture or more; 1 none" in help_text


def test_ik_in_a_mode_that_misses_the_point_names_the_modes_that_reach_it(api):
    """On the axis AB every posture has a 0 axis sign: asking for +++ there finds none, and
    the message names the modes that do reach P (those of the endpoint's answer)."""
    args = ["ik", "--design", "paper-optimum", "--working-mode", "+++", "0", "0.3", "0"]
    r = runner.invoke(app, args)
    assert r.exit_code == 1 and json.loads(r.stdout) == {"postures": []}
    design = {"L0": 0.0, "L1": 0.4, "L2": 0.4}
    served = api.post("/v1/ik", json={"p": [0, 0.3, 0], "design": design}).json()
    modes = [p["working_mode"] for p in served["postures"]]
    assert modes and all(m.startswith("0") for m in modes)
    assert r.stderr.startswith(
        f"error: no posture in working mode +++ reaches P = (0, 0.3, 0); it is reached in "
        f"working modes {', '.join(modes)} only"
    )
    # a reachable point still exits 0
    assert runner.invoke(app, ["ik", "-0.25", "0.1", "0.3"]).exit_code == 0
