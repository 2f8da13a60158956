"""Speed of the design analyses: labelled 256 x 256 sections and the sampled workspace volume.

    .venv/bin/python benchmarks/analysis.py [--n 256] [--rel-se 0.005] [--repeat 7]

Prints the median wall time of repeats (after one warm-up call) on one core (the numba kernels
and numpy run single-threaded), against the goal
of one second each (issue 4):

* a Cartesian (u, w) section, n x n cells x 8 working modes: inverse kinematics, joint limits,
  kappa(A), mode and singularity labels;
* a joint-space (theta2, theta3) section, n x n cells x 2 assembly modes;
* the sampled workspace volume (with joint limits, per working mode, kappa(A) <= 10 fraction)
  to the asked relative standard error, for the paper's optimum and the default design.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

from _machine import print_machine

from planner import Design
from planner.analysis.sections import cartesian_section, joint_section
from planner.analysis.workspace import closed_form_volume, sample_workspace

GOAL_S = 1.0


def median_seconds(fn: Callable[[], object], repeat: int) -> tuple[float, object]:
    out = fn()  # warm-up (compilation, caches)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def main() -> None:
    print_machine()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=256, help="cells per axis of the sections")
    parser.add_argument("--rel-se", type=float, default=0.005, help="target relative std error")
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()

    rows = []
    for name, design in (("paper optimum", Design.paper_optimum()), ("default", Design.default())):
        t, _ = median_seconds(lambda d=design: cartesian_section(d, args.n), args.repeat)
        rows.append((f"cartesian section {args.n}x{args.n} x 8 modes ({name})", t, ""))
        t, _ = median_seconds(lambda d=design: joint_section(d, args.n), args.repeat)
        rows.append((f"joint section {args.n}x{args.n} x 2 assembly ({name})", t, ""))
        t, s = median_seconds(
            lambda d=design: sample_workspace(d, rel_se=args.rel_se, kappa_max=10.0), args.repeat
        )
        exact = closed_form_volume(design)
        v = s.volume  # type: ignore[attr-defined]
        note = (
            f"V = {v.value:.5f} +- {v.standard_error:.5f} m^3 (rel {v.relative_error:.2%}, "
            f"{v.n_samples} pts); closed form {exact:.5f}, "
            f"|diff| = {abs(v.value - exact) / v.standard_error:.1f} SE"
        )
        rows.append((f"sampled volume to {args.rel_se:.1%} rel. SE ({name})", t, note))

    width = max(len(r[0]) for r in rows)
    print(f"{'task'.ljust(width)}  median [s]  goal [s]  ratio  ok  note")
    for task, t, note in rows:
        ok = "yes" if t < GOAL_S else "NO"
        print(f"{task.ljust(width)}  {t:10.4f}  {GOAL_S:8.1f}  {t / GOAL_S:5.2f}  {ok:3} {note}")


if __name__ == "__main__":
    main()
