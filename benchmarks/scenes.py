"""Scenes with many obstacles: plan time, solved share and index build time, side by side.

    PYTHONPATH=src .venv/bin/python benchmarks/scenes.py [--queries 20] [--budget 1.0]
        [--skip-large] [--scenes "free,1,000 spheres"] [--baseline OTHER/src ...]

Scenes (default design ``Design.default()``, default margins):

* ``free``: no obstacle;
* ``N spheres`` (5, 10, 100, 1,000): balls of radius 0.5-1 cm with centres in the shell
  0.35 m < |c| < 0.75 m around the robot (the issue's setting);
* ``N-point cloud`` (10,000 and 100,000): what a depth camera sees of a cell, every point a
  ball of radius 5 mm: a floor patch at z = -0.75 m, a wall at x = 0.95 m and the faces of
  a 20 cm box on the floor; the points drawn uniformly on those surfaces.

Queries: pairs (start, goal) valid in one working and assembly mode, drawn with a fixed seed,
and kept only when an independent grid search joins them in that scene by a path that is
certified: the 6-connected components of the valid nodes of a 48 x 64 x 64 joint grid
(scipy.ndimage) pick the pairs, a breadth-first path through the grid (scipy.sparse.csgraph)
joins them, and every straight motion of that path (the start and goal attached to its end
nodes) passes the checker's motion certificate. The solved share is taken over queries known
to be solvable, each with its witness path; the ``dropped`` column counts the pairs that the
grid's components joined but whose grid path was not certified (a grid only samples the
valid set: two valid neighbours need not be joined by a valid motion), drawn again. Each scene's index is built
once (its first query pays it, as the first plan of a named scene does; the ``build ms``
column is that build alone, measured apart), then every query is planned with
``planner.planning.plan``; the table gives the median and the 90th percentile of the plan
times and the share solved, and the checker's cost for 2,000 random postures (``states``:
every measure, exact clearance; ``valid``: the rules only, as the planner asks).

``--baseline OTHER/src`` plans free space and 5 spheres with another checkout's code too (a
subprocess with that ``PYTHONPATH``, e.g. ``git archive main src | tar -x -C /tmp/main``),
the same queries, this code before and after it: the ratio is this code's median of the two
over the baseline's.

Last, the 100,000-point cloud over HTTP (the service in this process, one worker): a plan
naming the stored scene against the same plan with the cloud inline, median request times.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from itertools import pairwise

import numpy as np
from _machine import print_machine
from scipy import ndimage, sparse
from scipy.sparse import csgraph

from planner import Design, geometry
from planner.geometry import Box, Sphere, pack_obstacles
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
    return [geometry.Points(pts, radius)]


def scenes(skip_large: bool, wanted: list[str]) -> dict[str, list]:
    """The scenes by name (module docstring), only those ``wanted`` when it is not empty."""
    make = {
        "free": lambda: [],
        "5 spheres": lambda: spheres(5),
        "10 spheres": lambda: spheres(10),
        "100 spheres": lambda: spheres(100),
        "1,000 spheres": lambda: spheres(1000),
        "10,000-point cloud": lambda: cloud(10_000),
        "100,000-point cloud": lambda: cloud(100_000),
    }
    if skip_large:
        del make["100,000-point cloud"]
    return {k: f() for k, f in make.items() if not wanted or k in wanted}


def _grid_graph(valid: np.ndarray) -> sparse.csr_matrix:
    """The 6-neighbour graph of the valid nodes of the joint grid (flat node indices)."""
    idx = np.arange(valid.size).reshape(valid.shape)
    rows, cols = [], []
    for axis in range(3):
        a = [slice(None)] * 3
        b = [slice(None)] * 3
        a[axis], b[axis] = slice(None, -1), slice(1, None)
        both = valid[tuple(a)] & valid[tuple(b)]
        rows.append(idx[tuple(a)][both])
        cols.append(idx[tuple(b)][both])
    r, c = np.concatenate(rows), np.concatenate(cols)
    n = valid.size
    return sparse.csr_matrix((np.ones(len(r), dtype=np.int8), (r, c)), shape=(n, n))


def _witness(chk, graph, nodes, a_node: int, b_node: int, qa, qb) -> bool:
    """Whether the grid's path from node ``a_node`` to ``b_node`` (breadth first), with
    ``qa`` and ``qb`` attached to its ends, is a valid path: every one of its straight
    motions certified by the checker (:meth:`ValidityChecker.motion_valid`). A grid only
    samples the valid set (two valid neighbours need not be joined by a valid motion), so
    a query counts as solvable only with this witness in hand."""
    _, pred = csgraph.breadth_first_order(graph, a_node, directed=False, return_predecessors=True)
    if b_node != a_node and pred[b_node] < 0:
        return False
    path = [b_node]
    while path[-1] != a_node:
        path.append(int(pred[path[-1]]))
    pts = [qb, *nodes[path], qa][::-1]
    return all(chk.motion_valid(p, q) for p, q in pairwise(pts))


def build_queries(design: Design, obstacles: list, n: int, seed: int = 11) -> tuple[list, int]:
    """n (start, goal) pairs in one mode joined by a certified path through the joint
    grid (module docstring), and how many pairs the grid's components joined but no
    certified grid path did (drawn and dropped)."""
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(design.joint_min), np.asarray(design.joint_max)
    axes = [np.linspace(lo[i], hi[i], GRID[i]) for i in range(3)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    step = (hi - lo) / (np.asarray(GRID) - 1)
    combos = []
    for asm in ("+", "-"):
        for mode in WORKING_MODES:
            chk = ValidityChecker(design, Margins(), obstacles, asm, mode)
            valid = chk.is_valid(nodes).reshape(GRID)
            labels, count = ndimage.label(valid)
            if count:
                combos.append((chk, labels, _grid_graph(valid)))
    out, dropped = [], 0
    while len(out) < n:
        chk, labels, graph = combos[rng.integers(len(combos))]
        q = rng.uniform(lo, hi, (2000, 3))
        idx = np.clip(np.rint((q - lo) / step).astype(int), 0, np.asarray(GRID) - 1)
        lab = labels[idx[:, 0], idx[:, 1], idx[:, 2]]
        ok = np.flatnonzero(chk.is_valid(q) & (lab > 0))
        if len(ok) < 2:
            continue
        a = ok[0]
        same = ok[1:][lab[ok[1:]] == lab[a]]
        if not len(same):
            continue
        b = same[0]
        flat = np.ravel_multi_index(idx[[a, b]].T, GRID)
        if not _witness(chk, graph, nodes, int(flat[0]), int(flat[1]), q[a], q[b]):
            dropped += 1
            continue
        asm = chk.assembly_mode
        out.append((JointPosture(q[a], asm), JointPosture(q[b], asm)))
    return out, dropped


def run(name: str, obstacles: list, queries: list, budget: float, design: Design) -> dict:
    """One scene's row (module docstring) as numbers: ms, and the solved count."""
    for cache in (
        "_PACKED",
        "_PACKED_SMALL",
        "_BY_IDENTITY",
    ):  # the queries' checkers packed it: a cold build
        if hasattr(geometry, cache):
            getattr(geometry, cache).clear()
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
    rows = sum(len(getattr(o, "points", ())) or 1 for o in obstacles)
    return {
        "name": name,
        "rows": rows,
        "build": build * 1e3,
        "p50": statistics.median(times) * 1e3,
        "p90": p90 * 1e3,
        "solved": solved,
        "queries": len(queries),
        "states": states * 1e3,
        "valid": valid * 1e3,
    }


def row_text(r: dict, dropped: int) -> str:
    return (
        f"| {r['name']} | {r['rows']} | {r['build']:.1f} | {r['p50']:.2f} | {r['p90']:.2f} | "
        f"{r['solved']}/{r['queries']} | {dropped} | {r['states']:.2f} | {r['valid']:.2f} |"
    )


def baseline_rows(src: str, names: list[str], args: argparse.Namespace) -> dict[str, dict]:
    """The same scenes and queries planned by another checkout's ``src`` (a subprocess with
    that ``PYTHONPATH``; its numba caches are its own): name -> row numbers."""
    cmd = [
        sys.executable,
        __file__,
        "--json",
        "--scenes",
        ",".join(names),
        "--queries",
        str(args.queries),
        "--budget",
        str(args.budget),
    ]
    env = {**os.environ, "PYTHONPATH": src}
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True).stdout
    rows = [json.loads(line) for line in out.splitlines() if line.startswith("{")]
    return {r["name"]: r for r in rows}


def http_named_vs_inline(obstacles: list, queries: list, repeats: int) -> list[str]:
    """Plans over HTTP (the service in this process, one worker) in a named scene against
    the same obstacles inline: median request time of each, and their ratio."""
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
    with TestClient(create_app(settings), base_url="http://localhost") as client:
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
    ap.add_argument("--scenes", default="", help="comma-separated scene names (default all)")
    ap.add_argument(
        "--baseline",
        action="append",
        default=[],
        metavar="SRC",
        help="another checkout's src folder: free space and 5 spheres planned by it too, "
        "side by side (repeatable)",
    )
    ap.add_argument("--json", action="store_true", help=argparse.SUPPRESS)  # baseline rows
    args = ap.parse_args()
    design = Design.default()
    box = [Box([0.0, 0.0, -5.0], [0.1, 0.1, 0.1])]  # compiles the box path before timing
    ValidityChecker(design, Margins(), box, "+", "+-+").check_states([[0.0, 2.0, 1.0]])
    wanted = [n for n in args.scenes.split(",") if n]
    chosen = {k: v for k, v in scenes(args.skip_large, wanted).items()}
    if args.json:
        for name, obstacles in chosen.items():
            queries, _ = build_queries(design, obstacles, args.queries)
            print(json.dumps(run(name, obstacles, queries, args.budget, design)), flush=True)
        return
    print_machine()
    print(f"{args.queries} queries per scene, budget {args.budget} s, seed 1")
    print(
        "| scene | rows | build ms | plan p50 ms | plan p90 ms | solved | dropped "
        "| 2,000 states ms | 2,000 valid ms |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    mine = {}
    for name, obstacles in chosen.items():
        queries, dropped = build_queries(design, obstacles, args.queries)
        mine[name] = run(name, obstacles, queries, args.budget, design)
        print(row_text(mine[name], dropped), flush=True)
    print(
        "\n(solved: over queries with a certified path through the joint grid; dropped: "
        "pairs the grid's components joined but no certified grid path did)"
    )
    small = [n for n in ("free", "5 spheres") if n in mine]
    for src in args.baseline:
        base = baseline_rows(src, small, args)
        again = {
            n: run(
                n, chosen[n], build_queries(design, chosen[n], args.queries)[0], args.budget, design
            )
            for n in small
        }
        print(f"\nplan p50 ms against {src} (this code before and after it, same queries)")
        print("| scene | this code | baseline | this code again | ratio |")
        print("|---|---|---|---|---|")
        for n in small:
            ours = statistics.median([mine[n]["p50"], again[n]["p50"]])
            print(
                f"| {n} | {mine[n]['p50']:.2f} | {base[n]['p50']:.2f} | "
                f"{again[n]['p50']:.2f} | {ours / base[n]['p50']:.2f} |"
            )
    if "100,000-point cloud" in chosen:
        obstacles = chosen["100,000-point cloud"]
        queries, _ = build_queries(design, obstacles, args.queries)
        print(f"\n100,000-point cloud, named scene against inline obstacles ({args.http} plans)")
        for line in http_named_vs_inline(obstacles, queries, args.http):
            print(line)


if __name__ == "__main__":
    main()
