"""Scenes with many obstacles: plan time, solved share and index build time, side by side.

    PYTHONPATH=src .venv/bin/python benchmarks/scenes.py [--queries 20] [--budget 1.0]
        [--skip-large]

Scenes (default design ``Design.default()``, default margins):

* ``free``: no obstacle;
* ``N spheres`` (5, 10, 100, 1,000): balls of radius 0.5-1 cm with centres in the shell
  0.35 m < |c| < 0.75 m around the robot (the issue's setting);
* ``N-point cloud`` (10,000 and 100,000): what a depth camera sees of a cell, every point a
  ball of radius 5 mm: a floor patch at z = -0.75 m, a wall at x = 0.95 m and the faces of
  a 20 cm box on the floor; the points drawn uniformly on those surfaces.

Queries: pairs (start, goal) valid in one working and assembly mode, drawn with a fixed seed,
and kept only when an independent grid search (6-connected components of the valid cells of
a 48 x 64 x 64 joint grid, scipy.ndimage) joins them in that scene: the solved share is taken
over queries known to be solvable (up to the grid's resolution). Each scene's index is built
once (its first query pays it, as the first plan of a named scene does; the ``build ms``
column is that build alone, measured apart), then every query is planned with
``planner.planning.plan``; the table gives the median and the 90th percentile of the plan
times and the share solved, and the checker's cost for 2,000 random postures (``states``:
every measure, exact clearance; ``valid``: the rules only, as the planner asks).

Last, the 100,000-point cloud over HTTP (the service in this process, one worker): a plan
naming the stored scene against the same plan with the cloud inline, median request times.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from _machine import print_machine
from scipy import ndimage

from planner import Design, geometry
from planner.geometry import Box, Points, Sphere, pack_obstacles
from planner.kinematics import WORKING_MODES
from planner.planning import JointPosture, PlanOptions, plan
from planner.validity import Margins, ValidityChecker

GRID = (48, 64, 64)


def spheres(n: int, seed: int = 3) -> list:
    """n balls of radius 0.5-1 cm, centres in the shell 0.35 < |c| < 0.75 m."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        c = rng.uniform(-0.75, 0.75, 3)
        if 0.35 < np.linalg.norm(c) < 0.75:
            out.append(Sphere(c, rng.uniform(0.005, 0.01)))
    return out


def cloud(n: int, seed: int = 5, radius: float = 0.005) -> list:
    """A depth camera's view of a cell as n points (floor patch, wall, a box on the floor)."""
    rng = np.random.default_rng(seed)
    # surfaces: (area, sampler); points split by area
    floor = (4.0, lambda k: np.column_stack([rng.uniform(-1, 1, (k, 2)), np.full(k, -0.75)]))
    wall = (
        2.4,
        lambda k: np.column_stack(
            [np.full(k, 0.95), rng.uniform(-1, 1, k), rng.uniform(-0.75, 0.45, k)]
        ),
    )

    def box_faces(k: int) -> np.ndarray:
        c, h = np.array([0.45, 0.45, -0.65]), 0.1
        p = rng.uniform(-h, h, (k, 3))
        axis = rng.integers(0, 3, k)
        p[np.arange(k), axis] = np.where(rng.random(k) < 0.5, -h, h)
        return c + p

    parts = [floor, wall, (0.24, box_faces)]
    total = sum(a for a, _ in parts)
    counts = [round(n * a / total) for a, _ in parts]
    counts[0] += n - sum(counts)
    pts = np.vstack([f(k) for (_, f), k in zip(parts, counts, strict=True)])
    return [Points(pts, radius)]


def scenes(skip_large: bool) -> dict[str, list]:
    out = {"free": [], "5 spheres": spheres(5), "10 spheres": spheres(10)}
    out["100 spheres"] = spheres(100)
    out["1,000 spheres"] = spheres(1000)
    out["10,000-point cloud"] = cloud(10_000)
    if not skip_large:
        out["100,000-point cloud"] = cloud(100_000)
    return out


def build_queries(design: Design, obstacles: list, n: int, seed: int = 11) -> list:
    """n (start, goal) pairs in one mode joined by the grid's components (module docstring)."""
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(design.joint_min), np.asarray(design.joint_max)
    axes = [np.linspace(lo[i], hi[i], GRID[i]) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    step = (hi - lo) / (np.asarray(GRID) - 1)
    combos = []
    for asm in ("+", "-"):
        for mode in WORKING_MODES:
            chk = ValidityChecker(design, Margins(), obstacles, asm, mode)
            labels, count = ndimage.label(chk.is_valid(grid).reshape(GRID))
            if count:
                combos.append((chk, labels))
    out = []
    while len(out) < n:
        chk, labels = combos[rng.integers(len(combos))]
        q = rng.uniform(lo, hi, (2000, 3))
        idx = np.clip(np.rint((q - lo) / step).astype(int), 0, np.asarray(GRID) - 1)
        lab = labels[idx[:, 0], idx[:, 1], idx[:, 2]]
        ok = np.flatnonzero(chk.is_valid(q) & (lab > 0))
        if len(ok) < 2:
            continue
        a = ok[0]
        same = ok[1:][lab[ok[1:]] == lab[a]]
        if len(same):
            asm = chk.assembly_mode
            out.append((JointPosture(q[a], asm), JointPosture(q[same[0]], asm)))
    return out


def run(name: str, obstacles: list, queries: list, budget: float, design: Design) -> str:
    geometry._PACKED.clear()  # the queries' checkers packed it: measure a build
    geometry._BY_IDENTITY.clear()
    t0 = time.perf_counter()
    pack_obstacles(obstacles)  # the scene's index, kept for the plans below
    build = time.perf_counter() - t0
    # the checker's cost for 2,000 random postures (index built)
    chk = ValidityChecker(design, Margins(), obstacles, "+", "+-+")
    q = np.random.default_rng(1).uniform(-np.pi, np.pi, (2000, 3))
    chk.is_valid(q[:10])
    t0 = time.perf_counter()
    chk.check_states(q)
    states = time.perf_counter() - t0
    t0 = time.perf_counter()
    chk.is_valid(q)
    valid = time.perf_counter() - t0
    times, solved = [], 0
    options = PlanOptions(time_budget_s=budget, seed=1)
    for start, goal in queries:
        t0 = time.perf_counter()
        res = plan(design, start, goal, obstacles=obstacles, margins=Margins(), options=options)
        times.append(time.perf_counter() - t0)
        solved += res.status.value == "solved"
    times.sort()
    p90 = times[min(len(times) - 1, int(0.9 * len(times)))]
    rows = sum(len(o.points) if isinstance(o, Points) else 1 for o in obstacles)
    return (
        f"| {name} | {rows} | {build * 1e3:.1f} | {statistics.median(times) * 1e3:.2f} | "
        f"{p90 * 1e3:.2f} | {solved}/{len(queries)} | {states * 1e3:.2f} | {valid * 1e3:.2f} |"
    )


def http_named_vs_inline(obstacles: list, queries: list, repeats: int) -> list[str]:
    """Plans over HTTP (the service in this process, one worker) in a named scene against
    the same obstacles inline: median request time of each, and their ratio."""
    import json
    import tempfile
    from pathlib import Path

    from fastapi.testclient import TestClient

    from planner.wire import PointsObstacle
    from planner_api.app import create_app
    from planner_api.settings import Settings

    wire = [
        PointsObstacle(points=o.points.tolist(), radius=o.radius).model_dump() for o in obstacles
    ]
    store = Path(tempfile.mkdtemp()) / "scenes.db"
    settings = Settings(workers=1, scene_store=str(store), request_timeout_s=120)
    out = []
    with TestClient(create_app(settings)) as client:
        while client.get("/v1/ready").status_code != 200:
            time.sleep(0.2)
        t0 = time.perf_counter()
        client.put("/v1/scenes/bench", json={"obstacles": wire})
        put_s = time.perf_counter() - t0
        times: dict[str, list[float]] = {"named": [], "inline": []}
        for k in range(repeats):
            start, goal = queries[k % len(queries)]
            body = {
                "start": {"q": start.q.tolist(), "assembly_mode": start.assembly_mode},
                "goal": {"q": goal.q.tolist(), "assembly_mode": goal.assembly_mode},
                "timing": {"method": "none"},
            }
            for kind, extra in (("named", {"scene": "bench"}), ("inline", {"obstacles": wire})):
                text = json.dumps({**body, **extra})
                t0 = time.perf_counter()
                r = client.post(
                    "/v1/plan", content=text, headers={"content-type": "application/json"}
                )
                times[kind].append(time.perf_counter() - t0)
                assert r.status_code == 200, r.text[:200]
        named, inline = (statistics.median(times[k]) for k in ("named", "inline"))
        out.append(f"PUT of the scene: {put_s * 1e3:.0f} ms")
        out.append(
            f"plan over HTTP, median of {repeats}: named {named * 1e3:.1f} ms, inline "
            f"{inline * 1e3:.1f} ms, named / inline = {named / inline:.3f}"
        )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--queries", type=int, default=20)
    ap.add_argument("--budget", type=float, default=1.0)
    ap.add_argument("--skip-large", action="store_true", help="no 100,000-point cloud")
    ap.add_argument("--http", type=int, default=5, help="plans of the HTTP comparison")
    args = ap.parse_args()
    print_machine()
    design = Design.default()
    box = [Box([0.0, 0.0, -5.0], [0.1, 0.1, 0.1])]  # compiles the box path before timing
    ValidityChecker(design, Margins(), box, "+", "+-+").check_states([[0.0, 2.0, 1.0]])
    print(f"{args.queries} queries per scene, budget {args.budget} s, seed 1")
    print("| scene | rows | build ms | plan p50 ms | plan p90 ms | solved | 2,000 states ms "
          "| 2,000 valid ms |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for name, obstacles in scenes(args.skip_large).items():
        queries = build_queries(design, obstacles, args.queries)
        print(run(name, obstacles, queries, args.budget, design), flush=True)
    if not args.skip_large:
        print(f"\n100,000-point cloud, named scene against inline obstacles ({args.http} plans)")
        for line in http_named_vs_inline(obstacles, queries, args.http):
            print(line)


if __name__ == "__main__":
    main()
