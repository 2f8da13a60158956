"""Soak: mixed requests at high concurrency against a real service, twice, with memory.

Starts ``planner serve`` on a free loopback port, then runs two rounds of ``--seconds`` each
at ``--concurrency`` (default 32 for 60 s) of a seeded mix: fk, analyze, small free-space
plans with TOPPRA, plans around a sphere, /v1/timing, a figure, and a few bad requests (a
422 is an expected answer). Prints per round the total, the answers by status, p50 / p95 /
p99 latency, throughput, and the resident memory (RSS) of the server and of its worker
processes before and after; the rounds' RSS should agree within a few percent (no leak).

    .venv/bin/python benchmarks/soak.py [--seconds 60] [--concurrency 32] [--workers 2]
"""

from __future__ import annotations

import argparse
import asyncio
import collections
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import numpy as np
from _machine import print_machine

ROOT = Path(__file__).resolve().parents[1]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


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
            out.append(("POST", "/v1/plan", {"start": start,
                        "goal": {"q": goal, "assembly_mode": "+"}, "planner": {"seed": 1}}))  # fmt: skip
        elif kind == "plan_sphere":
            out.append(("POST", "/v1/plan", {"start": start,
                        "goal": {"q": goal, "assembly_mode": "+"}, "planner": {"seed": 1},
                        "obstacles": [{"type": "sphere", "center": [0.5, 0.0, -0.4],
                                       "radius": 0.08}]}))  # fmt: skip
        elif kind == "timing":
            out.append(("POST", "/v1/timing", {"waypoints": [q, goal]}))
        elif kind == "figure":
            out.append(("GET", "/v1/figures/cartesian_section.png?dpi=40", None))
        else:
            out.append(("POST", "/v1/fk", {"q": [q[0], True, "x"]}))
    return out


async def _round(url: str, requests: list, seconds: float, concurrency: int) -> None:
    statuses: collections.Counter[str] = collections.Counter()
    latencies: list[float] = []
    end = time.monotonic() + seconds
    index = 0

    async def worker(client: httpx.AsyncClient) -> None:
        nonlocal index
        while time.monotonic() < end:
            method, path, body = requests[index % len(requests)]
            index += 1
            t0 = time.perf_counter()
            try:
                r = await client.request(method, url + path, json=body)
                statuses[str(r.status_code)] += 1
            except httpx.HTTPError as exc:
                statuses[type(exc).__name__] += 1
            latencies.append(time.perf_counter() - t0)

    limits = httpx.Limits(max_connections=concurrency, max_keepalive_connections=concurrency)
    async with httpx.AsyncClient(timeout=60, limits=limits) as client:
        t0 = time.perf_counter()
        await asyncio.gather(*(worker(client) for _ in range(concurrency)))
        wall = time.perf_counter() - t0
    ms = np.array(latencies) * 1e3
    by_status = ", ".join(f"{k}: {v}" for k, v in sorted(statuses.items()))
    print(f"  total {len(latencies)} in {wall:.1f} s = {len(latencies) / wall:.0f} req/s; "
          f"by status: {by_status}")  # fmt: skip
    print(f"  latency p50 {np.percentile(ms, 50):.1f} ms, p95 {np.percentile(ms, 95):.1f} ms, "
          f"p99 {np.percentile(ms, 99):.1f} ms")  # fmt: skip


def main() -> None:
    print_machine()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--concurrency", type=int, default=32)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    args = parser.parse_args()
    port = _free_port()
    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'src'}{os.pathsep}{ROOT}",
           "PLANNER_WORKERS": str(args.workers), "PLANNER_QUEUE_SIZE": str(args.concurrency * 2)}  # fmt: skip
    proc = subprocess.Popen(
        [sys.executable, "-m", "planner_cli", "serve", "--port", str(port), "--log-level", "warning"],
        cwd=ROOT, env=env,
    )  # fmt: skip
    url = f"http://127.0.0.1:{port}"
    try:
        end = time.monotonic() + 300
        while True:
            try:
                if httpx.get(f"{url}/v1/ready", timeout=1).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if time.monotonic() > end or proc.poll() is not None:
                raise RuntimeError("the service did not become ready")
            time.sleep(0.2)
        requests = _mix(np.random.default_rng(7), 2000)
        print(f"soak: {args.workers} workers, concurrency {args.concurrency}, "
              f"{args.seconds:g} s per round")  # fmt: skip
        print(f"memory at ready:       {_memory(proc.pid)}")
        for k in (1, 2):
            print(f"round {k}:")
            asyncio.run(_round(url, requests, args.seconds, args.concurrency))
            print(f"memory after round {k}: {_memory(proc.pid)}")
    finally:
        proc.terminate()
        proc.wait(timeout=60)


if __name__ == "__main__":
    main()
