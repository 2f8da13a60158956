"""Soak: mixed requests at high concurrency against a real service, twice, with memory.

Starts ``planner serve`` on a free loopback port, then runs two rounds of ``--seconds`` each
at ``--concurrency`` (default 32 for 60 s) of a seeded mix: fk, analyze, small free-space
plans with TOPPRA, plans around a sphere, /v1/timing, a figure, and a few bad requests (a
422 is an expected answer). Prints per round the total, the answers by status, p50 / p95 /
p99 latency, throughput, the load average, and the resident memory (RSS) of the server and
of its worker processes before and after; the rounds' RSS should agree within a few percent
(no leak). The clients are light: ``--concurrency`` threads, each with its own keep-alive
``http.client`` connection (benchmarks/_light.py), so the client's own cost does not hide the
server's (httpx spends ~2 ms per request). Ends with the rounds as a Markdown table.

    .venv/bin/python benchmarks/soak.py [--seconds 60] [--concurrency 32] [--workers 2]
"""

from __future__ import annotations

import argparse
import collections
import http.client
import json
import os
import threading
import time
from pathlib import Path

import numpy as np
from _light import LightClient
from _machine import print_machine
from _server import start_service


def _rss_mb(pid: int) -> float:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except FileNotFoundError:
        pass
    return 0.0


def _children(pid: int) -> list[int]:
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            if int(stat.read_text().rsplit(")", 1)[1].split()[1]) == pid:
                out.append(int(stat.parent.name))
        except (FileNotFoundError, ProcessLookupError, IndexError, ValueError):
            continue
    return out


def _memory(server: int) -> str:
    workers = _children(server)
    rss = [_rss_mb(p) for p in workers]
    return f"server {_rss_mb(server):6.0f} MB, {len(workers)} children {sum(rss):6.0f} MB"


def _mix(rng: np.random.Generator, n: int) -> list[tuple[str, str, dict | None]]:
    """(method, path, body) of ``n`` seeded requests."""
    out: list[tuple[str, str, dict | None]] = []
    for _ in range(n):
        q = [float(rng.uniform(-1, 1)), float(rng.uniform(0.8, 1.2)), float(rng.uniform(1.8, 2.2))]
        goal = [x + float(rng.uniform(-0.2, 0.2)) for x in q]
        kind = rng.choice(["fk", "analyze", "plan", "plan_sphere", "timing", "figure", "bad"],
                          p=[0.25, 0.15, 0.25, 0.1, 0.1, 0.05, 0.1])  # fmt: skip
        start = {"q": q, "assembly_mode": "+"}
        if kind == "fk":
            out.append(("POST", "/v1/fk", {"q": q}))
        elif kind == "analyze":
            out.append(("POST", "/v1/analyze", {"q": q, "assembly_mode": "+"}))
        elif kind == "plan":
            out.append(
                (
                    "POST",
                    "/v1/plan",
                    {
                        "start": start,
                        "goal": {"q": goal, "assembly_mode": "+"},
                        "planner": {"seed": 1},
                    },
                )
            )
        elif kind == "plan_sphere":
            out.append(
                (
                    "POST",
                    "/v1/plan",
                    {
                        "start": start,
                        "goal": {"q": goal, "assembly_mode": "+"},
                        "planner": {"seed": 1},
                        "obstacles": [
                            {"type": "sphere", "center": [0.5, 0.0, -0.4], "radius": 0.08}
                        ],
                    },
                )
            )
        elif kind == "timing":
            out.append(("POST", "/v1/timing", {"waypoints": [q, goal]}))
        elif kind == "figure":
            out.append(("GET", "/v1/figures/cartesian_section.png?dpi=40", None))
        else:
            out.append(("POST", "/v1/fk", {"q": [q[0], True, "x"]}))
    return out


def _round(url: str, requests: list, seconds: float, concurrency: int) -> dict:
    """One round: ``concurrency`` threads, each with its own keep-alive light connection
    (:class:`LightClient`), sending the seeded mix in turn for ``seconds``; the round's
    figures (printed, and returned for the table)."""
    statuses: collections.Counter[str] = collections.Counter()
    latencies: list[float] = []
    lock = threading.Lock()
    end = time.monotonic() + seconds
    encoded = [(m, p, None if b is None else json.dumps(b).encode()) for m, p, b in requests]
    load = os.getloadavg()[0]

    def worker(k: int) -> None:
        client = LightClient(url)
        index = k
        mine: list[float] = []
        seen: collections.Counter[str] = collections.Counter()
        while time.monotonic() < end:
            method, path, body = encoded[index % len(encoded)]
            index += concurrency
            t0 = time.perf_counter()
            try:
                status, _, _ = client.request(method, path, body)
                seen[str(status)] += 1
            except (OSError, http.client.HTTPException) as exc:
                seen[type(exc).__name__] += 1
            mine.append(time.perf_counter() - t0)
        client.close()
        with lock:
            latencies.extend(mine)
            statuses.update(seen)

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(concurrency)]
    t0 = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    wall = time.perf_counter() - t0
    ms = np.array(latencies) * 1e3
    row = {
        "requests": len(latencies),
        "by_status": ", ".join(f"{k}: {v}" for k, v in sorted(statuses.items())),
        "p50": float(np.percentile(ms, 50)),
        "p95": float(np.percentile(ms, 95)),
        "p99": float(np.percentile(ms, 99)),
        "rate": len(latencies) / wall,
        "load": f"{load:.1f} -> {os.getloadavg()[0]:.1f}",
    }
    print(
        f"  total {row['requests']} in {wall:.1f} s = {row['rate']:.0f} req/s; "
        f"by status: {row['by_status']}"
    )
    print(
        f"  latency p50 {row['p50']:.1f} ms, p95 {row['p95']:.1f} ms, "
        f"p99 {row['p99']:.1f} ms; load average {row['load']}"
    )
    return row


def main() -> None:
    print_machine()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--concurrency", type=int, default=32)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    args = parser.parse_args()
    settings = {
        "PLANNER_WORKERS": str(args.workers),
        "PLANNER_QUEUE_SIZE": str(args.concurrency * 2),
    }
    proc, url = start_service(settings)
    try:
        requests = _mix(np.random.default_rng(7), 2000)
        print(
            f"soak: {args.workers} workers, concurrency {args.concurrency}, "
            f"{args.seconds:g} s per round"
        )
        print(f"memory at ready:       {_memory(proc.pid)}")
        rows = []
        for k in (1, 2):
            print(f"round {k}:")
            row = _round(url, requests, args.seconds, args.concurrency)
            row["memory"] = _memory(proc.pid)
            rows.append(row)
            print(f"memory after round {k}: {row['memory']}")
        print()
        print(
            "| round | requests | by status | p50 | p95 | p99 | throughput | load (1 min) "
            "| RSS after |"
        )
        print("|---|---|---|---|---|---|---|---|---|")
        for k, row in enumerate(rows, 1):
            print(
                f"| {k} | {row['requests']:,} | {row['by_status']} | {row['p50']:.0f} ms | "
                f"{row['p95']:.0f} ms | {row['p99']:.0f} ms | {row['rate']:.0f} req/s | "
                f"{row['load']} | {row['memory']} |"
            )
    finally:
        proc.terminate()
        proc.wait(timeout=60)


if __name__ == "__main__":
    main()
