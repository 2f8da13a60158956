"""First plan after ``warm_up()`` against a warm one: does "ready" mean warm?

    .venv/bin/python benchmarks/warmup.py [--repeat 3]

Each round starts a fresh Python process (as the service starts a worker), which runs
:func:`planner.warmup.warm_up` (or, for the baseline, nothing), then times the same job
three times in a row: a plan among a sphere, a box and a capsule (OMPL, seeded), timed with
TOPPRA and with Ruckig, then a figure (PNG) as the figure endpoints draw it. The job differs
from the warm-up's own (other start, goal, obstacles and figure), so it measures a request's
first-call costs, not a replay. The first job's time includes the imports it needs.

Goal (issue 12): the first job after warm_up() within 2x of the second (warm) one.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys

from _machine import print_machine

_JOB = r"""
import json, os, sys, time
os.environ.setdefault("MPLBACKEND", "Agg")
t0 = time.perf_counter()
if sys.argv[1] == "warm":
    from planner.warmup import warm_up
    warm_up()
warm_up_s = time.perf_counter() - t0

def job():
    t = time.perf_counter()  # the imports count: a cold worker pays them in its first job
    from planner import Design
    from planner.geometry import Box, Capsule, Sphere
    from planner.planning import JointPosture, PlanOptions
    from planner.solver import solve
    from planner.timing import TimingOptions

    design = Design.default()
    obstacles = [Sphere([0.55, -0.02, -0.38], 0.1), Box([0, 0, -0.8], [2, 2, 0.1], [1, 0, 0, 0]),
                 Capsule([0.6, 0.5, 0.3], [0.6, 0.5, 0.6], 0.05)]
    for method in ("toppra", "ruckig"):
        solve(design, JointPosture([0.0, 2.0, 1.0], "+"), JointPosture([1.2, 2.3, 1.3], "+"),
              obstacles=obstacles, options=PlanOptions(seed=1),
              timing=TimingOptions(method=method))
    plan_s = time.perf_counter() - t
    t = time.perf_counter()
    from planner.plotting import render_figure

    render_figure("joint_section", Design.paper_optimum(), n=32, fmt="png")
    return plan_s, time.perf_counter() - t

runs = [job() for _ in range(3)]
print(json.dumps({"warm_up_s": warm_up_s, "plan_s": [r[0] for r in runs],
                  "figure_s": [r[1] for r in runs]}))
"""


def run(kind: str) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", _JOB, kind], capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="fresh processes per case")
    args = parser.parse_args()
    print_machine()
    print("fresh process per round; times in ms, median over rounds")
    print(
        f"{'case':<22} {'warm_up s':>9} {'1st plan':>9} {'2nd plan':>9} {'ratio':>6} "
        f"{'1st fig':>8} {'2nd fig':>8} {'ratio':>6}"
    )
    ratios = {}
    for kind in ("cold", "warm"):
        rounds = [run(kind) for _ in range(args.repeat)]

        def med(key: str, i: int, rounds: list[dict] = rounds) -> float:
            return statistics.median(r[key][i] for r in rounds)

        w = statistics.median(r["warm_up_s"] for r in rounds)
        p1, p2 = 1e3 * med("plan_s", 0), 1e3 * med("plan_s", 1)
        f1, f2 = 1e3 * med("figure_s", 0), 1e3 * med("figure_s", 1)
        label = "no warm_up()" if kind == "cold" else "after warm_up()"
        ratios[kind] = p1 / p2
        print(
            f"{label:<22} {w:>9.2f} {p1:>9.1f} {p2:>9.1f} {p1 / p2:>6.1f} "
            f"{f1:>8.1f} {f2:>8.1f} {f1 / f2:>6.1f}"
        )
    verdict = "met" if ratios["warm"] <= 2.0 else "NOT met"
    print(f"goal: first plan after warm_up() <= 2x a warm one: {verdict}")


if __name__ == "__main__":
    main()
