"""Where the product's plans of the fair table spend their time, query by query (issue 43).

    PYTHONPATH=src .venv/bin/python benchmarks/planning_breakdown.py [--scenes 1k_spheres,narrow]
        [--fair-queries 40] [--query-seed 11] [--no-memory] [--passes 1]

For each query of a scene of the fair table (``benchmarks/planning.py --fair``: the same
scenes and queries) the product's ``plan`` is run with each step timed by ``process_time``
(the process's own CPU time, little moved by the machine's load): the whole plan, the walk
along a remembered path (its recall, and whether a walk held), the compiled searches (their
tree nodes, found or not), the simplifications (vertices in and out; inside the search's
time), the corridor, the region map's and the obstacles' proofs. The last lines say which
queries make the scene's p50 and p95 (numpy's interpolation between neighbours). Queries run
in order in one process, the scene's caches cleared first, as the fair table's product rows
(which interleave other set-ups); ``--no-memory``: without the remembered paths
(:mod:`planner.planning.experience`). The steps are timed by wrapping the module functions
the pipeline calls (a benchmark's instrument; docs/planning.md, run J). ``--passes N``: the
scene's queries run N times in order (its caches cleared before each pass, so every pass
plans alike), the table of the first pass, and then the p50 and p95 over the queries of each
query's least CPU over the passes (what a change of a few percent is compared by: the load
of a shared machine only adds; docs/planning.md, run K).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
from _machine import print_machine
from planning import fair_scene

from planner import caching
from planner.planning import PlanOptions, compiled_rrt, corridor, dispatch, experience, plan
from planner.validity import Margins
from planner.warmup import warm_up

#: (module, function, step name) of the steps timed.
STEPS = (
    (compiled_rrt, "walk", "walk"),
    (experience, "recall", "recall"),
    (compiled_rrt, "rrt_connect", "search"),
    (compiled_rrt, "simplify", "simplify"),
    (corridor, "guided_search", "corridor"),
    (dispatch, "disprove_with_map", "map proof"),
    (dispatch, "disprove_with_obstacles", "3-D proof"),
)


class Steps:
    """The wrapped steps and what they recorded for the plan under way (:attr:`now`)."""

    def __init__(self) -> None:
        self.now: dict | None = None
        self.saved: list[tuple[object, str, Callable]] = []

    def wrap(self) -> None:
        for module, name, step in STEPS:
            fn = getattr(module, name)
            self.saved.append((module, name, fn))
            setattr(module, name, self._timed(fn, step))

    def unwrap(self) -> None:
        for module, name, fn in self.saved:
            setattr(module, name, fn)

    def _timed(self, fn: Callable, step: str) -> Callable:
        def timed(*args, **kwargs):
            c0 = time.process_time()
            out = fn(*args, **kwargs)
            if self.now is not None:
                rec = self.now
                rec[step] = rec.get(step, 0.0) + (time.process_time() - c0) * 1e3
                if step == "search" and out is not None:
                    rec.setdefault("nodes", []).append(f"{out.nodes}{'' if out.exact else '!'}")
                if step == "simplify":
                    rec.setdefault("vertices", []).append(f"{len(args[0])}>{len(out)}")
                if step == "recall":
                    rec.setdefault("walked", []).append(out is not None)
            return out

        return timed


def scene_rows(kind: str, args: argparse.Namespace, steps: Steps) -> None:
    design, obstacles, queries = fair_scene(kind, args.fair_queries, args.query_seed)
    rows: list = []
    least = np.full(len(queries), np.inf)
    for _ in range(max(1, args.passes)):
        caching.clear("corridor", "experience")
        for i, (start, goal) in enumerate(queries):
            steps.now = {}
            c0 = time.process_time()
            res = plan(
                design, start, goal, obstacles=obstacles, margins=Margins(), options=PlanOptions()
            )
            cpu = (time.process_time() - c0) * 1e3
            least[i] = min(least[i], cpu)
            if len(rows) < len(queries):
                answer = res.diagnostics.planner if res.solved else res.status.value
                rows.append((cpu, answer, steps.now))
            steps.now = None
    print(f"\n{kind}, query seed {args.query_seed}{' (no memory)' if args.no_memory else ''}")
    head = (
        f"{'q':>3} {'cpu ms':>7} {'answer':<10} {'walk':>6} {'recall':>6} {'walked':<7} "
        f"{'search':>7} {'nodes (! not found)':<19} {'simplify':>8} {'vertices':<14} "
        f"{'corridor':>8} {'proofs':>6}"
    )
    print(head)
    print("-" * len(head))
    for i, (cpu, answer, r) in enumerate(rows):
        walked = "".join("y" if w else "n" for w in r.get("walked", []))
        proofs = r.get("map proof", 0.0) + r.get("3-D proof", 0.0)
        print(
            f"{i:>3} {cpu:>7.2f} {answer:<10} {r.get('walk', 0.0):>6.2f} "
            f"{r.get('recall', 0.0):>6.2f} {walked:<7} {r.get('search', 0.0):>7.2f} "
            f"{','.join(r.get('nodes', [])):<19} {r.get('simplify', 0.0):>8.2f} "
            f"{','.join(r.get('vertices', [])):<14} {r.get('corridor', 0.0):>8.2f} {proofs:>6.2f}"
        )
    cpu = np.array([c for c, _, _ in rows])
    order = np.argsort(cpu)
    for q in (50, 95):
        pos = q / 100 * (len(cpu) - 1)
        lo, hi = order[int(np.floor(pos))], order[int(np.ceil(pos))]
        print(
            f"p{q} {np.percentile(cpu, q):.2f} ms: between queries {lo} ({cpu[lo]:.2f} ms) "
            f"and {hi} ({cpu[hi]:.2f} ms)"
        )
    if args.passes > 1:
        print(
            f"least of {args.passes} passes per query: p50 {np.percentile(least, 50):.3f} ms, "
            f"p95 {np.percentile(least, 95):.2f} ms, sum {least.sum():.1f} ms"
        )


def main() -> None:
    print_machine()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", default="1k_spheres,narrow")
    parser.add_argument("--fair-queries", type=int, default=40)
    parser.add_argument("--query-seed", type=int, default=11)
    parser.add_argument("--no-memory", action="store_true")
    parser.add_argument("--passes", type=int, default=1)
    args = parser.parse_args()
    warm_up()
    steps = Steps()
    steps.wrap()
    memory = (experience.recall, experience.remember, experience.guide)
    if args.no_memory:
        experience.recall = lambda *_a: None
        experience.remember = lambda *_a, **_k: None
        experience.guide = lambda *_a: np.empty((0, 3))
    try:
        for kind in args.scenes.split(","):
            scene_rows(kind, args, steps)
    finally:
        experience.recall, experience.remember, experience.guide = memory
        steps.unwrap()
    print(
        "cpu ms: the whole plan; walk: the walk with its recall and simplification; search: "
        "the compiled searches with their simplifications; proofs: the region map's and the "
        "obstacles' (process_time)"
    )


if __name__ == "__main__":
    main()
