"""The regression checks of issue 36: detours through other working modes, and the mode choice
for time against brute force. Prints two tables; ``python benchmarks/regression.py``.

    .venv/bin/python benchmarks/regression.py [--queries 100] [--sequences 20] [--seed 36]

* **Free-space queries** (``--queries``): random designs (L0, L1 in [0.2, 0.35] m, L2 in
  [0.4, 0.7] m), random start and goal joint postures, each valid in its own working mode,
  on a grid of the joint box (theta1 random). Each query is placed by two routes: the
  product's region map (``planner.analysis.regions``, the planner's ``PROOF_RESOLUTION``) and
  an independent flood written here (a 257 x 257 grid per mode, 4-connected, from the
  validity checker alone; two modes one sign apart joined where a component of their
  *band*, the grid postures valid for every rule but the serial margin of the flipped
  measure, the other two signs kept with it, touches both). The table counts, for the
  queries both place in one component, how many :func:`planner.planning.plan` solved (goal:
  all) and how many needed a detour back into the start's own mode; and for those both
  place apart, how many were proven ``no_path`` (goal: all).
* **Mode choice for time** (``--sequences``): random designs, a cycle through two Cartesian
  targets in working mode "any" (points of random valid postures, stops or passes at
  random), ``objective="time"`` against brute force over all 64 assignments of the eight
  modes, each planned and timed as a "fixed" sequence. The table counts the sequences where
  they agree (goal: all), those whose best assignment crosses the axis, and the assignments
  the search timed against brute force's.
"""

from __future__ import annotations

import argparse
import itertools
import math
import statistics
import sys
import time

import numpy as np
from _machine import print_machine
from scipy import ndimage

from planner import SequenceTarget, solve_sequence
from planner.analysis import regions as R
from planner.design import Design
from planner.exceptions import InputError
from planner.kinematics import WORKING_MODES, forward_batch
from planner.planning import CartesianTarget, JointPosture, PlanOptions, PlanStatus, plan
from planner.planning.proofs import PROOF_RESOLUTION
from planner.timing import JointLimits
from planner.validity import Margins, ValidityChecker

MARGINS = Margins(kappa_max=10.0, serial_min=0.05, clearance=0.01)
GRID = 257


def random_design(rng: np.random.Generator) -> Design:
    l0, l1, l2 = rng.uniform([0.2, 0.2, 0.4], [0.35, 0.35, 0.7])
    return Design(float(l0), float(l1), float(l2), link_radius=0.01)


class Flood:
    """The independent flood of one design and assembly mode: component labels per mode on
    the grid, joined across modes through the bands of the transits (module docstring)."""

    def __init__(self, design: Design, asm: str) -> None:
        self.t2 = np.linspace(design.joint_min[1], design.joint_max[1], GRID)
        self.t3 = np.linspace(design.joint_min[2], design.joint_max[2], GRID)
        g3, g2 = np.meshgrid(self.t3, self.t2, indexing="ij")
        q = np.stack([np.zeros(g2.size), g2.ravel(), g3.ravel()], axis=1)
        self.labels = np.zeros((8, GRID, GRID), dtype=np.int64)
        offset = 0
        for mi, mode in enumerate(WORKING_MODES):
            valid = ValidityChecker(design, MARGINS, (), asm, mode).is_valid(q)
            lab, n = ndimage.label(valid.reshape(GRID, GRID))
            self.labels[mi] = np.where(lab > 0, lab + offset, 0)
            offset += n
        parent = list(range(offset + 1))

        def find(a: int) -> int:
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            return a

        free = ValidityChecker(design, MARGINS, (), asm, "+++", serial_rules=False).is_valid(q)
        fb = forward_batch(design, q, asm)
        measures = np.nan_to_num(fb.serial_measures, nan=0.0)
        for mi, a in enumerate(WORKING_MODES):
            for j in range(3):
                b = a[:j] + ("-" if a[j] == "+" else "+") + a[j + 1 :]
                mj = WORKING_MODES.index(b)
                if mj < mi:
                    continue
                band = free & fb.ok
                for k in range(3):
                    if k != j:
                        sign = 1.0 if a[k] == "+" else -1.0
                        band &= sign * measures[:, k] >= MARGINS.serial_min
                lab, _ = ndimage.label(band.reshape(GRID, GRID))
                joined: dict[int, int] = {}
                for mode_labels in (self.labels[mi], self.labels[mj]):
                    both = (mode_labels > 0) & (lab > 0)
                    for band_id, comp in zip(lab[both], mode_labels[both], strict=True):
                        if band_id in joined:
                            ra, rb = find(joined[band_id]), find(int(comp))
                            parent[ra] = rb
                        else:
                            joined[int(band_id)] = int(comp)
        self.find = find

    def component(self, mi: int, k3: int, k2: int) -> int:
        lab = int(self.labels[mi, k3, k2])
        return self.find(lab) if lab else 0

    def random_point(self, rng: np.random.Generator, design: Design):
        """A grid posture valid in its mode (theta1 random): (q, mode index, component)."""
        filled = np.flatnonzero(self.labels.reshape(-1))
        a = int(filled[rng.integers(len(filled))])
        mi, rest = divmod(a, GRID * GRID)
        k3, k2 = divmod(rest, GRID)
        th1 = rng.uniform(design.joint_min[0], design.joint_max[0])
        return np.array([th1, self.t2[k2], self.t3[k3]]), mi, self.component(mi, k3, k2)


def flood_mode(design: Design, q: np.ndarray, asm: str) -> int:
    """Index of the working mode of posture q (its signs)."""
    signs = forward_batch(design, q, asm).working_mode_signs[0]
    return WORKING_MODES.index("".join("+" if x > 0 else "-" for x in signs))


def map_components(rmap: R.RegionMap, q: np.ndarray, asm: str, mode: str) -> set[int]:
    return {r.component for r in R.regions_at(rmap, q, asm) if r.working_mode == mode}


def queries(n: int, rng: np.random.Generator) -> None:
    rows = {"joined": 0, "solved": 0, "detours": 0, "apart": 0, "proven": 0, "undecided": 0}
    times: list[float] = []
    failures: list[str] = []
    done = 0
    while done < n:
        design = random_design(rng)
        asm = "+-"[int(rng.integers(2))]
        flood = Flood(design, asm)
        rmap = R.region_map(design, MARGINS, PROOF_RESOLUTION)
        for _ in range(5):
            if done >= n:
                break
            qa, ma, ca = flood.random_point(rng, design)
            qb, mb, cb = flood.random_point(rng, design)
            mapped_a = map_components(rmap, qa, asm, WORKING_MODES[ma])
            mapped_b = map_components(rmap, qb, asm, WORKING_MODES[mb])
            map_joined = bool(mapped_a & mapped_b)
            done += 1
            if map_joined != (ca == cb):
                rows["undecided"] += 1  # the two routes disagree: counted, not planned
                continue
            t = time.perf_counter()
            res = plan(
                design,
                JointPosture(qa, asm),
                JointPosture(qb, asm),
                margins=MARGINS,
                options=PlanOptions(time_budget_s=10.0, seed=done),
            )
            times.append(time.perf_counter() - t)
            if map_joined:
                rows["joined"] += 1
                rows["solved"] += res.solved
                rows["detours"] += "which no path inside the mode joins" in res.message
                if not res.solved:
                    failures.append(f"{design} {qa.tolist()} -> {qb.tolist()} {asm}: {res.message}")
            else:
                rows["apart"] += 1
                rows["proven"] += (
                    res.status is PlanStatus.NO_PATH and res.diagnostics.proven_infeasible
                )
            print(f"query {done}/{n}: {res.status.value}", file=sys.stderr, flush=True)
    print(f"\nfree-space joint queries: {n} (seeded), plan budget 10 s")
    print(
        f"{'queries joined by both':>28} {'solved':>7} {'via detour':>11} "
        f"{'apart by both':>14} {'proven':>7} {'routes disagree':>16} {'p50 plan s':>11}"
    )
    print(
        f"{rows['joined']:>28} {rows['solved']:>7} {rows['detours']:>11} {rows['apart']:>14} "
        f"{rows['proven']:>7} {rows['undecided']:>16} {statistics.median(times):>11.3f}"
    )
    for line in failures:
        print("  not solved:", line)


def sequences(n: int, rng: np.random.Generator) -> None:
    agree = crossing = timed = brute_timed = 0
    worst = 0.0
    limits = JointLimits(velocity=(2.0, 2.0, 2.0), acceleration=(10.0, 10.0, 10.0))
    done = 0
    while done < n:
        design = random_design(rng)
        asm = "+-"[int(rng.integers(2))]
        flood = Flood(design, asm)
        qs, _, _ = flood.random_point(rng, design)
        start = JointPosture(qs, asm)
        points = [
            forward_batch(design, flood.random_point(rng, design)[0], asm).p[0] for _ in range(2)
        ]
        stops = rng.uniform(size=2) < 0.5
        targets = [
            SequenceTarget(CartesianTarget(p), stop=bool(s), blend=0.0 if s else 0.02)
            for p, s in zip(points, stops, strict=True)
        ]
        brute = {}
        for modes in itertools.product(WORKING_MODES, repeat=2):
            fixed = [
                SequenceTarget(CartesianTarget(t.goal.p, m), t.stop, t.blend)
                for t, m in zip(targets, modes, strict=True)
            ]
            try:
                r = solve_sequence(
                    design,
                    start,
                    fixed,
                    cycle=True,
                    objective="fixed",
                    margins=MARGINS,
                    limits=limits,
                )
            except InputError:  # a blend too long for this assignment's legs
                continue
            brute[modes] = r.cycle_time if r.solved else math.inf
        finite = {k: v for k, v in brute.items() if math.isfinite(v)}
        if len(finite) < 2:
            continue  # not a choice
        done += 1
        best_time, best_modes = min((v, k) for k, v in finite.items())
        r = solve_sequence(
            design, start, targets, cycle=True, objective="time", margins=MARGINS, limits=limits
        )
        same = r.solved and math.isclose(r.cycle_time, best_time, rel_tol=1e-9)
        agree += same
        side = WORKING_MODES[flood_mode(design, qs, asm)][0]
        crossing += any(m[0] != side for m in best_modes)
        timed += r.diagnostics.estimates
        brute_timed += len(finite)
        if r.solved:
            worst = max(worst, r.cycle_time / best_time - 1.0)
        print(
            f"sequence {done}/{n}: {'agrees' if same else 'differs'}", file=sys.stderr, flush=True
        )
    print(f"\nmode choice for time: {n} seeded cycles through two 'any' targets, 64 assignments")
    print(
        f"{'sequences':>10} {'= brute force':>14} {'best crosses axis':>20} "
        f"{'worst excess':>13} {'timed (search)':>15} {'solved (brute)':>15}"
    )
    print(f"{n:>10} {agree:>14} {crossing:>20} {worst:>12.2%} {timed:>15} {brute_timed:>15}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--queries", type=int, default=100)
    parser.add_argument("--sequences", type=int, default=20)
    parser.add_argument("--seed", type=int, default=36)
    args = parser.parse_args()
    print_machine()
    rng = np.random.default_rng(args.seed)
    queries(args.queries, rng)
    sequences(args.sequences, rng)


if __name__ == "__main__":
    main()
