"""``planner plan request.json`` (in-process planning, summary, --out) and ``planner bench``."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

from plan_checker import check_plan
from typer.testing import CliRunner

from planner.wire import PlanResponse
from planner_cli import app

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()

REQUEST = {
    "start": {"q": [0.2, 1.0, 2.0], "assembly_mode": "+"},
    "goal": {"q": [1.0, 1.0, 2.0], "assembly_mode": "+"},
    "obstacles": [{"type": "sphere", "center": [0.623, -0.013, -0.426], "radius": 0.08}],
    "margins": {"clearance": 0.01},
    "planner": {"seed": 1},
}


def _write(tmp_path: Path, body: object, name: str = "request.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(body) if not isinstance(body, str) else body)
    return path


def test_plan_prints_a_summary_and_writes_the_full_response(api, tmp_path):
    """The summary of a solved plan and the full answer in ``--out``: the answer passes the
    independent check against the request (tests/plan_checker.py: from the start to the
    goal, clear of the sphere, a consistent trajectory), the service gives the same path,
    the summary's numbers are the answer's. Mutant caught by the check (not by comparing with
    the service, which shares the library, nor by the old test): ``obstacles_to_core``
    building each sphere at a quarter of its radius."""
    out = tmp_path / "result.json"
    r = runner.invoke(app, ["plan", str(_write(tmp_path, REQUEST)), "--out", str(out)])
    assert r.exit_code == 0, r.output
    full = PlanResponse.model_validate_json(out.read_text())
    assert full.status == "solved"
    report = check_plan(REQUEST, json.loads(out.read_text()))
    assert report.ok, report
    assert full.path.waypoints[0] == REQUEST["start"]["q"]
    assert full.path.waypoints[-1] == REQUEST["goal"]["q"]
    lines = r.stdout.splitlines()  # the results; the progress lines are on stderr
    assert lines[0] == "status: solved"
    assert f"waypoints: {len(full.path.waypoints)}" in lines
    assert f"segments: {len(full.path.segments)}" in lines
    assert f"transits: {len(full.path.transits)}" in lines
    assert any(line.startswith(f"duration: {full.trajectory.duration:.4f} s") for line in lines)
    assert any(line.startswith("  min_clearance: ") for line in lines)
    assert len(lines) <= 40  # one screen
    # the same request through the service gives the same path (seeded planner)
    served = api.post("/v1/plan", json=REQUEST).json()
    assert served["status"] == "solved"
    assert served["path"]["waypoints"] == full.path.waypoints
    assert full.diagnostics.min_clearance >= 0.01 - 1e-9
    # not on a terminal: what it is doing, as plain lines on stderr, each step with the time
    # since the command began ("at"), then how long planning and timing took, in words (a bare
    # "(2.2 s)" read as the duration of the trajectory)
    loading, planning, done = r.stderr.splitlines()[-3:]
    assert re.fullmatch(r"plan: loading the planner \(at \d+\.\d s\)", loading)
    assert re.fullmatch(
        r"plan: planning \(search budget 1 s\) and timing \(at \d+\.\d s\)", planning
    )
    took = re.fullmatch(r"plan: planned and timed in (\d+\.\d) s", done)
    assert took, done
    assert float(took[1]) >= full.diagnostics.planning_time_s - 0.05


def test_plan_other_status_exits_1(tmp_path):
    # P beyond the reach L1 + L2 of both legs: no posture reaches it
    body = {**REQUEST, "goal": {"p": [1.5, 0.0, 0.0], "working_mode": "any"}}
    r = runner.invoke(app, ["plan", str(_write(tmp_path, body))])
    assert r.exit_code == 1
    assert r.stdout.splitlines()[0] == "status: unreachable"
    assert "duration: none" in r.stdout


def test_plan_bad_request_names_the_field_and_exits_2(tmp_path):
    body = {**REQUEST, "start": {"q": [0.2, 1.0], "assembly_mode": "+"}}
    r = runner.invoke(app, ["plan", str(_write(tmp_path, body))])
    assert r.exit_code == 2 and "start.q" in r.output
    r = runner.invoke(app, ["plan", str(_write(tmp_path, "{not json", "broken.json"))])
    assert r.exit_code == 2 and "error" in r.output
    r = runner.invoke(app, ["plan", str(tmp_path / "missing.json")])
    assert r.exit_code == 2 and "cannot read" in r.output
    body = {**REQUEST, "margins": {"kappa_max": 0.5}}
    r = runner.invoke(app, ["plan", str(_write(tmp_path, body))])
    assert r.exit_code == 2 and "margins.kappa_max" in r.output


def test_bench_builtin_prints_its_table():
    r = runner.invoke(app, ["bench", "--builtin"])
    assert r.exit_code == 0, r.output
    rows = [line for line in r.stdout.splitlines() if line[:1].isalpha()]
    assert any(line.startswith("forward_batch") for line in rows)
    assert any(line.startswith("time_path toppra") for line in rows)
    for line in r.stdout.splitlines()[2:]:
        assert float(line.split()[-1]) > 0
    # progress on stderr: each task as it starts, numbered
    tasks = [row.rsplit(maxsplit=1)[0].strip() for row in r.stdout.splitlines()[2:]]
    progress = r.stderr.splitlines()
    assert len(progress) == len(tasks) == 4
    for i, task in enumerate(tasks):
        assert progress[i].startswith(f"bench: [{i + 1}/4] {task} (")


def test_bench_runs_a_script_and_refuses_unknown_names():
    """``planner bench kinematics --quick`` runs benchmarks/kinematics.py with the quick
    arguments: the script's own header says the sizes it parsed, and its table holds the three
    quantities with positive rates and each ratio the quotient of its two rates (up to the
    printed rounding). An unknown name is refused naming it and every script of benchmarks/
    (listed here from the folder), before anything runs.

    Mutants caught: ``--quick`` not passed on (``args = []``: the script runs its full sizes;
    the old test, which looked for the words "kinematics" and "forward", passed it), the
    script's ratio inverted (``loop / vec``), the refusal not naming the unknown benchmark;
    the old test passed all three."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), str(ROOT)])}
    done = subprocess.run(
        [sys.executable, "-m", "planner_cli", "bench", "kinematics", "--quick"],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
        cwd=ROOT,
    )
    assert done.returncode == 0, done.stderr
    out = done.stdout.splitlines()
    assert out[0] == "== kinematics (benchmarks/kinematics.py --n 100000 --loop-n 200 --repeat 3)"
    assert "kinematics, N = 100,000 postures, median of 3, one core" in out  # as it parsed them
    rows = {}
    for line in out:
        found = re.fullmatch(r"(\S.*?)\s+(\d+\.\d\d)\s+(\d+\.\d)\s+(\d+)", line)
        if found:
            rows[found[1]] = tuple(float(x) for x in found.groups()[1:])
    assert list(rows) == ["forward", "inverse (x8 modes)", "conditioning"], out
    for name, (vec_m, loop_k, ratio) in rows.items():
        assert vec_m > 0 and loop_k > 0, name
        # the ratio of the unrounded rates lies within the printed roundings
        low = 1e3 * (vec_m - 0.005) / (loop_k + 0.05) - 0.5
        high = 1e3 * (vec_m + 0.005) / max(loop_k - 0.05, 1e-9) + 0.5
        assert low <= ratio <= high, (name, vec_m, loop_k, ratio)
    assert "bench: [1/1] kinematics" in done.stderr  # progress, not mixed into the tables
    r = runner.invoke(app, ["bench", "nope"])
    assert r.exit_code == 2
    scripts = sorted(p.stem for p in (ROOT / "benchmarks").glob("*.py") if p.stem[0] != "_")
    message = " ".join(r.output.replace("\u2502", " ").split())  # unwrapped from its box
    assert f"unknown benchmark nope; one of {', '.join(scripts)}" in message
    assert "== " not in r.output  # nothing ran
