"""What a new user meets at the command line: a bad option is named (exit 2, no traceback), a
valid input without an answer says why (exit 1), and the dynamics commands take an inertia."""

from __future__ import annotations

import json
import re

import numpy as np
from typer.testing import CliRunner

from planner import Design
from planner.dynamics import Inertia, inverse_dynamics
from planner.dynamics.inertia import ALUMINIUM_DENSITY, DEFAULT_TUBE_RADIUS, tube_inertia
from planner.dynamics.mjcf import to_mjcf
from planner_cli import app

runner = CliRunner()
NUMBER = re.compile(r"-?\d+\.?\d*(?:e[-+]?\d+)?")


def _same_model(text: str, reference: str) -> None:
    """The same MJCF up to the last digits of its numbers."""
    assert NUMBER.sub("#", text) == NUMBER.sub("#", reference)
    got = [float(x) for x in NUMBER.findall(text)]
    want = [float(x) for x in NUMBER.findall(reference)]
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)


def test_figures_with_an_unknown_format_names_the_option_and_exits_2(tmp_path):
    r = runner.invoke(app, ["figures", str(tmp_path / "out"), "--formats", "png,xyz"])
    assert r.exit_code == 2, r.output
    assert r.exception is None or isinstance(r.exception, SystemExit)  # no traceback
    assert r.stderr.startswith("error: --formats: no format 'xyz'; one of ")
    assert "png" in r.stderr and "svg" in r.stderr
    assert not (tmp_path / "out").exists()  # refused before any figure was drawn
    # a named figure is PNG or SVG only: a format matplotlib writes is still refused there
    r = runner.invoke(app, ["figures", str(tmp_path), "--named", "region_map", "--formats", "pdf"])
    assert (
        r.exit_code == 2
        and r.stderr.strip() == "error: --formats: no format 'pdf'; one of png, svg"
    )


def test_fk_without_a_posture_says_why_and_exits_1():
    """L0 = 0.3 with L1 = L2 = 0.1 and q = 0: C and D lie |CD| = L0 apart, more than
    2 L2 = 0.2 m, so the loop cannot close (computed here from the frame, not the library)."""
    r = runner.invoke(app, ["fk", "0", "0", "0", "--L0", "0.3", "--L1", "0.1", "--L2", "0.1"])
    assert r.exit_code == 1
    assert json.loads(r.stdout) == {"postures": []}
    c, d = np.array([-0.15 + 0.1, 0.0]), np.array([0.15 + 0.1, 0.0])
    cd = float(np.linalg.norm(d - c))
    assert r.stderr.strip() == (
        f"error: no posture has q = (0, 0, 0) in any assembly mode: q does not assemble: "
        f"|CD| = {cd:.6g} m > 2 L2 = 0.2 m"
    )
    r = runner.invoke(
        app,
        ["fk", "0", "0", "0", "--L0", "0.3", "--L1", "0.1", "--L2", "0.1", "--assembly-mode", "-"],
    )
    assert r.exit_code == 1 and "in assembly mode -:" in r.stderr
    help_text = " ".join(runner.invoke(app, ["fk", "--help"]).stdout.replace("│", " ").split())
    assert "Exit status: 0 one posture or more; 1 none" in help_text


def test_mjcf_names_the_home_option_once():
    r = runner.invoke(app, ["mjcf", "--home", "0,0,0", "--design", "paper-optimum"])
    assert r.exit_code == 2
    assert r.stderr.strip() == (
        "error: --home: home = [0.0, 0.0, 0.0] does not assemble in assembly mode '+'"
    )
    assert "home.home" not in r.output


def test_mjcf_and_dynamics_take_an_inertia_file_and_a_payload(tmp_path):
    """A partial inertia file (the proximal mass alone) and --payload-mass: the model is the
    library's for the default tube of that mass (a denser tube: the same shape scaled) and
    that payload; ``planner dynamics`` with the same options gives that robot's torques."""
    design = Design.default()
    default = Inertia.default(design)
    radius = design.link_radius or DEFAULT_TUBE_RADIUS
    density = ALUMINIUM_DENSITY * 0.3 / default.proximal.mass
    heavier = tube_inertia(design.L1, radius, "proximal", density=density)
    assert abs(heavier.mass - 0.3) < 1e-12
    inertia = Inertia(heavier, default.distal, 2.0, default.base_inertia, default.rotor)
    path = tmp_path / "arm.json"
    path.write_text(json.dumps({"proximal": {"mass": 0.3}}))
    options = ["--inertia", str(path), "--payload-mass", "2"]
    r = runner.invoke(app, ["mjcf", *options])
    assert r.exit_code == 0, r.output
    _same_model(r.stdout, to_mjcf(design, inertia))
    assert 'mass="2.0"' in r.stdout and 'mass="2.0"' not in to_mjcf(design)
    r = runner.invoke(app, ["dynamics", "0", "2", "1", "--qdd", "1,0,0", *options])
    assert r.exit_code == 0, r.output
    ref = inverse_dynamics(
        design, inertia, np.array([0, 2.0, 1.0]), np.zeros(3), np.array([1.0, 0, 0])
    ).tau[0]
    np.testing.assert_allclose(json.loads(r.stdout)["tau"][0], ref, rtol=1e-9, atol=1e-12)
    # a bad number in the file is named; an unreadable file names the option
    path.write_text(json.dumps({"proximal": {"mass": -1}}))
    r = runner.invoke(app, ["mjcf", "--inertia", str(path)])
    assert r.exit_code == 2 and "inertia.proximal.mass" in r.stderr
    r = runner.invoke(app, ["mjcf", "--inertia", str(tmp_path / "none.json")])
    assert r.exit_code == 2 and "--inertia" in r.output


def test_scene_list_without_a_service_names_the_url_and_how_to_set_it(unused_port, monkeypatch):
    monkeypatch.setenv("PLANNER_URL", f"http://127.0.0.1:{unused_port}")
    r = runner.invoke(app, ["scene", "list"])
    assert r.exit_code == 2
    assert f"no planning service answers at http://127.0.0.1:{unused_port}" in r.stderr
    assert "--url or PLANNER_URL" in r.stderr and "Traceback" not in r.output


def test_job_wait_polls_until_done_and_writes_the_result(api, tmp_path, monkeypatch):
    """``planner job submit`` then ``planner job wait --out``: the result is the endpoint's
    answer to the same request (the CLI's client forwarded to the in-process service)."""
    import httpx

    from planner.client import PlannerClient
    from planner_cli import service

    def forward(r: httpx.Request) -> httpx.Response:
        headers = {"content-type": "application/json"}
        answer = api.request(r.method, r.url.path, content=r.content, headers=headers)
        return httpx.Response(answer.status_code, content=answer.content)

    transport = httpx.MockTransport(forward)
    monkeypatch.setattr(
        service, "make_client", lambda url, key: PlannerClient("http://x", transport=transport)
    )
    body = {"design": {"L0": 0.3, "L1": 0.3, "L2": 0.4}, "rel_se": 0.05}
    request = tmp_path / "check.json"
    request.write_text(json.dumps(body))
    r = runner.invoke(app, ["job", "submit", "design_check", str(request)])
    assert r.exit_code == 0, r.output
    job_id = r.stdout.strip()
    out = tmp_path / "result.json"
    r = runner.invoke(app, ["job", "wait", job_id, "--out", str(out), "--interval", "0.05"])
    assert r.exit_code == 0, r.output
    assert r.stdout.startswith(f"{job_id}\tdesign_check\tdone")
    result = json.loads(out.read_text())
    served = api.post("/v1/design/check", json=body).json()
    # C=D as L0 <= 2 L1, CD stretched as 2 (L2 - L1) <= L0 (docs/analysis.md)
    assert (
        result["parallel_singularities"]
        == served["parallel_singularities"]
        == ["C=D", "CD_stretched"]
    )
    assert result["volume"] == served["volume"]
    r = runner.invoke(app, ["job", "wait", "0" * 32])
    assert r.exit_code == 1 and "no job" in r.output
