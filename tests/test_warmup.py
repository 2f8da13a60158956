"""planner warm-up compiles every numba kernel a request uses, before the first request."""

from __future__ import annotations

import subprocess
import sys

from typer.testing import CliRunner

from planner.cli import app

_WORKLOAD = """
import numba, importlib, numpy as np
from planner.warmup import warm_up
warm_up()

def compiled():
    total = 0
    for name in ('planner._kernels', 'planner.validity', 'planner.geometry'):
        for obj in vars(importlib.import_module(name)).values():
            if isinstance(obj, numba.core.registry.CPUDispatcher):
                total += len(obj.signatures)
    return total

before = compiled()
from planner import Design
from planner.planning import JointPosture, PlanOptions, plan
from planner.geometry import Box, Capsule, Sphere
design = Design.default()
obstacles = [Sphere([0.55, -0.02, -0.38], 0.1), Box([0, 0, -0.8], [2, 2, 0.1], [1, 0, 0, 0]),
             Capsule([0.6, 0.5, 0.3], [0.6, 0.5, 0.6], 0.05)]
plan(design, JointPosture([0.0, 2.0, 1.0], "+"), JointPosture([1.2, 2.3, 1.3], "+"),
     obstacles=obstacles, options=PlanOptions(seed=1))
print(before, compiled())
"""


def test_a_plan_with_every_obstacle_type_compiles_nothing_after_warm_up():
    """In a new interpreter, a plan among spheres, boxes and capsules after warm_up() adds no
    compiled signature to any numba kernel: nothing is compiled inside a request."""
    out = subprocess.run(
        [sys.executable, "-c", _WORKLOAD], capture_output=True, text=True, check=True
    )
    before, after = out.stdout.split()
    assert int(before) > 0
    assert after == before, out.stderr


def test_cli_warm_up_reports_its_time():
    result = CliRunner().invoke(app, ["warm-up"])
    assert result.exit_code == 0
    assert result.stdout.startswith("kernels ready in ")
