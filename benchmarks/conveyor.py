"""Picking from a moving belt: picks per minute, parts missed, the interception against brute
force, and the planning time of one pick.

    .venv/bin/python benchmarks/conveyor.py [--parts 20] [--cases 50]

* A stream of parts: a belt along x (y = 0, z = -0.45 m) at 0.1 / 0.25 / 0.5 / 1 m/s, parts
  entering at x = -0.75 m at random spacing (0.1 to 0.4 m apart, seeded), each picked
  (``dwell`` 0.1 s) and placed at a fixed bin (-0.2, 0.25, -0.45) m, a stop, cycle after
  cycle: the robot plans each pick from where it rests (``planner.solve_sequence`` with the
  part's ``t0`` on its clock); a part it can no longer meet (``unreachable``) is missed and
  the next one taken. Picks per minute over the time the robot rests at the bin after its
  last pick (and the parts offered per minute: at 0.1 m/s the arrivals set the rate);
  beside it the same parts with the working modes held fixed (the bin's mode) and the
  all-stops rate: the same parts picked at rest at the same points (:func:`all_stops_rate`:
  the belt halted for each pick, bin -> point, ``dwell`` at rest, -> bin as a stop sequence).
  Per design (the default 0.5 / 0.2 / 0.6 and 0.4 / 0.3 / 0.5) and limits (the default
  2 rad/s, 8 rad/s^2 and a fast 4 rad/s, 30 rad/s^2).
* The interception against brute force: ``--cases`` seeded parts (speed 0.1-1 m/s, line and
  dwell random), the search's cost (when the tool rests at the bin) against the least cost
  over every meeting time on a 1 ms grid (the same cost function, the product's
  :meth:`~planner.sequence.interception.Interception.costs`; the test suite checks 4 cases
  against an independent route): the largest excess, %. Goal: within 2 % on all.
* Planning + timing of one pick (the part and the bin, modes for time), p50 in process.
  Goal: <= 50 ms.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np
from _machine import print_machine

from planner import Design, SequenceTarget, solve_sequence
from planner.kinematics import WORKING_MODES, inverse_batch
from planner.planning import CartesianTarget, JointPosture
from planner.sequence.belt import scan_part
from planner.sequence.interception import Interception, intercept
from planner.sequence.problem import MovingTarget
from planner.timing import JointLimits
from planner.timing.state_moves import StateMover
from planner.validity import Margins, ValidityChecker

BIN = np.array([-0.2, 0.25, -0.45])
ENTRY = np.array([-0.75, 0.0, -0.45])
MODE = "+-+"
DWELL = 0.1
SPEEDS = (0.1, 0.25, 0.5, 1.0)
DESIGNS = {"default 0.5/0.2/0.6": Design.default(), "0.4/0.3/0.5": Design(0.4, 0.3, 0.5)}
LIMITS = {
    "2 rad/s, 8 rad/s^2": JointLimits.default(),
    "4 rad/s, 30 rad/s^2": JointLimits(velocity=(4.0,) * 3, acceleration=(30.0,) * 3),
}


def bin_posture(design: Design) -> JointPosture:
    return JointPosture(inverse_batch(design, BIN).q[0, WORKING_MODES.index(MODE)], "+")


def arrivals(speed: float, n: int, seed: int) -> np.ndarray:
    """When each part enters at ENTRY, s: gaps of 0.1-0.4 m of belt."""
    gaps = np.random.default_rng(seed).uniform(0.1, 0.4, n) / speed
    return np.cumsum(gaps) - gaps[0]


def stream(design, limits, speed, n, seed, mode="any"):
    """Picks, missed, picks per minute, and the picked parts' arrivals and meeting points."""
    here, clock = bin_posture(design), 0.0
    missed, picked = 0, []
    for a in arrivals(speed, n, seed):
        part = MovingTarget(ENTRY, mode, [speed, 0.0, 0.0], float(a - clock))
        targets = [SequenceTarget(part, dwell=DWELL), SequenceTarget(CartesianTarget(BIN))]
        r = solve_sequence(design, here, targets, limits=limits)
        if not r.solved:
            missed += 1
            continue
        picked.append((float(a), np.array(r.legs[0].meet_point)))
        clock += r.cycle_time
        here = JointPosture(r.trajectory.q[-1], "+")
    rate = 60.0 * len(picked) / clock if clock > 0 else 0.0
    return len(picked), missed, rate, picked


def all_stops_rate(design, limits, speed, picked) -> float:
    """The same parts picked at rest at the same points: the belt halts while a part is at
    its pick point until the dwell ends (every later part delayed as much); the robot moves
    bin -> point -> bin as a stop sequence (planned and timed), leaving the bin so as to
    arrive when the part does (or at once, when it is late)."""
    clock, delay = 0.0, 0.0
    for a, p in picked:
        targets = [SequenceTarget(CartesianTarget(p)), SequenceTarget(CartesianTarget(BIN))]
        r = solve_sequence(design, bin_posture(design), targets, limits=limits)
        if not r.solved:
            return math.nan
        t_in = r.legs[0].end_time
        t_part = a + delay + (p[0] - ENTRY[0]) / speed
        meet = max(clock + t_in, t_part)
        delay += meet + DWELL - t_part
        clock = meet + DWELL + (r.cycle_time - t_in)
    return 60.0 * len(picked) / clock if clock else math.nan


def stream_table(n_parts: int) -> None:
    print(f"\n## A stream of parts ({n_parts} per row, dwell {DWELL} s, bin {BIN.tolist()} m)\n")
    print(
        "| design | limits | belt m/s | parts/min offered | picks/min (modes for time) | "
        "missed | picks/min (modes fixed) | missed | all-stops picks/min | belt / all-stops |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for dname, design in DESIGNS.items():
        for lname, limits in LIMITS.items():
            for k, speed in enumerate(SPEEDS):
                _, missed, rate, picked = stream(design, limits, speed, n_parts, k)
                _, missed_f, rate_f, _ = stream(design, limits, speed, n_parts, k, MODE)
                stops = all_stops_rate(design, limits, speed, picked)
                offered = 60.0 * (n_parts - 1) / float(arrivals(speed, n_parts, k)[-1])
                print(
                    f"| {dname} | {lname} | {speed:g} | {offered:.1f} | {rate:.1f} | {missed} "
                    f"| {rate_f:.1f} "
                    f"| {missed_f} | {stops:.1f} | {rate / stops:.2f} |"
                )


def brute_force_table(cases: int) -> None:
    design, limits = Design.default(), JointLimits.default()
    start = bin_posture(design)
    excess, solved = [], 0
    for seed in range(cases):
        rng = np.random.default_rng(1000 + seed)
        speed = rng.uniform(0.1, 1.0)
        p = [-0.75, rng.uniform(-0.1, 0.1), rng.uniform(-0.5, -0.4)]
        part = MovingTarget(p, MODE, [speed, 0.0, 0.0], rng.uniform(0.0, 0.5))
        dwell = float(rng.uniform(0.1, 0.3))
        targets = [SequenceTarget(part, dwell=dwell), SequenceTarget(CartesianTarget(BIN))]
        r = solve_sequence(design, start, targets)
        checker = ValidityChecker(design, Margins(), (), "+", MODE)
        path = scan_part(design, part, checker, limits, np.asarray(start.q), -math.inf)
        landing = inverse_batch(design, BIN).q[0, WORKING_MODES.index(MODE)]
        ic = Interception(
            design,
            part,
            dwell,
            checker,
            limits,
            StateMover(limits, jerk=False),
            path,
            np.asarray(start.q),
            0.0,
            landing,
        )
        grid = np.arange(0.0, float(path.t[-1]), 1e-3)
        best = float(np.min(ic.costs(grid))) if grid.size else math.inf
        if not math.isfinite(best):
            assert not r.solved and not intercept(ic)
            continue
        solved += 1
        # a case the search did not solve while the grid did counts as an infinite excess
        excess.append(100.0 * (r.legs[1].end_time - best) / best if r.solved else math.inf)
    print(f"\n## Interception against brute force ({cases} seeded cases, {solved} solvable)\n")
    print("| largest excess over the 1 ms grid's best | median | cases within 2 % |")
    print("|---|---|---|")
    within = sum(e <= 2.0 for e in excess)
    print(f"| {max(excess):+.3f} % | {statistics.median(excess):+.3f} % | {within} / {solved} |")


def pick_time_table(repeats: int) -> None:
    """Wall and CPU time (``time.process_time``: what the pick costs this process, whatever
    else shares the cores) of one pick, p50."""
    design = Design.default()
    start = bin_posture(design)
    rows = {}
    for mode in ("any", MODE):
        wall, cpu = [], []
        for k in range(repeats):
            part = MovingTarget(ENTRY, mode, [0.5, 0.0, 0.0], 0.05 * k)
            targets = [SequenceTarget(part, dwell=DWELL), SequenceTarget(CartesianTarget(BIN))]
            t, c = time.perf_counter(), time.process_time()
            r = solve_sequence(design, start, targets)
            wall.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
            assert r.solved, r.message
        rows[mode] = (1e3 * statistics.median(wall), 1e3 * statistics.median(cpu))
    print(f"\n## Planning + timing of one pick (p50 of {repeats}, in process)\n")
    print("| | modes for time (any) | mode given |")
    print("|---|---|---|")
    print(f"| wall | {rows['any'][0]:.0f} ms | {rows[MODE][0]:.0f} ms |")
    print(f"| CPU of this process | {rows['any'][1]:.0f} ms | {rows[MODE][1]:.0f} ms |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", type=int, default=20)
    parser.add_argument("--cases", type=int, default=50)
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--tables", default="pick,brute,stream", help="which tables, comma list")
    args = parser.parse_args()
    tables = set(args.tables.split(","))
    print_machine()
    solve_sequence(
        Design.default(),
        bin_posture(Design.default()),
        [
            SequenceTarget(MovingTarget(ENTRY, MODE, [0.5, 0, 0]), dwell=DWELL),
            SequenceTarget(CartesianTarget(BIN)),
        ],
    )  # warm-up
    if "pick" in tables:
        pick_time_table(args.repeats)
    if "brute" in tables:
        brute_force_table(args.cases)
    if "stream" in tables:
        stream_table(args.parts)


if __name__ == "__main__":
    main()
