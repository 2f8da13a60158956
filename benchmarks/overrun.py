"""How long a hostile request holds a worker after its answer: the reproducers of a job that
outlived its 504 (a 2 KB ``/v1/cartesian`` over 1000 m links through 50 far waypoints with
``kappa_max`` 1e6; ``/v1/design/optimize`` over 8192 samples), and a client that disconnects
from the same Cartesian request.

Starts ``planner serve`` with one warm worker and a short request budget
(``--timeout``, default 5 s), sends each request and measures, side by side in one run:
when the answer came (504 expected), when the worker was free again (``planner_pool_in_flight``
back to 0 in ``/metrics``), and whether the job stopped itself or its worker was killed
(``planner_pool_worker_kills``). Before the deadline checks and the watchdog the Cartesian
job held its worker for more than 200 s after a 30 s budget.

Run: ``python benchmarks/overrun.py [--timeout 5] [--grace 0.5]``.
"""

from __future__ import annotations

import argparse
import json
import re
import socket
import sys
import time
from pathlib import Path

import httpx
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _machine import print_machine  # noqa: E402
from _server import start_service, wait_ready  # noqa: E402

CARTESIAN = {
    "design": {"L0": 0.0, "L1": 1000.0, "L2": 1000.0},
    "start": {"q": [0.3, 2.0, 1.0], "assembly_mode": "+"},
    "waypoints": np.round(np.random.default_rng(0).uniform(-1500, 1500, (50, 3)), 1).tolist(),
    "margins": {"kappa_max": 1e6},
}
OPTIMIZE = {"objective": "well_conditioned_volume", "n_samples": 8192, "maxiter": 30}


def _metric(url: str, name: str) -> float:
    text = httpx.get(f"{url}/metrics", timeout=30).text
    m = re.search(rf"^{name} ([0-9.e+]+)$", text, re.M)
    return float(m.group(1)) if m else float("nan")


def _wait_free(url: str, t0: float, limit_s: float) -> float:
    while _metric(url, "planner_pool_in_flight") > 0:
        if time.monotonic() - t0 > limit_s:
            return float("inf")
        time.sleep(0.05)
    return time.monotonic() - t0


def _disconnect(port: int, path: str, body: dict, after_s: float) -> None:
    data = json.dumps(body).encode()
    with socket.create_connection(("127.0.0.1", port)) as sock:
        sock.sendall(
            f"POST {path} HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
            f"Content-Length: {len(data)}\r\n\r\n".encode()
            + data
        )
        time.sleep(after_s)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timeout", type=float, default=5.0, help="request budget, s")
    parser.add_argument("--grace", type=float, default=0.5, help="overrun grace, s")
    args = parser.parse_args()
    print_machine()
    proc, url = start_service(
        {
            "PLANNER_WORKERS": "1",
            "PLANNER_REQUEST_TIMEOUT_S": str(args.timeout),
            "PLANNER_OVERRUN_GRACE_S": str(args.grace),
        },
        ready_s=600,
        quiet=True,
    )
    port = int(url.rsplit(":", 1)[1])
    try:
        wait_ready(url, 600)
        with open("/proc/loadavg") as f:
            print(f"load average at start: {f.read().split()[0]}")
        print(f"request budget {args.timeout:g} s, overrun grace {args.grace:g} s, 1 worker\n")
        print(f"{'request':<34} {'answer':>6} {'answered s':>10} {'freed s':>8} {'stopped by':>11}")
        cases = [
            ("/v1/cartesian (1000 m links)", "/v1/cartesian", CARTESIAN, False),
            ("/v1/design/optimize (8192)", "/v1/design/optimize", OPTIMIZE, False),
            ("/v1/cartesian, client gone at 1 s", "/v1/cartesian", CARTESIAN, True),
        ]
        for label, path, body, disconnect in cases:
            wait_ready(url, 600)
            kills = _metric(url, "planner_pool_worker_kills_total")
            t0 = time.monotonic()
            if disconnect:
                _disconnect(port, path, body, 1.0)
                status, answered = "-", float("nan")
            else:
                r = httpx.post(f"{url}{path}", json=body, timeout=args.timeout + 600)
                status, answered = str(r.status_code), time.monotonic() - t0
            freed = _wait_free(url, t0, args.timeout + 600)
            killed = _metric(url, "planner_pool_worker_kills_total") > kills
            by = "watchdog" if killed else "itself"
            print(f"{label:<34} {status:>6} {answered:>10.2f} {freed:>8.2f} {by:>11}")
    finally:
        proc.terminate()
        proc.wait(timeout=60)


if __name__ == "__main__":
    main()
