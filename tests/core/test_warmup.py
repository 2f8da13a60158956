"""``warm_up()`` pays every first-call cost of a request before the first request: after it,
a worker's first plan (OMPL), timing (TOPPRA and Ruckig) and figure import nothing and
compile nothing, so the first request costs what a warm one does ("ready means warm",
issue 12). Asserted on what the process holds, not on wall-clock times
(benchmarks/warmup.py measures the times). The wire models are not the library's: the
service's worker warm-up (:mod:`planner_api.warmup`) validates them through its own jobs."""

from __future__ import annotations

import json
import subprocess
import sys

from typer.testing import CliRunner

from planner_cli import app

_WORKLOAD = """
import importlib, json, sys
import numba
from planner.warmup import STEPS, warm_up

calls = []
warm_up(lambda name, index, total: calls.append([name, index, total]))

def compiled():
    # every numba kernel of every planner module loaded: its compiled signatures
    total = 0
    for name in [m for m in sys.modules if m == 'planner' or m.startswith('planner.')]:
        for obj in vars(sys.modules[name]).values():
            if isinstance(obj, numba.core.registry.CPUDispatcher):
                total += len(obj.signatures)
    return total

import matplotlib
backend = matplotlib.get_backend().lower()
signatures_before, modules_before = compiled(), set(sys.modules)

# a request unlike the warm-up's: other start, goal, obstacles of every type, design, figure
import numpy as np
from planner import Design
from planner.geometry import Box, Capsule, Sphere
from planner.planning import JointPosture, PlanOptions
from planner.plotting import render_figure
from planner.solver import solve
from planner.timing import TimingOptions
design = Design.default()
obstacles = [Sphere([0.55, -0.02, -0.38], 0.1), Box([0, 0, -0.8], [2, 2, 0.1], [1, 0, 0, 0]),
             Capsule([0.6, 0.5, 0.3], [0.6, 0.5, 0.6], 0.05)]
solved = [solve(design, JointPosture([0.0, 2.0, 1.0], "+"), JointPosture([1.2, 2.3, 1.3], "+"),
                obstacles=obstacles, options=PlanOptions(seed=1), timing=TimingOptions(method=m))
          for m in ("toppra", "ruckig")]
res = solved[0].plan
# a stop mid-motion of the Ruckig answer (a stream's or /v1/stop's brake), other limits
from planner.timing import JointLimits
from planner.timing.braking import stop_trajectory
from planner.timing.running import RunningTrajectory
from planner.validity import ValidityChecker
tr = solved[1].trajectory
ts = np.linspace(0.0, tr.duration, 80)
qs, qds, qdds, _ = tr.at(ts)
rules = ValidityChecker(design, obstacles=obstacles, serial_rules=False).is_valid
braked = stop_trajectory(RunningTrajectory.of(ts, qs, qds, qdds), 0.4 * tr.duration,
                         design=design, assembly_mode="+", limits=JointLimits((1.5,) * 3, (6.0,) * 3, (150.0,) * 3),
                         path_rules=rules, brake_rules=rules)
durations = [s.trajectory.duration for s in solved]
# a plan among a point cloud (packed with its tree) and a sphere; a torque-limited plan (the
# inverse dynamics in the timing); a design check of another design (the conditioning)
from planner.analysis.design_check import check_design
from planner.geometry import Points
g = 0.03 * (np.arange(36) - 18.0)
gx, gy = (a.ravel() for a in np.meshgrid(g, g, indexing="ij"))
cloud = Points(np.column_stack([gx, gy, np.full(gx.size, -0.7)]), 0.02)
clouded = solve(design, JointPosture([0.0, 2.0, 1.0], "+"), JointPosture([1.2, 2.3, 1.3], "+"),
                obstacles=[obstacles[0], cloud], options=PlanOptions(seed=1))
torqued = solve(design, JointPosture([0.0, 2.0, 1.0], "+"), JointPosture([0.8, 2.3, 1.2], "+"),
                options=PlanOptions(seed=1),
                limits=JointLimits((3.0,) * 3, (30.0,) * 3, torque=(9.0, 2.0, 2.0)))
checked = check_design(Design(0.0, 0.4, 0.4), rel_se=0.05)
# a straight line of the tool from another start (the certificate, its timing, the measure)
from planner.cartesian.plan import plan_cartesian
from planner.kinematics import forward_batch
line_start = JointPosture([0.3, 2.1, 1.2], "+")
p_line = forward_batch(design, np.asarray(line_start.q), "+").p[0]
line = plan_cartesian(design, line_start, [p_line + np.array([0.02, 0.1, -0.03])],
                      cartesian_speed=0.3)
more = [clouded.plan.status, torqued.plan.status, torqued.trajectory.duration > 0,
        checked.singularity_free, line.status.value, line.trajectory is not None]
png = render_figure("joint_section", Design.paper_optimum(), n=24, fmt="png")
print(json.dumps({
    "calls": calls, "steps": [s.name for s in STEPS], "backend": backend,
    "loaded": [m for m in ("ompl", "toppra", "ruckig", "matplotlib", "scipy.optimize")
               if m in modules_before],
    "signatures": [signatures_before, compiled()],
    "new_modules": sorted(set(sys.modules) - modules_before),
    "status": res.status, "durations": durations, "png": png[:8].hex(),
    "stop": braked.status, "more": more,
}))
"""


def _run_workload() -> dict:
    out = subprocess.run(
        [sys.executable, "-c", _WORKLOAD], capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.splitlines()[-1])


def test_after_warm_up_a_first_request_imports_and_compiles_nothing():
    """In a new interpreter, after warm_up(): OMPL, toppra, ruckig and matplotlib (Agg) are
    loaded and numba holds compiled kernels; a plan among a sphere, a box and a capsule,
    timed with both methods, and a figure of another design then load no module and add no
    compiled signature to any numba kernel, nor does a stop mid-motion of the Ruckig answer,
    a plan among a point cloud, a torque-limited plan, a design check or a straight line of
    the tool: nothing is imported or compiled in a request."""
    got = _run_workload()
    assert got["status"] == "solved" and all(d > 0 for d in got["durations"])
    assert got["stop"] == "solved"
    assert got["more"] == ["solved", "solved", True, False, "solved", True]
    assert got["png"].startswith("89504e47")  # a PNG came out
    assert got["loaded"] == ["ompl", "toppra", "ruckig", "matplotlib", "scipy.optimize"]
    assert got["backend"] == "agg"
    before, after = got["signatures"]
    assert before > 0
    assert after == before
    assert got["new_modules"] == []
    # progress: each named step announced in order with the steps done so far, then 'ready'
    total = len(got["steps"])
    assert total >= 6
    expected = [[name, i, total] for i, name in enumerate(got["steps"])]
    assert got["calls"] == [*expected, ["ready", total, total]]


def test_cli_warm_up_reports_each_step_and_its_time():
    """Not on a terminal (the runner's stderr is a pipe): one plain line per step on stderr,
    the total on stdout."""
    from planner.warmup import STEPS

    result = CliRunner().invoke(app, ["warm-up"])
    assert result.exit_code == 0, result.output
    assert result.stdout.startswith("warmed up in ")
    lines = result.stderr.splitlines()
    for i, step in enumerate(STEPS):
        assert f"[{i + 1}/{len(STEPS)}] {step.name}" in lines[i]
