"""Region maps (``planner.analysis.regions``): build time, regions per mode, proof time and
false proofs over seeded solved queries. Prints a table; ``python benchmarks/regions.py``.

Build times are medians of 5 cold builds (cache cleared) on one core, after a warm-up
that loads the numba kernel. False proofs: seeded queries (both ends valid, same assembly
mode) are planned with ``planner.planning.plan``; a solved query the map proves
disconnected would be a false proof (the count must be 0). ``--queries N`` (default 1000).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from _machine import print_machine

from planner.analysis import regions as R
from planner.design import Design
from planner.kinematics import WORKING_MODES, forward_batch
from planner.planning import JointPosture, PlanOptions, plan
from planner.validity import Margins, ValidityChecker

DESIGNS = {
    "singularity-free 0.5/0.2/0.6 (P off axis, 2L1<L0)": Design.default(),
    "mode-change 0.6/0.25/0.45 (P reaches the axis, 2L1<L0)": Design(0.6, 0.25, 0.45),
    "general 0.3/0.3/0.4 (P reaches the axis, 2L1>L0)": Design(0.3, 0.3, 0.4),
    "paper optimum 0/0.4/0.4": Design.paper_optimum(),
}
CUT = Design(0.3, 0.3, 0.4, joint_min=(-3.14, -0.49, -2.81), joint_max=(3.14, 0.51, -1.72))


def build_times() -> None:
    print("| design | n = 128 | n = 256 | n = 512 | regions per mode, asm + (certified) |")
    print("|---|---|---|---|---|")
    R.region_map(Design.default(), n=16)  # load the kernel
    for name, design in DESIGNS.items():
        cells = []
        for n in (128, 256, 512):
            runs = []
            for _ in range(5):
                R.clear_cache()
                t0 = time.perf_counter()
                R.region_map(design, n=n)
                runs.append(time.perf_counter() - t0)
            cells.append(f"{statistics.median(runs) * 1e3:.1f} ms")
        rmap = R.region_map(design, n=256)
        over, cert = rmap.region_count(), rmap.region_count(certified=True)
        per = " ".join(f"{m}:{over[0, k]}({cert[0, k]})" for k, m in enumerate(WORKING_MODES))
        print(f"| {name} | {' | '.join(cells)} | {per} |")


def _valid(design, rng):
    while True:
        q = rng.uniform(design.joint_min, design.joint_max)
        asm = "+-"[int(rng.integers(2))]
        fb = forward_batch(design, q, asm)
        if not fb.ok[0] or np.any(fb.working_mode_signs[0] == 0):
            continue
        mode = "".join("+" if s > 0 else "-" for s in fb.working_mode_signs[0])
        if ValidityChecker(design, Margins(), (), asm, mode).is_valid(q[None])[0]:
            return q, asm


def proofs(count: int) -> None:
    rmap = R.region_map(CUT, n=256)
    big = [r for r in rmap.regions if r.assembly_mode == "-" and r.valid_cells > 200]
    ends = []
    for comp in sorted({r.component for r in big})[:2]:
        region = next(r for r in big if r.component == comp)
        mi = WORKING_MODES.index(region.working_mode)
        k3, k2 = np.nonzero((rmap.labels[1, mi] == region.label) & (rmap.status[1, mi] == 2))
        ends.append(np.array([0.0, rmap.theta2[k2[len(k2) // 2]], rmap.theta3[k3[len(k3) // 2]]]))
    runs = []
    for _ in range(50):
        t0 = time.perf_counter()
        ok = R.prove_disconnected(rmap, ends[0], ends[1], "-")
        runs.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    res = plan(CUT, JointPosture(ends[0], "-"), JointPosture(ends[1], "-"),
               options=PlanOptions(time_budget_s=1.0))  # fmt: skip
    t_plan = time.perf_counter() - t0
    print(f"\ndisconnected scene (joint limits cut the general design): proven {ok}, proof "
          f"median {statistics.median(runs) * 1e6:.0f} us on a cached map; the planner "
          f"answers {res.status.value} after {t_plan:.2f} s (1 s budget)")  # fmt: skip

    rng = np.random.default_rng(2024)
    designs = list(DESIGNS.values())
    solved = proven = false = 0
    t0 = time.perf_counter()
    for k in range(count):
        design = designs[k % len(designs)]
        qa, asm = _valid(design, rng)
        while True:
            qb, asm_b = _valid(design, rng)
            if asm_b == asm:
                break
        claim = R.prove_disconnected(R.region_map(design, n=256), qa, qb, asm)
        proven += claim
        result = plan(design, JointPosture(qa, asm), JointPosture(qb, asm),
                      options=PlanOptions(time_budget_s=0.05 if claim else 0.5, seed=1 + k))  # fmt: skip
        solved += result.solved
        false += result.solved and claim
    print(f"\n{count} seeded queries over the four designs: {solved} solved, {proven} proven "
          f"disconnected, false proofs (solved and proven): {false}  "
          f"[{time.perf_counter() - t0:.0f} s]")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--queries", type=int, default=1000)
    args = parser.parse_args()
    print_machine()
    build_times()
    proofs(args.queries)


if __name__ == "__main__":
    main()
