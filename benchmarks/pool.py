"""Worker pool benchmark: the round trip of a job that does nothing, through
:class:`planner_api.pool.WorkerPool` alone (no HTTP), on asyncio's loop and on uvloop's
(what ``planner serve`` runs on).

What one crossing to a worker costs: pickling both ways, the job pipe, the worker's wake-up,
the answer pipe read by the event loop. Back to back (the cores stay awake) and with a pause
between calls (the cores go idle, as between the requests of a lone client: the wake-ups then
cost what an idle CPU takes to wake, which on a VM is most of it).

    PYTHONPATH=src:. python benchmarks/pool.py [--calls 500]
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import time

import uvloop
from _machine import print_machine

from planner_api.pool import WorkerPool


def _nothing(x: bytes) -> bytes:
    return x


async def _rows(calls: int) -> list[tuple[float, float, float]]:
    pool = WorkerPool(1, 1, warm_up=None)
    await pool.start()
    try:
        while pool.state != "ready":
            await asyncio.sleep(0.02)
        rows = []
        for pause in (0.0, 0.002, 0.005):
            seconds = []
            for _ in range(calls + 50):
                t0 = time.perf_counter()
                await pool.run(_nothing, b"x" * 100, deadline=time.monotonic() + 30)
                seconds.append(time.perf_counter() - t0)
                if pause:
                    time.sleep(pause)  # the loop's thread sleeps: the cores go idle
            ordered = sorted(seconds[50:])
            rows.append((pause, statistics.median(ordered), ordered[int(0.95 * len(ordered))]))
        return rows
    finally:
        pool.shutdown(timeout_s=5)


def main() -> None:
    print_machine()
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--calls", type=int, default=500)
    args = parser.parse_args()
    print(f"{'loop':8} {'pause between calls':>20} {'p50':>9} {'p95':>9}")
    for name, factory in (("asyncio", asyncio.new_event_loop), ("uvloop", uvloop.new_event_loop)):
        with asyncio.Runner(loop_factory=factory) as runner:
            for pause, p50, p95 in runner.run(_rows(args.calls)):
                print(f"{name:8} {pause * 1e3:17.0f} ms {p50 * 1e3:6.3f} ms {p95 * 1e3:6.3f} ms")


if __name__ == "__main__":
    main()
