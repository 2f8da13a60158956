"""Availability under kills: can a client make the pool cold?

A client of small plans (one keep-alive connection, back to back) runs in windows of
``--window`` seconds, alternately undisturbed and disturbed, side by side in one run. In a
disturbed window an unfriendly client either submits a long job and cancels it at once, once a
second (``pairs``: each cancel of a running job is a worker kill), or sends a request of
seconds of work and drops the connection before the answer (``drops``, 20 over the disturbed
time: the client gone, a kill), or 16 clients send 6 MB plans back to back (``bodies``: then the
measured client is a probe of ``/v1/health``, every 10 ms). The table gives the small client's rate and p50 / p99 latency in each kind of window, the ratio to
the undisturbed rate, the kills the pool counted and the fewest warm workers seen (sampled
from ``/metrics`` between requests). Before the warm template, one pair a second left 0 warm
workers in 26 of 30 samples and the small client's p90 at 4.8 s.

    python benchmarks/availability.py                  # 60 s disturbed per kind, 2 workers
    python benchmarks/availability.py --window 5 --seconds 20
"""

from __future__ import annotations

import argparse
import http.client
import itertools
import json
import socket
import statistics
import threading
import time

from _light import LightClient
from _machine import machine_line
from _server import start_service

SMALL = {
    "start": {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"},
    "goal": {"q": [0.3, 2.2, 1.1], "assembly_mode": "+"},
    "timing": {"method": "ruckig"},
}


def _long_work(i: int) -> dict:
    """Seconds of work (a design optimisation of the conditioning), a new one each time: the
    reach differs, so no cache of a worker answers it (a plan is no use here: the planner
    proves a walled-off goal unreachable within milliseconds, and a region map takes 60 ms)."""
    return {"objective": "gci", "maxiter": 30, "reach": 1.0 + 1e-4 * i, "seed": i}


def _metric(client: LightClient, name: str) -> float:
    try:
        _, body, _ = client.request("GET", "/metrics")
    except (OSError, http.client.HTTPException):  # an idle keep-alive closed: once more
        _, body, _ = client.request("GET", "/metrics")
    for line in body.decode().splitlines():
        if line.startswith(name + " "):
            return float(line.split()[1])
    return float("nan")


def _pairs(url: str, stop: threading.Event) -> None:
    """One submit + cancel pair a second."""
    c = LightClient(url)
    for i in itertools.count():
        if stop.is_set():
            return
        t0 = time.monotonic()
        job = {"kind": "design_optimize", "request": _long_work(i)}
        status, body, _ = c.request("POST", "/v1/jobs", job)
        if status == 202:
            c.request("DELETE", f"/v1/jobs/{json.loads(body)['id']}")
        stop.wait(max(0.0, 1.0 - (time.monotonic() - t0)))


def _drops(url: str, stop: threading.Event, period_s: float) -> None:
    """A long request whose connection is dropped 0.3 s after it was sent, every ``period_s``."""
    host, port = url.removeprefix("http://").split(":")
    for i in itertools.count(10**6):
        if stop.is_set():
            return
        body = json.dumps(_long_work(i)).encode()
        head = (
            f"POST /v1/design/optimize HTTP/1.1\r\nHost: {host}\r\n"
            f"Content-Type: application/json\r\nContent-Length: {len(body)}\r\n\r\n"
        ).encode()
        with socket.create_connection((host, int(port))) as s:
            s.sendall(head + body)
            stop.wait(0.3)
        stop.wait(period_s)


#: A plan whose body is ~6 MB: a cloud of 200,000 points far from the robot.
BIG_PLAN = {
    **SMALL,
    "obstacles": [
        {
            "type": "points",
            "radius": 0.01,
            "points": [[3.0 + 1e-6 * i, 3.0 + 1e-3 * (i % 1000), 3.0] for i in range(200_000)],
        }
    ],
}


def _bodies(url: str, stop: threading.Event, clients: int = 16) -> None:
    """``clients`` clients, each sending the 6 MB plan back to back."""
    body = json.dumps(BIG_PLAN).encode()

    def one() -> None:
        c = LightClient(url)
        while not stop.is_set():
            try:
                c.request("POST", "/v1/plan", body)
            except OSError:
                pass
        c.close()

    threads = [threading.Thread(target=one, daemon=True) for _ in range(clients)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)


def _window(
    url: str, seconds: float, probe: LightClient, health: bool = False
) -> tuple[list[float], float]:
    """Small plans (or, with ``health``, ``GET /v1/health``) back to back for ``seconds``:
    (latencies, fewest warm workers seen)."""
    c = LightClient(url)
    lat: list[float] = []
    fewest = float("inf")
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            if health:
                status, _, s = c.request("GET", "/v1/health")
                time.sleep(0.01)  # a probe's pace, not a flood
            else:
                status, _, s = c.request("POST", "/v1/plan", SMALL)
        except (OSError, http.client.HTTPException):
            status, s = 0, float("nan")  # counted as no answer (the rate falls)
        if status == 200:
            lat.append(s)
        fewest = min(fewest, _metric(probe, "planner_pool_warm_workers"))
    c.close()
    return lat, fewest


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--window", type=float, default=10.0, help="seconds per window")
    ap.add_argument("--seconds", type=float, default=60.0, help="disturbed seconds per kind")
    ap.add_argument(
        "--inline-parse-bytes",
        type=int,
        default=None,
        help="PLANNER_INLINE_PARSE_BYTES (default: the service's); 1073741824 parses every "
        "body on the event loop, as before large bodies went to the workers",
    )
    ap.add_argument("--kinds", default="pairs,drops,bodies", help="disturbances, comma-separated")
    args = ap.parse_args()
    print(f"# availability under kills ({machine_line()})")
    settings = {"PLANNER_WORKERS": str(args.workers), "PLANNER_MAX_BODY_BYTES": str(64 << 20)}
    if args.inline_parse_bytes is not None:
        settings["PLANNER_INLINE_PARSE_BYTES"] = str(args.inline_parse_bytes)
    proc, url = start_service(settings, quiet=True)
    probe = LightClient(url)
    try:
        rows = []
        rounds = max(1, round(args.seconds / args.window))
        for kind in args.kinds.split(","):
            calm: list[float] = []
            rough: list[float] = []
            fewest = float("inf")
            kills0 = _metric(probe, "planner_pool_worker_kills_total")
            for i in range(rounds):
                print(f"{kind}: round {i + 1} of {rounds}", flush=True)
                health = kind == "bodies"  # what a load balancer's probe sees
                calm += _window(url, args.window, probe, health)[0]
                stop = threading.Event()
                period = args.seconds / 20.0  # 20 drops over the disturbed time
                target = {
                    "pairs": (_pairs, (url, stop)),
                    "drops": (_drops, (url, stop, period)),
                    "bodies": (_bodies, (url, stop)),
                }[kind]
                t = threading.Thread(target=target[0], args=target[1], daemon=True)
                t.start()
                lat, low = _window(url, args.window, probe, health)
                stop.set()
                t.join(15)
                rough += lat
                fewest = min(fewest, low)
            kills = _metric(probe, "planner_pool_worker_kills_total") - kills0
            rows.append((kind, calm, rough, kills, fewest))
        seconds = rounds * args.window
        print()
        print(
            "| disturbance | window | answers/s | p50 ms | p99 ms | rate vs undisturbed | kills | fewest warm |"
        )
        print("|---|---|---|---|---|---|---|---|")
        for kind, calm, rough, kills, fewest in rows:
            for name, lat in (("undisturbed", calm), (kind, rough)):
                q = statistics.quantiles(lat, n=100) if len(lat) > 1 else [lat[0]] * 99
                rate = len(lat) / seconds
                ratio = rate / (len(calm) / seconds)
                extra = f"{kills:.0f} | {fewest:.0f}" if name == kind else "|"
                print(
                    f"| {kind} | {name} | {rate:.1f} | {1e3 * q[49]:.1f} | {1e3 * q[98]:.1f} "
                    f"| {ratio:.2f} | {extra} |"
                )
    finally:
        probe.close()
        proc.terminate()
        proc.wait(30)


if __name__ == "__main__":
    main()
