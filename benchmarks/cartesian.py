"""Straight tool paths: success, fraction, time (planning + timing) and deviation.

    .venv/bin/python benchmarks/cartesian.py [--cases 100] [--seed 0] [--method toppra]

On two designs (the default, singularity-free one and L0 = 0.6, L1 = 0.25, L2 = 0.45, which has
a CD-stretched parallel singularity), seeded cases across the workspace: a start posture drawn
uniformly in joint space (kept when valid with the default margins), then either a line of
0.3 m in a random direction or a 3-point polyline of 0.15 m legs. Each is planned with
:func:`planner.cartesian.plan.plan_cartesian` (default path tolerance 1 mm, toppra timing
with a tool speed of 0.25 m/s unless told otherwise). Reported per design and kind: success
(fraction 1), mean fraction, p50/p95 of the whole call (planning + timing; and the p50 of
the solved cases alone), the largest
deviation of P from the polyline measured over the timed trajectory, and the mean number of
joint waypoints. Goal (issue 16): p50 <= 10 ms for a 0.3 m line with toppra timing on the
default design (reported, not asserted): the last row states it, with the wall-clock p50 and
the CPU p50 of this process (other load on a shared machine does not count in the latter).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from _machine import print_machine

from planner import Design, forward_batch
from planner.cartesian.plan import plan_cartesian
from planner.planning import JointPosture, posture_mode
from planner.validity import Margins, ValidityChecker


def starts(design: Design, rng: np.random.Generator, n: int) -> list[JointPosture]:
    out = []
    while len(out) < n:
        q = rng.uniform(-np.pi, np.pi, 3)
        post = JointPosture(q, "+")
        mode = posture_mode(design, post)
        if mode and ValidityChecker(design, Margins(), (), "+", mode).is_valid(q[None])[0]:
            out.append(post)
    return out


def unit(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def run(
    design: Design, name: str, kind: str, cases: int, seed: int, method: str
) -> tuple[str, float, float]:
    """One row of the table, and the wall-clock and CPU p50 (s) of its cases."""
    rng = np.random.default_rng(seed)
    times, cpu, fractions, devs, nway, solved_t = [], [], [], [], [], []
    ok = 0
    for start in starts(design, rng, cases):
        p0 = forward_batch(design, start.q, "+").p[0]
        if kind == "line 0.3 m":
            wp = (p0 + 0.3 * unit(rng))[None]
        else:
            a = p0 + 0.15 * unit(rng)
            wp = np.stack([a, a + 0.15 * unit(rng)])
        t0, c0 = time.perf_counter(), time.process_time()
        res = plan_cartesian(design, start, wp, timing=method, cartesian_speed=0.25)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        fractions.append(res.fraction)
        ok += res.solved
        if res.solved:
            solved_t.append(times[-1])
        nway.append(res.diagnostics.waypoints)
        if res.trajectory is not None:
            devs.append(res.diagnostics.max_path_deviation)
    q = statistics.quantiles(times, n=20)
    row = (
        f"{name:<22} {kind:<18} {ok:>4}/{cases:<4} {statistics.mean(fractions):>8.3f} "
        f"{1e3 * statistics.median(times):>8.2f} {1e3 * q[18]:>8.2f} "
        f"{1e3 * statistics.median(cpu):>8.2f} "
        f"{1e3 * statistics.median(solved_t) if solved_t else float('nan'):>10.2f} "
        f"{1e3 * max(devs, default=float('nan')):>10.4f} {statistics.mean(nway):>8.1f}"
    )
    return row, statistics.median(times), statistics.median(cpu)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--method", default="toppra", choices=["toppra", "ruckig"])
    args = ap.parse_args()
    print_machine()
    designs = [("default", Design.default()), ("L0=.6 L1=.25 L2=.45", Design(0.6, 0.25, 0.45))]
    # warm the kernels and solvers outside the figures
    plan_cartesian(
        Design.default(),
        starts(Design.default(), np.random.default_rng(1), 1)[0],
        [[0.5, 0.1, 0.1]],
        timing=args.method,
    )
    print(f"timing: {args.method}, tool speed 0.25 m/s, path tolerance 1 mm")
    print(
        f"{'design':<22} {'kind':<18} {'success':>9} {'fraction':>8} {'p50 ms':>8} "
        f"{'p95 ms':>8} {'cpu p50':>8} {'solved p50':>10} {'max dev mm':>10} "
        f"{'waypts':>8}"
    )
    goal = None
    for name, design in designs:
        for kind in ("line 0.3 m", "3-point polyline"):
            row, wall, cpu = run(design, name, kind, args.cases, args.seed, args.method)
            print(row, flush=True)
            if goal is None:
                goal = (wall, cpu)
    print("(p50/p95: wall clock of the whole call, planning + timing; cpu p50: this process;")
    print(" max dev: largest distance of P from the polyline over the timed trajectory)")
    assert goal is not None
    print()
    print(
        f"goal (issue 16): default design, 0.3 m line, {args.method} timing: p50 "
        f"{1e3 * goal[0]:.2f} ms wall, {1e3 * goal[1]:.2f} ms cpu; goal <= 10 ms: "
        f"{'met' if goal[1] <= 0.010 else 'not met'} (on cpu)"
    )


if __name__ == "__main__":
    main()
