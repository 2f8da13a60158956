"""Throughput of the vectorised kinematics against a per-posture Python loop.

    .venv/bin/python benchmarks/kinematics.py [--n 1000000] [--repeat 7]

Prints postures per second (median of repeats) for forward kinematics, inverse kinematics
(postures = points x 8 working modes) and conditioning at N postures, each against the
scalar ``Manipulator`` API called in a plain Python loop over a small sample, as a ratio.
One core: numba kernels run single-threaded.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np
from _machine import print_machine

from planner import Design, Manipulator, conditioning, forward_batch, inverse_batch


def median_seconds(fn: Callable[[], object], repeat: int) -> float:
    fn()  # warm-up (compilation, caches)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    print_machine()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1_000_000)
    parser.add_argument("--loop-n", type=int, default=2_000, help="postures in the Python loop")
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()

    design = Design.default()
    manipulator = Manipulator(design)
    rng = np.random.default_rng(0)
    q = rng.uniform(-np.pi, np.pi, size=(args.n, 3))
    batch = forward_batch(design, q, "+")
    p = np.ascontiguousarray(batch.p[batch.ok])
    small_q = q[: args.loop_n]
    small_p = p[: args.loop_n]
    postures = [manipulator.posture(x, "+") for x in small_q]

    rows = []
    t_vec = median_seconds(lambda: forward_batch(design, q, "+"), args.repeat)
    t_loop = median_seconds(lambda: [manipulator.posture(x, "+") for x in small_q], 3)
    rows.append(("forward", args.n / t_vec, len(small_q) / t_loop))

    t_vec = median_seconds(lambda: inverse_batch(design, p), args.repeat)
    t_loop = median_seconds(lambda: [manipulator.inverse(x) for x in small_p], 3)
    rows.append(("inverse (x8 modes)", 8 * len(p) / t_vec, 8 * len(small_p) / t_loop))

    t_vec = median_seconds(
        lambda: conditioning(design, batch.q, batch.passive, batch.w), args.repeat
    )
    t_loop = median_seconds(lambda: [manipulator.conditioning(x) for x in postures], 3)
    rows.append(("conditioning", args.n / t_vec, len(postures) / t_loop))

    print(f"kinematics, N = {args.n:,} postures, median of {args.repeat}, one core")
    print(f"{'quantity':<20} {'vectorised [M/s]':>17} {'python loop [k/s]':>18} {'ratio':>8}")
    for name, vec, loop in rows:
        print(f"{name:<20} {vec / 1e6:>17.2f} {loop / 1e3:>18.1f} {vec / loop:>8.0f}")
    print("goal: forward >= 15 M postures/s")


if __name__ == "__main__":
    main()
