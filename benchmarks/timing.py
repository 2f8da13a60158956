"""Time parameterisation: computation time, ruckig/toppra duration ratio, deviation, repairs.

    .venv/bin/python benchmarks/timing.py [--paths 100] [--waypoints 20] [--seed 0]

On seeded random joint-space walks (``--waypoints`` waypoints, steps uniform in +-0.5 rad per
joint, default design, default limits 2 rad/s, 8 rad/s^2, 200 rad/s^3):

* computation time p50/p95 of ``time_path`` per method, including the dense re-check (joint
  limits, assembly, deviation, and a kappa(A) validity checker built on the kinematics);
* trajectory duration of ruckig relative to toppra (same velocity and acceleration limits),
  against the baseline of resting at every waypoint, for several jerk limits;
* deviation from the planned polyline, and the repairs taken when a small forbidden box is
  put inside some corners (where the blends pass, off the polyline).

Goals (issue 7): toppra p50 <= 10 ms for a 20-waypoint path including the dense re-check;
ruckig duration <= 1.2x toppra's. Goals (issue 16): ruckig's p50 at most toppra's, with the
ruckig/toppra duration ratio <= 1.2 at its maximum; the "goals" table shows both side by
side. The methods run interleaved path by path (each path timed by every method in turn), so
that load from other processes falls on all of them alike.
"""

from __future__ import annotations

import argparse
import itertools
import statistics
import time

import numpy as np
from _machine import print_machine

from planner import Design, conditioning, forward_batch
from planner.exceptions import TrajectoryCheckError
from planner.timing import JointLimits, time_path


def random_walk(rng: np.random.Generator, n: int) -> np.ndarray:
    return np.clip(np.cumsum(rng.uniform(-0.5, 0.5, size=(n, 3)), axis=0), -2.5, 2.5)


def kappa_checker(design: Design, kappa_max: float = 50.0):
    def check(q: np.ndarray) -> np.ndarray:
        batch = forward_batch(design, q, "+")
        cond = conditioning(design, batch.q, batch.passive, batch.w)
        return batch.ok & (np.nan_to_num(cond.kappa_A, nan=np.inf) <= kappa_max)

    return check


def corner_box_checker(w: np.ndarray, k: int, half: float = 0.008):
    """Rejects a small box inside corner k, where a 0.05 rad blend passes (its arc is 0.05 from the vertex)."""
    y1 = (w[k] - w[k - 1]) / np.linalg.norm(w[k] - w[k - 1])
    y2 = (w[k + 1] - w[k]) / np.linalg.norm(w[k + 1] - w[k])
    centre = w[k] + 0.045 * (y2 - y1) / np.linalg.norm(y2 - y1)
    lo, hi = centre - half, centre + half

    def check(q: np.ndarray) -> np.ndarray:
        return ~np.all((q >= lo) & (q <= hi), axis=1)

    dense = np.concatenate([np.linspace(a, b, 2000) for a, b in itertools.pairwise(w)])
    return check if np.all(check(dense)) else None


def pct(xs: list[float], p: float) -> float:
    return float(np.percentile(xs, p))


def main() -> None:
    print_machine()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--paths", type=int, default=100)
    parser.add_argument("--waypoints", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    design = Design.default()
    limits = JointLimits.default()
    rng = np.random.default_rng(args.seed)
    paths = [random_walk(rng, args.waypoints) for _ in range(args.paths)]
    check = kappa_checker(design)
    time_path(design, paths[0], limits, check_states=check)  # warm-up (numba, caches)
    time_path(design, paths[0], limits, method="ruckig", check_states=check)

    print(
        f"timing, {args.paths} seeded random paths of {args.waypoints} waypoints, "
        f"default design and limits (v 2 rad/s, a 8 rad/s^2, j 200 rad/s^3), one process"
    )
    print()
    print(
        f"{'method':<26} {'wall p50 [ms]':>14} {'p95':>7} {'cpu p50 [ms]':>13} {'p95':>7} "
        f"{'repairs':>8} {'dev p50 [rad]':>14}"
    )
    configs = (
        ("toppra", "toppra", None),
        ("toppra + kappa(A) check", "toppra", check),
        ("ruckig", "ruckig", None),
        ("ruckig + kappa(A) check", "ruckig", check),
    )
    results: dict[str, list] = {label: [] for label, _, _ in configs}
    wall: dict[str, list[float]] = {label: [] for label, _, _ in configs}
    cpu: dict[str, list[float]] = {label: [] for label, _, _ in configs}
    for w in paths:  # interleaved: every method on this path, then the next path
        for label, method, checker in configs:
            t0, c0 = time.perf_counter(), time.process_time()
            traj = time_path(design, w, limits, method=method, check_states=checker)
            wall[label].append(time.perf_counter() - t0)
            cpu[label].append(time.process_time() - c0)
            results[label].append(traj)
    for label, _, _ in configs:
        trajs = results[label]
        print(
            f"{label:<26} {1e3 * pct(wall[label], 50):>14.2f} {1e3 * pct(wall[label], 95):>7.2f} "
            f"{1e3 * pct(cpu[label], 50):>13.2f} {1e3 * pct(cpu[label], 95):>7.2f} "
            f"{sum(t.repairs for t in trajs):>8d} "
            f"{statistics.median(t.max_deviation_q for t in trajs):>14.4f}"
        )
    print("goal: toppra p50 <= 10 ms including the dense re-check (cpu: this process only, so")
    print("      other load on the machine does not count; wall: elapsed time)")

    print()
    print("goals (issue 16), side by side: computation time (cpu p50, the runs above) and")
    print("duration (default limits: jerk = 25 x acceleration)")
    print(
        f"{'checker':<12} {'toppra p50 [ms]':>16} {'ruckig p50 [ms]':>16} {'ruckig/toppra':>14} "
        f"{'goal':>6} {'duration ratio p50':>19} {'max':>7} {'goal':>7}"
    )
    for name, suffix in (("none", ""), ("kappa(A)", " + kappa(A) check")):
        top, ruck = cpu["toppra" + suffix], cpu["ruckig" + suffix]
        ratio = [
            r.duration / t.duration
            for r, t in zip(results["ruckig" + suffix], results["toppra" + suffix], strict=True)
        ]
        print(
            f"{name:<12} {1e3 * pct(top, 50):>16.2f} {1e3 * pct(ruck, 50):>16.2f} "
            f"{pct(ruck, 50) / pct(top, 50):>14.3f} {'<= 1':>6} {pct(ratio, 50):>19.3f} "
            f"{max(ratio):>7.3f} {'<= 1.2':>7}"
        )

    print()
    print("duration relative to toppra (same v, a; toppra blends 0.05 rad)")
    print(
        f"{'jerk / acceleration [1/s]':<26} {'ruckig p50':>11} {'p95':>7} {'max':>7} "
        f"{'rest-at-every-waypoint p50':>27} {'ruckig dev max [rad]':>21}"
    )
    top = [t.duration for t in results["toppra"]]
    for ratio_ja in (10.0, 25.0, 50.0):
        lim = JointLimits(
            limits.velocity, limits.acceleration, tuple(a * ratio_ja for a in limits.acceleration)
        )
        r_blend, r_stop, devs = [], [], []
        for w, t_top in zip(paths, top, strict=True):
            blend = time_path(design, w, lim, method="ruckig")
            stop = time_path(design, w, lim, method="ruckig", max_deviation=0.0)
            r_blend.append(blend.duration / t_top)
            r_stop.append(stop.duration / t_top)
            devs.append(blend.max_deviation_q)
        print(
            f"{ratio_ja:<26.0f} {pct(r_blend, 50):>11.3f} {pct(r_blend, 95):>7.3f} "
            f"{max(r_blend):>7.3f} {pct(r_stop, 50):>27.3f} {max(devs):>21.4f}"
        )
    print("goal: ruckig duration <= 1.2x toppra (the default jerk is 25 x acceleration)")

    print()
    print("repairs: a small forbidden box inside one corner per path (blend passes through it)")
    print(
        f"{'method':<10} {'cases':>6} {'returned':>9} {'repaired':>9} {'refused':>8} "
        f"{'repairs max':>12} {'wall p50 [ms]':>14}"
    )
    cases = []
    for i, w in enumerate(paths):
        box = corner_box_checker(w, 1 + i % (args.waypoints - 2))
        if box is not None:
            cases.append((w, box))
    for method in ("toppra", "ruckig"):
        ok, refused, reps, times = 0, 0, [], []
        for w, box in cases:
            t0 = time.perf_counter()
            try:
                traj = time_path(design, w, limits, method=method, check_states=box)
            except TrajectoryCheckError:
                refused += 1
                continue
            times.append(time.perf_counter() - t0)
            ok += 1
            reps.append(traj.repairs)
        print(
            f"{method:<10} {len(cases):>6d} {ok:>9d} {sum(r > 0 for r in reps):>9d} "
            f"{refused:>8d} {max(reps, default=0):>12d} "
            f"{1e3 * statistics.median(times) if times else float('nan'):>14.2f}"
        )
    print("every returned trajectory passed the dense re-check (time_path never returns one")
    print("that does not); refused = TrajectoryCheckError")


if __name__ == "__main__":
    main()
