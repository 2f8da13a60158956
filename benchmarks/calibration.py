"""Kinematic calibration: suggested postures against as many random ones.

    .venv/bin/python benchmarks/calibration.py [--robots 10] [--noise-mm 0.05] [--sizes 20,30,50]

For each of --robots seeded "as built" robots (the default design with lengths +-2 mm,
actuator offsets +-0.5 deg, tracker frame +-10 mm / 1 deg), N postures are measured with
Gaussian noise of --noise-mm per coordinate, either the N of ``suggest_poses`` (greedy
D-optimal over the valid set) or N drawn uniformly from the same valid set; each set is
calibrated (lengths, offsets, frame) and the identified model predicts P at 500 held-out
valid postures. Printed: the median and worst (over robots) held-out RMS error of P, mm, of
each choice, their ratio, and the median condition number and calibration time.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from _machine import print_machine

from planner import Design
from planner.calibration import Measurements, calibrate, suggest_poses
from planner.calibration.model import FULL_NAMES, loop_state, rotation_matrix
from planner.calibration.poses import valid_sample

NOMINAL = Design.default()


def as_built(seed: int) -> np.ndarray:
    """A perturbed robot's full parameter vector (legs equal)."""
    rng = np.random.default_rng(seed)
    full = np.zeros(len(FULL_NAMES))
    full[:5] = (NOMINAL.L0, NOMINAL.L1, NOMINAL.L1, NOMINAL.L2, NOMINAL.L2)
    dl = rng.uniform(-0.002, 0.002, size=3)
    full[:5] += (dl[0], dl[1], dl[1], dl[2], dl[2])
    full[5:8] = np.radians(rng.uniform(-0.5, 0.5, size=3))
    full[8:11] = rng.uniform(-0.01, 0.01, size=3)
    full[11:14] = np.radians(rng.uniform(-1.0, 1.0, size=3))
    return full


def observe(full: np.ndarray, q: np.ndarray, modes: list[str]) -> np.ndarray:
    """P of the robot ``full`` in its tracker's frame (noise-free)."""
    branch = np.where(np.asarray(modes) == "+", 1.0, -1.0)
    return (loop_state(full, q, branch).p3 - full[8:11]) @ rotation_matrix(full[11:14])


def held_out_rms(full, result, q, modes) -> float:
    branch = np.where(np.asarray(modes) == "+", 1.0, -1.0)
    err = result.predict(q, branch) - observe(full, q, modes)
    return float(np.sqrt(np.mean(np.sum(err**2, axis=1))))


def run(robots: int, noise: float, sizes: list[int]) -> None:
    pool = valid_sample(NOMINAL, 20000, 12345)
    rng = np.random.default_rng(7)
    test = rng.choice(len(pool.q), size=500, replace=False)
    q_test, m_test = pool.q[test], [pool.assembly_mode[i] for i in test]
    print(f"noise {noise * 1e3:g} mm per coordinate, {robots} robots, 500 held-out postures")
    print()
    print(
        "| N | suggested: median / worst RMS (mm) | random: median / worst RMS (mm) | random / suggested | cond. suggested / random | fit time (ms) |"
    )
    print("|---|---|---|---|---|---|")
    for n in sizes:
        poses = suggest_poses(NOMINAL, n, seed=1)
        rows: dict[str, list[float]] = {"s": [], "r": [], "cs": [], "cr": [], "t": []}
        for k in range(robots):
            full = as_built(100 + k)
            noise_rng = np.random.default_rng(1000 + k)
            pick = noise_rng.choice(len(pool.q), size=n, replace=False)
            for key, q, modes in (
                ("s", poses.q, poses.assembly_mode),
                ("r", pool.q[pick], [pool.assembly_mode[i] for i in pick]),
            ):
                p = observe(full, q, modes) + noise_rng.normal(0, noise, size=(n, 3))
                t0 = time.perf_counter()
                result = calibrate(NOMINAL, Measurements(q, p))
                rows["t"].append(time.perf_counter() - t0)
                rows[key].append(held_out_rms(full, result, q_test, m_test) * 1e3)
                rows["c" + key].append(result.condition_number)
        ms, mr = statistics.median(rows["s"]), statistics.median(rows["r"])
        print(
            f"| {n} | {ms:.4f} / {max(rows['s']):.4f} | {mr:.4f} / {max(rows['r']):.4f} | "
            f"{mr / ms:.2f} | {statistics.median(rows['cs']):.1f} / "
            f"{statistics.median(rows['cr']):.1f} | {statistics.median(rows['t']) * 1e3:.1f} |"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=10)
    parser.add_argument("--noise-mm", type=float, default=0.05)
    parser.add_argument("--sizes", default="20,30,50")
    args = parser.parse_args()
    print_machine()
    run(args.robots, args.noise_mm * 1e-3, [int(x) for x in args.sizes.split(",")])


if __name__ == "__main__":
    main()
