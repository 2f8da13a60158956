"""Region maps (``planner.analysis.regions``): build time, regions per mode, proof time and
false proofs over seeded solved queries. Prints a table; ``python benchmarks/regions.py``.

Build times are p50 (and p90) of cold builds (cache cleared; 21 at n = 256, 5 at 128 and
512) on one core, after a warm-up that loads the numba kernels; ``--builds-only`` prints
that table alone. Then the check of the paper's "twice as large" claim (section 3.3), and
the proofs. False proofs: seeded queries (both ends valid, same assembly
mode) are planned with ``planner.planning.plan``'s search alone (``region_map=False``); a
solved query the map (at 256 or at the planner's ``PROOF_RESOLUTION``) proves disconnected
would be a false proof (the count must be 0). ``--queries N`` (default 1000).

``--speed`` prints only the before/after table of issue 17: the old build (the route kept
callable by the tests, ``tests/analysis/_region_reference.py``) and today's, interleaved
in blocks of 5 (cold, cache cleared), medians of wall and CPU time at 128 and 256, side by
side with their ratio and the page faults per build (``--runs``: builds of each).

``--obstacles`` prints only the soak of the proof with obstacles
(``planner.analysis.obstacle_regions``): ``--queries`` seeded scenes and queries planned by the
search alone, the proof asked of each; false proofs counted (must be 0), proof times. The
same goals inside tolerance balls (point or joint, "any" with ``prefer``): the proof over the
whole ball (:func:`planner.planning.tolerance.prove_goal_set`) and, every 4th solved query,
the planner with the tolerance; a claim for a ball that holds a goal the search reached is a
false proof (there must be none).
"""

from __future__ import annotations

import argparse
import resource
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from _machine import print_machine

from planner import caching
from planner.analysis import coverage as C
from planner.analysis import regions as R
from planner.design import Design
from planner.kinematics import WORKING_MODES, forward_batch
from planner.planning import JointPosture, PlanOptions, plan
from planner.planning.proofs import PROOF_RESOLUTION
from planner.validity import Margins, ValidityChecker

DESIGNS = {
    "singularity-free 0.5/0.2/0.6 (P off axis, 2L1<L0)": Design.default(),
    "mode-change 0.6/0.25/0.45 (P reaches the axis, 2L1<L0)": Design(0.6, 0.25, 0.45),
    "general 0.3/0.3/0.4 (P reaches the axis, 2L1>L0)": Design(0.3, 0.3, 0.4),
    "paper optimum 0/0.4/0.4": Design.paper_optimum(),
}
CUT = Design(0.3, 0.3, 0.4, joint_min=(-3.14, -0.49, -2.81), joint_max=(3.14, 0.51, -1.72))


#: The issue's goal for one cold map at the default resolution, s.
GOAL_256 = 0.030


def _cold_builds(design: Design, n: int, runs: int) -> tuple[list[float], list[float]]:
    """Wall and CPU seconds of ``runs`` cold builds (cache cleared before each)."""
    wall, cpu = [], []
    for _ in range(runs):
        caching.clear("regions")
        t0, c0 = time.perf_counter(), time.process_time()
        R.region_map(design, n=n)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return wall, cpu


def build_times(runs: int) -> None:
    """p50 of cold builds per design and resolution; at 256 also p90 and the CPU time (the
    machine is shared: wall time counts the other processes' turns too)."""
    print(
        f"cold builds (cache cleared), p50 of {runs} at n = 256 (5 at 128 and 512); goal at "
        f"256: <= {GOAL_256 * 1e3:.0f} ms\n"
    )
    print(
        "| design | n = 128 | n = 256 p50 | n = 256 p90 | n = 256 CPU p50 | n = 512 | "
        "goal met | regions per mode, asm + (certified) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    R.region_map(Design.default(), n=16)  # load the kernels
    for name, design in DESIGNS.items():
        w128, _ = _cold_builds(design, 128, 5)
        w256, c256 = _cold_builds(design, 256, runs)
        w512, _ = _cold_builds(design, 512, 5)
        p50 = statistics.median(w256)
        p90 = float(np.quantile(w256, 0.9))
        rmap = R.region_map(design, n=256)
        over, cert = rmap.region_count(), rmap.region_count(certified=True)
        per = " ".join(f"{m}:{over[0, k]}({cert[0, k]})" for k, m in enumerate(WORKING_MODES))
        print(
            f"| {name} | {statistics.median(w128) * 1e3:.1f} ms | {p50 * 1e3:.1f} ms | "
            f"{p90 * 1e3:.1f} ms | {statistics.median(c256) * 1e3:.1f} ms | "
            f"{statistics.median(w512) * 1e3:.0f} ms | {'yes' if p50 <= GOAL_256 else 'no'} | "
            f"{per} |"
        )


def _timed(build) -> tuple[float, float, int]:
    """Wall and CPU seconds and minor page faults of one call."""
    f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    t0, c0 = time.perf_counter(), time.process_time()
    build()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return wall, cpu, resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0


#: Builds per block of :func:`speed` (old and new alternate block by block).
SPEED_BLOCK = 5


def speed(runs: int) -> None:
    """Old build against new, interleaved block by block (``SPEED_BLOCK`` old builds, then
    as many new, and so on) so that both meet the same load of the shared machine; medians
    of ``runs`` cold builds each (rounded up to whole blocks), and the page faults per
    build. Blocks, not single builds: a new build writes into the one block of memory that
    the previous map of its resolution left to the allocator, and an old build in between
    (its arrays of other sizes) takes that memory back, which would charge the new build
    page faults that a process building maps does not pay."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "analysis"))
    from _region_reference import reference_region_map

    designs = {**DESIGNS, "cut limits 0.3/0.3/0.4 (no mirror)": CUT}
    blocks = -(-runs // SPEED_BLOCK)
    print(
        f"cold builds, old (before issue 17) and new interleaved in blocks of "
        f"{SPEED_BLOCK}, medians of {blocks * SPEED_BLOCK} each; goal at 256: <= "
        f"{GOAL_256 * 1e3:.0f} ms\n"
    )
    print(
        "| design | n | old wall | new wall | old CPU | new CPU | CPU old / new | "
        "new wall p90 | page faults old / new |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    margins = Margins()
    for design in designs.values():  # compile both routes before timing
        reference_region_map(design, margins, 16, R.DEFAULT_REFINE)
        R.region_map(design, margins, 16)
    for n in (128, 256):
        for name, design in designs.items():
            old, new = [], []
            for _ in range(blocks):
                for _ in range(SPEED_BLOCK):
                    old.append(_timed(lambda d=design, n=n: reference_region_map(d, margins, n, 4)))
                for _ in range(SPEED_BLOCK):
                    caching.clear("regions")
                    new.append(_timed(lambda d=design, n=n: R.region_map(d, margins, n)))
            med = [
                statistics.median(t[k] for t in runs_) for k in (0, 1, 2) for runs_ in (old, new)
            ]
            p90 = float(np.quantile([t[0] for t in new], 0.9)) * 1e3
            print(
                f"| {name} | {n} | {med[0] * 1e3:.1f} ms | {med[1] * 1e3:.1f} ms | "
                f"{med[2] * 1e3:.1f} ms | {med[3] * 1e3:.1f} ms | {med[2] / med[3]:.2f} | "
                f"{p90:.1f} ms | {med[4]:.0f} / {med[5]:.0f} |"
            )


#: The paper's convex and non-convex working modes (section 3.3) with their mirrors about AB.
CONVEX, NONCONVEX = ("+-+", "-+-"), ("++-", "--+")


def twice_as_large(m: int = 400) -> None:
    """The paper's "by a change of working mode we can reach a workspace twice as large" (as
    each of figures 13-14), per design and union-graph component of assembly mode '+' (the
    mirror image of '-'): what the certified regions of the convex pair, of the non-convex
    pair and of the whole component (every mode a change of working mode reaches from there)
    cover, in the linkage plane (the paper's sections) and in 3-D (theta1 a full turn)."""
    print(
        f'\n"twice as large": certified regions (n = 256, default margins), assembly mode '
        f"'+', linkage plane on a {m} x {m} raster and 3-D volume as theta1 turns\n"
    )
    print(
        "| design | component | convex m^2 | non-convex m^2 | all m^2 | all / convex | "
        "all / non-convex | convex m^3 | non-convex m^3 | all m^3 | 3-D all / convex | "
        "3-D all / non-convex |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, design in DESIGNS.items():
        rmap = R.region_map(design, n=256)
        cov = C.cartesian_coverage(rmap, m)
        mine = [r for r in rmap.regions if r.assembly_mode == "+" and r.valid_cells]
        for comp in sorted({r.component for r in mine}):
            ids = [r.id for r in mine if r.component == comp]
            cv = [r.id for r in mine if r.component == comp and r.working_mode in CONVEX]
            nc = [r.id for r in mine if r.component == comp and r.working_mode in NONCONVEX]
            a = (cov.area(cv), cov.area(nc), cov.area(ids))
            v = (cov.volume(cv), cov.volume(nc), cov.volume(ids))
            if a[2] < 0.01 * cov.area(r.id for r in mine):
                continue  # slivers of undecided-free cells: not a workspace
            ratios = [f"{x[2] / x[k]:.2f}" if x[k] > 0 else "-" for x in (a, v) for k in (0, 1)]
            print(
                f"| {name} | {comp} | {a[0]:.3f} | {a[1]:.3f} | {a[2]:.3f} | {ratios[0]} | "
                f"{ratios[1]} | {v[0]:.3f} | {v[1]:.3f} | {v[2]:.3f} | {ratios[2]} | "
                f"{ratios[3]} |"
            )


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
    res = plan(
        CUT,
        JointPosture(ends[0], "-"),
        JointPosture(ends[1], "-"),
        options=PlanOptions(time_budget_s=1.0, region_map=False),
    )
    t_plan = time.perf_counter() - t0
    t0 = time.perf_counter()
    proven = plan(
        CUT,
        JointPosture(ends[0], "-"),
        JointPosture(ends[1], "-"),
        options=PlanOptions(time_budget_s=5.0),
    )
    t_proven = time.perf_counter() - t0
    print(
        f"\ndisconnected scene (joint limits cut the general design): proven {ok}, proof "
        f"median {statistics.median(runs) * 1e6:.0f} us on a cached map; the search alone "
        f"answers {res.status.value} after {t_plan:.2f} s (1 s budget); the planner "
        f"(map on, 5 s budget) {proven.status.value}, proven_infeasible "
        f"{proven.diagnostics.proven_infeasible}, after {t_proven * 1e3:.1f} ms"
    )

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
        # the endpoint's resolution and the planner's (planner.planning.dispatch)
        claim = R.prove_disconnected(R.region_map(design, n=256), qa, qb, asm) or (
            R.prove_disconnected(R.region_map(design, n=PROOF_RESOLUTION), qa, qb, asm)
        )
        proven += claim
        result = plan(
            design,
            JointPosture(qa, asm),
            JointPosture(qb, asm),
            options=PlanOptions(time_budget_s=0.05 if claim else 0.5, seed=1 + k, region_map=False),
        )
        solved += result.solved
        false += result.solved and claim
    print(
        f"\n{count} seeded queries over the four designs: {solved} solved, {proven} proven "
        f"disconnected, false proofs (solved and proven): {false}  "
        f"[{time.perf_counter() - t0:.0f} s]"
    )


def obstacle_soak(queries: int, seed: int = 23) -> None:
    """The 3-D proof's false-proof soak: seeded scenes (four designs, theta1 limited or not,
    2-6 spheres and plates), start and goal in one assembly mode (the goal's working mode
    random: mode changes included); the search alone (``region_map=False``, 0.5 s) plans
    each, then the proof is asked. A proof claimed for a query the search solved is a false
    proof (there must be none); the proof's time is printed for both outcomes."""
    from planner.analysis.obstacle_regions import prove_disconnected_with_obstacles
    from planner.geometry import Box, Sphere
    from planner.kinematics import WORKING_MODES
    from planner.planning import (
        CartesianTarget,
        JointPosture,
        PlanOptions,
        PlanStatus,
        plan,
        plan_with_goal_options,
    )
    from planner.planning.tolerance import goal_ball, prove_goal_set

    designs = [
        Design.default(),
        Design.paper_optimum(),
        Design(0.3, 0.3, 0.4),
        Design(0.6, 0.25, 0.45),
    ]
    from planner.warmup import warm_up

    warm_up()  # numba kernels compiled (the proof's too) outside the measurements
    rng = np.random.default_rng(seed)
    solved = false = proven = ball_proven = false_ball = planned = false_plan = 0
    t_solved, t_other, t_ball = [], [], []
    done = 0
    while done < queries:
        base = designs[done % len(designs)]
        design = (
            base
            if done % 2
            else Design(
                base.L0,
                base.L1,
                base.L2,
                joint_min=(-2.0, -np.pi, -np.pi),
                joint_max=(2.0, np.pi, np.pi),
            )
        )
        obstacles = []
        for _ in range(rng.integers(2, 7)):
            c = rng.uniform(-0.7, 0.7, 3)
            if rng.uniform() < 0.5:
                obstacles.append(Sphere(c, rng.uniform(0.05, 0.2)))
            else:
                quat = rng.normal(size=4)
                obstacles.append(Box(c, rng.uniform(0.02, 0.6, 3), quat / np.linalg.norm(quat)))
        asm = "+" if rng.uniform() < 0.5 else "-"
        q = rng.uniform(design.joint_min, design.joint_max, (4000, 3))
        valid = {}
        for mode in WORKING_MODES:
            ok = ValidityChecker(design, Margins(), obstacles, asm, mode).is_valid(q)
            if ok.sum() >= 2:
                valid[mode] = q[ok]
        if not valid:
            continue
        modes = sorted(valid)
        m0, m1 = modes[rng.integers(len(modes))], modes[rng.integers(len(modes))]
        start = valid[m0][rng.integers(len(valid[m0]))]
        goal = valid[m1][rng.integers(len(valid[m1]))]
        res = plan(
            design,
            JointPosture(start, asm),
            JointPosture(goal, asm),
            obstacles=obstacles,
            options=PlanOptions(time_budget_s=0.5, seed=done + 1, region_map=False),
        )
        t0 = time.perf_counter()
        proof = prove_disconnected_with_obstacles(design, Margins(), obstacles, start, goal, asm)
        dt = (time.perf_counter() - t0) * 1e3
        # the same goal inside a tolerance ball (point or joint, centre off the goal, radius
        # up to 0.2 m or rad, "any" with prefer for a point): the proof over the ball, and
        # every 4th query the planner with the tolerance
        radius = float(rng.uniform(0.01, 0.2))
        shift = rng.normal(size=3)
        shift *= rng.uniform(0, radius) / np.linalg.norm(shift)
        if done % 2:
            target = CartesianTarget(forward_batch(design, goal, asm).p[0] + shift, "any")
        else:
            target = JointPosture(goal + shift, asm)
        t0 = time.perf_counter()
        ball = (
            prove_goal_set(
                design, JointPosture(start, asm), goal_ball(target, radius), obstacles=obstacles
            )
            is not None
        )
        t_ball.append((time.perf_counter() - t0) * 1e3)
        done += 1
        proven += proof.proven
        ball_proven += ball
        if res.status is PlanStatus.SOLVED:
            solved += 1
            false += proof.proven
            false_ball += ball
            t_solved.append(dt)
            if solved % 4 == 0:
                planned += 1
                answer = plan_with_goal_options(
                    design,
                    JointPosture(start, asm),
                    target,
                    obstacles=obstacles,
                    options=PlanOptions(time_budget_s=0.2, seed=done),
                    tolerance=radius,
                    prefer="best_conditioned" if done % 2 else "shortest",
                )
                false_plan += answer.diagnostics.proven_infeasible
        else:
            t_other.append(dt)
        if done % 100 == 0:
            print(
                f"  {done}/{queries} queries: {solved} solved, {proven} proven, {false} false "
                f"proofs; balls: {ball_proven} proven, {false_ball} false",
                flush=True,
            )
    print(
        f"\nobstacle proof soak: {done} queries, {solved} solved by the search, {proven} proven "
        f"(of the {done - solved} unsolved), false proofs: {false}"
    )
    print(
        f"the same goals in a tolerance ball: {ball_proven} balls proven (of the "
        f"{done - solved} unsolved), false ball proofs: {false_ball}; the planner with the "
        f"tolerance and prefer on {planned} solved queries: false proofs {false_plan}; ball "
        f"proof p50 {np.percentile(t_ball, 50):.1f} ms, p95 {np.percentile(t_ball, 95):.1f} "
        "ms"
    )
    for label, t in (("solved queries", t_solved), ("unsolved queries", t_other)):
        if t:
            print(
                f"  proof time on {label}: p50 {np.percentile(t, 50):.1f} ms, p95 "
                f"{np.percentile(t, 95):.1f} ms, max {max(t):.1f} ms (n = {len(t)})"
            )


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--queries", type=int, default=1000)
    parser.add_argument("--runs", type=int, default=21, help="cold builds per design at 256")
    parser.add_argument("--builds-only", action="store_true", help="skip the proof checks")
    parser.add_argument("--claim", action="store_true", help="only the 'twice as large' table")
    parser.add_argument("--speed", action="store_true", help="only old against new builds")
    parser.add_argument(
        "--obstacles",
        action="store_true",
        help="only the soak of the proof with obstacles (--queries of them)",
    )
    args = parser.parse_args()
    print_machine()
    if args.speed:
        speed(args.runs)
        return
    if args.claim:
        twice_as_large()
        return
    if args.obstacles:
        obstacle_soak(args.queries)
        return
    build_times(args.runs)
    if args.builds_only:
        return
    twice_as_large()
    proofs(args.queries)


if __name__ == "__main__":
    main()
