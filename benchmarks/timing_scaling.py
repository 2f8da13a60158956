"""Timing through many via points: computation time against the number of waypoints.

    .venv/bin/python benchmarks/timing_scaling.py [--sizes 5 20 100 500] [--paths 3]

Seeded random joint-space walks (steps uniform in +-0.5 rad per joint, kept in +-2.5 rad;
the reversals there are stops), default design and limits, a kappa(A) validity checker.
Each path is timed by both methods twice, interleaved: with the caches of ``time_path``
(a repair round solves again only the rest-to-rest sections its repair changed) and without
them (every section and move solved again in every round, as before issue 26). Columns:
wall p50 (ms), ms per waypoint, repair rounds, toppra sections and Ruckig candidate moves
solved over all rounds.

Goal (issue 26): both methods linear in the number of waypoints (ms per waypoint flat).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from _machine import print_machine

from planner import Design, conditioning, forward_batch
from planner.timing import JointLimits, ruckig_method, time_path, toppra_method


def random_walk(rng: np.random.Generator, n: int) -> np.ndarray:
    return np.clip(np.cumsum(rng.uniform(-0.5, 0.5, size=(n, 3)), axis=0), -2.5, 2.5)


def kappa_checker(design: Design, kappa_max: float = 50.0):
    def check(q: np.ndarray) -> np.ndarray:
        batch = forward_batch(design, q, "+")
        cond = conditioning(design, batch.q, batch.passive, batch.w)
        return batch.ok & (np.nan_to_num(cond.kappa_A, nan=np.inf) <= kappa_max)

    return check


class Work:
    """Counts toppra sections solved and Ruckig moves solved (module functions wrapped)."""

    def __init__(self) -> None:
        self.sections = self.moves = 0
        self._grid, self._calc = toppra_method.section_grid, ruckig_method._calculate
        self._key = toppra_method.section_key
        toppra_method.section_grid = self._count_grid
        ruckig_method._calculate = self._count_calc

    def _count_grid(self, *args, **kwargs):
        self.sections += 1
        return self._grid(*args, **kwargs)

    def _count_calc(self, *args, **kwargs):
        self.moves += 1
        return self._calc(*args, **kwargs)

    def caches(self, on: bool) -> None:
        """With the caches, or with every key unique (nothing is ever found)."""
        key = self._key if on else (lambda *a: object())
        toppra_method.section_key = key
        ruckig_method.section_key = key


def main() -> None:
    print_machine()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[5, 20, 100, 500])
    parser.add_argument("--paths", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    design, limits = Design.default(), JointLimits.default()
    check = kappa_checker(design)
    rng = np.random.default_rng(args.seed)
    work = Work()
    time_path(design, random_walk(rng, 5), limits, method="ruckig", check_states=check)
    print(f"time_path on {args.paths} seeded random walks per size, kappa(A) checker, one process")
    print()
    print(
        f"{'method':<8} {'caches':<7} {'waypoints':>9} {'wall p50 [ms]':>14} "
        f"{'ms/waypoint':>12} {'repairs':>8} {'sections':>9} {'moves':>7}"
    )
    rows: dict[tuple, list] = {}
    for n in args.sizes:
        paths = [random_walk(rng, n) for _ in range(args.paths)]
        for w in paths:
            for method in ("toppra", "ruckig"):
                for on in (True, False):
                    work.caches(on)
                    work.sections = work.moves = 0
                    t0 = time.perf_counter()
                    traj = time_path(design, w, limits, method=method, check_states=check)
                    dt = time.perf_counter() - t0
                    rows.setdefault((method, on, n), []).append(
                        (dt, traj.repairs, work.sections, work.moves)
                    )
    work.caches(True)
    for method in ("toppra", "ruckig"):
        for on in (True, False):
            for n in args.sizes:
                r = rows[(method, on, n)]
                wall = statistics.median(x[0] for x in r)
                print(
                    f"{method:<8} {'on' if on else 'off':<7} {n:>9d} {1e3 * wall:>14.1f} "
                    f"{1e3 * wall / n:>12.3f} {sum(x[1] for x in r):>8d} "
                    f"{sum(x[2] for x in r):>9d} {sum(x[3] for x in r):>7d}"
                )
    print("goal (issue 26): ms/waypoint flat in the number of waypoints, both methods")


if __name__ == "__main__":
    main()
