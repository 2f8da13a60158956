"""Every script of examples/ runs against a real service (the ``live_server`` fixture: uvicorn
on a free loopback port) and passes its own checks; its output says so."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"

#: Example -> the lines its output must hold (each example asserts its own checks too).
EXPECTED = {
    "01_first_plan.py": ["status: solved", "check: P ends", "first plan: ok"],
    "02_mode_change.py": ["status: solved", "transit at waypoint", "mode change: ok"],
    "03_obstacles.py": ["status: solved", "check: smallest link-to-ball gap", "obstacles: ok"],
    "04_design_study.py": ["paper-optimum", "C=D, CD_stretched", "figure:", "design study: ok"],
    "05_cartesian.py": ["status: solved", "check: P within", "status: no_path", "cartesian: ok"],
    "06_pick_and_place.py": ["status: solved", "check: passing the corners", "pick and place: ok"],
    "07_conveyor.py": [
        "check: P on the part over every dwell",
        "picks per minute:",
        "conveyor: ok",
    ],
}


def _run(name: str, url: str, *args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), str(ROOT)])}
    env.pop("PLANNER_URL", None)
    return subprocess.run(
        [sys.executable, str(EXAMPLES / name), url, *args],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
        cwd=ROOT,
    )


def test_every_example_is_listed():
    assert sorted(p.name for p in EXAMPLES.glob("[0-9]*.py")) == sorted(EXPECTED)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_example_runs_against_the_live_server(live_server, tmp_path, name):
    result = _run(name, live_server, str(tmp_path))
    assert result.returncode == 0, result.stdout + result.stderr
    for line in EXPECTED[name]:
        assert line in result.stdout, (line, result.stdout)
    if name == "04_design_study.py":
        assert (tmp_path / "default_cartesian_section.png").read_bytes().startswith(b"\x89PNG")
    if name == "06_pick_and_place.py":
        assert (tmp_path / "pick_and_place.csv").read_text().splitlines()[1].startswith("t,")
    if name == "05_cartesian.py":
        assert (tmp_path / "cartesian.csv").read_text().splitlines()[1].startswith("t,theta1,")


def test_example_reports_an_unreachable_server(unused_port):
    result = _run("01_first_plan.py", f"http://127.0.0.1:{unused_port}")
    assert result.returncode != 0 and "TransportError" in result.stderr
