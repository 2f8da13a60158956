"""Service benchmark: latency and throughput of the HTTP service on loopback.

Starts ``planner serve`` (uvicorn, ``--workers`` processes) on a free port. First the
per-request overhead: a bare FastAPI app on uvicorn (the floor: its ``async def`` endpoint; its
``def`` one, the earlier rounds' floor, beside it) and the service, each with one
light keep-alive client (``http.client``), interleaved request by request in the same run,
with the event-loop process's CPU per request (/proc) and the first plan and fk right after
``/v1/ready`` said ready against their steady-state medians (issue 43's goals);
then a small plans' throughput from light clients against workers x the in-process rate.
Then a fixed, seeded set of requests with the typed async client at concurrency 1, 8 and 32:
p50 / p95 / p99 latency and throughput per endpoint, next to the same work done in-process
(the job function called directly), and their ratio.

Endpoints: ``/v1/fk`` (the cheapest call: the overhead floor), ``/v1/analyze``, and
``/v1/plan`` with free-space joint goals (without timing, and with toppra) when the planner
is in this build, ``/v1/timing`` (toppra on 5-waypoint joint paths) and ``/v1/cartesian``
(0.1 m lines of P in seeded directions from one start, toppra at 0.25 m/s; some stop short,
which is work too).

    PYTHONPATH=src:. python benchmarks/service.py [--workers 2] [--requests 400]
        [--endpoints fk analyze timing plan plan+toppra cartesian]
    PYTHONPATH=src:. python benchmarks/service.py --modes [--modes-queries 20]
        [--modes-budget 2.0]

``--modes`` (issue 17's goals measured through HTTP): mode changes and the proof of no path
as ``/v1/plan`` requests, one at a time, against the library's :func:`planner.planning.plan`
on the same queries in this process. The scenes are those of ``benchmarks/planning.py --map``
(imported, not copied): for each design of its ``DESIGNS``, the mode-change queries of
``build_mode_change_queries`` without and with the 5 spheres, and the ``disconnected_queries``
of its cut design (5 s budget, ``proven_infeasible`` expected). The design travels in the
request body; each worker builds a design's region map on the first request of that design
and keeps it in its LRU cache (the default design's is built at warm-up), so the first
request of each row is reported apart (``first``: cold when the row's design is new to the
worker, and likewise in-process) from the rest (p50 / p95 / max). Sequential requests all go
to the first idle worker, so one worker serves the whole table.
"""

from __future__ import annotations

import argparse
import asyncio
import importlib.util
import os
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import httpx
import numpy as np
from _light import LightClient
from _machine import print_machine
from _server import ROOT, free_port, start_service

from planner.client import AsyncPlannerClient
from planner.endpoints import cartesian as cartesian_jobs
from planner.endpoints import kinematics as kinematics_jobs
from planner.endpoints import plan as plan_jobs
from planner.endpoints import timing as timing_jobs
from planner.wire import (
    AnalyzeRequest,
    CartesianRequest,
    FKRequest,
    PlanRequest,
    TimingRequest,
)


def _start_server(workers: int) -> tuple[subprocess.Popen[bytes], str]:
    """The service with ``workers`` worker processes and room for the benchmark's queue."""
    return start_service({"PLANNER_WORKERS": str(workers), "PLANNER_QUEUE_SIZE": "256"})


#: The floor: a bare FastAPI app on uvicorn answering a tiny JSON POST (no validation of
#: ours, no worker process, no middleware), served the same way as the service. ``/echo`` is
#: an ``async def`` endpoint, the fastest a FastAPI user writes (the floor the goals are
#: checked against); ``/echo-def`` the same as a plain ``def``, which FastAPI runs in its
#: thread pool (a thread hop per request: about twice the CPU), the floor of the rounds
#: before (docs/service.md, "Per-request overhead", says which floor each figure used).
#: ``/echo-hop`` is ``/echo`` with a hand-over to another process on the way, the least a
#: plan's hand-over to its worker can cost the loop: the validated body's JSON written to a
#: child process's pipe, the loop asleep until the child echoes it back (read when the pipe
#: wakes the loop, as the service's pool reads its workers), the echoed bytes the answer.
#: The child is started on the first such request; it ends when the app's pipe closes.
_BARE_APP = """
import asyncio
import os
import subprocess
import sys

import uvicorn
from fastapi import FastAPI, Response
from pydantic import BaseModel

_ECHO = "import sys\\nfor line in sys.stdin.buffer:\\n    sys.stdout.buffer.write(line)\\n" \\
    "    sys.stdout.buffer.flush()"
_hop = {}

async def hand_over(data: bytes) -> bytes:
    loop = asyncio.get_running_loop()
    if not _hop:
        child = subprocess.Popen([sys.executable, "-c", _ECHO], stdin=subprocess.PIPE,
                                 stdout=subprocess.PIPE, bufsize=0)
        out = child.stdout.fileno()
        os.set_blocking(out, False)
        _hop.update(child=child, waiter=None)

        def readable() -> None:
            chunk = os.read(out, 65536)
            waiter = _hop["waiter"]
            if waiter is not None and not waiter.done():
                waiter.set_result(chunk)

        loop.add_reader(out, readable)
    waiter = _hop["waiter"] = loop.create_future()
    os.write(_hop["child"].stdin.fileno(), data + b"\\n")
    return (await waiter).rstrip(b"\\n")

class Body(BaseModel):
    q: list[float]

app = FastAPI()

@app.post("/echo")
async def echo(body: Body) -> dict:
    return {"q": body.q}

@app.post("/echo-def")
def echo_def(body: Body) -> dict:
    return {"q": body.q}

@app.post("/echo-hop")
async def echo_hop(body: Body) -> Response:
    answer = await hand_over(body.model_dump_json().encode())
    return Response(answer, media_type="application/json")

uvicorn.run(app, host="127.0.0.1", port=int(__import__("sys").argv[1]), log_level="warning",
            access_log=False)
"""


def _start_bare() -> tuple[subprocess.Popen[bytes], str]:
    port = free_port()
    proc = subprocess.Popen([sys.executable, "-c", _BARE_APP, str(port)], cwd=ROOT)
    url = f"http://127.0.0.1:{port}"
    end = time.monotonic() + 60
    while time.monotonic() < end:
        try:
            httpx.post(f"{url}/echo", json={"q": [0, 1, 2]}, timeout=1)
            return proc, url
        except httpx.HTTPError:
            time.sleep(0.1)
    proc.kill()
    raise RuntimeError("the bare app did not start")


def _cpu_s(pid: int) -> float:
    """CPU seconds of process ``pid`` so far, all its threads: the scheduler's own count in
    nanoseconds (``/proc/<pid>/task/*/schedstat``), not the 10 ms ticks of ``/proc/<pid>/stat``,
    which on a loaded machine charge whichever process the tick finds running."""
    total = 0
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            total += int((task / "schedstat").read_text().split()[0])
        except (FileNotFoundError, ProcessLookupError):  # a thread that just ended
            continue
    return total / 1e9


def _loop_cpu_s(pid: int) -> float:
    """CPU seconds of the main thread of ``pid`` (uvicorn's event loop), in nanoseconds."""
    return int(Path(f"/proc/{pid}/schedstat").read_text().split()[0]) / 1e9


def _floor_rows(
    url: str, pid: int, n: int, rng: np.random.Generator, workers: int, throughput: bool = True
) -> None:
    """The per-request overhead against a bare FastAPI app on uvicorn (the floor), with one
    light keep-alive client per server, interleaved request by request so that both see the
    same machine load (issue goals: /v1/fk p50 <= 1.3 x bare p50; a small free-space plan p50
    <= bare p50 + 1.5 x its in-process time; throughput >= 0.9 x workers x in-process rate).

    The plan's in-process time is measured twice: in a tight loop before (the job hot in the
    caches) and interleaved with the requests, one call after each plan request, under the
    conditions the worker meets (caches cooled by the requests between two jobs); the goal
    is checked against the interleaved one, and the worker's own time for the job (the mean
    of ``planner_job_duration_seconds`` from ``/metrics``) is shown beside it."""
    bare, bare_url = _start_bare()
    try:
        fk_bodies = [r.model_dump_json().encode() for r in _requests("fk", n, rng)]
        plans = _solvable("plan", n, rng)
        plan_bodies = [r.model_dump_json(exclude_none=True).encode() for r in plans]
        # the same plans with a broken rule: the 422's cost (its body crosses to a worker
        # first, then FastAPI's path answers: docs/service.md, "How requests are served")
        bad_bodies = [
            body.replace(b'"start":{"q":[', b'"start":{"q":["x",', 1) for body in plan_bodies
        ]
        _in_process(plan_jobs.plan, plans[:20])
        plan_local = statistics.median(_in_process(plan_jobs.plan, plans)) * 1e3
        floor, service = LightClient(bare_url), LightClient(url)
        # the service was just announced ready: its first requests, before any warming here
        # (the connection opened by a probe first, as a client's would be by any request)
        service.call("GET", "/v1/health")
        first_plan = service.call("POST", "/v1/plan", plan_bodies[0])
        first_fk = service.call("POST", "/v1/fk", fk_bodies[0])
        rows: dict[str, list[float]] = {
            "bare FastAPI POST": [], "bare POST, def endpoint": [], "/v1/health (GET)": [],
            "/v1/fk": [],
            "/v1/plan (free, none)": [], "in-process plan job": [], "/v1/plan 422 (bad q)": [],
        }  # fmt: skip
        for i in range(min(n, 50)):  # warm connections, caches and workers
            floor.call("POST", "/echo", fk_bodies[i])
            floor.call("POST", "/echo-def", fk_bodies[i])
            service.call("POST", "/v1/fk", fk_bodies[i])
            service.call("POST", "/v1/plan", plan_bodies[i])
        load = os.getloadavg()[0]
        job_s0, job_n0 = _worker_job_seconds(service)
        cpu = dict.fromkeys(
            ("bare", "bare loop", "bare def", "bare def loop", "fk", "fk loop", "plan",
             "plan loop", "422 loop"),
            0.0,
        )  # fmt: skip
        for i in range(n):
            c0, l0 = _cpu_s(bare.pid), _loop_cpu_s(bare.pid)
            rows["bare FastAPI POST"].append(floor.call("POST", "/echo", fk_bodies[i]))
            c1, l1 = _cpu_s(bare.pid), _loop_cpu_s(bare.pid)
            rows["bare POST, def endpoint"].append(floor.call("POST", "/echo-def", fk_bodies[i]))
            cpu["bare"] += c1 - c0
            cpu["bare loop"] += l1 - l0
            cpu["bare def"] += _cpu_s(bare.pid) - c1
            cpu["bare def loop"] += _loop_cpu_s(bare.pid) - l1
            rows["/v1/health (GET)"].append(service.call("GET", "/v1/health"))
            c0, l0 = _cpu_s(pid), _loop_cpu_s(pid)
            rows["/v1/fk"].append(service.call("POST", "/v1/fk", fk_bodies[i]))
            c1, l1 = _cpu_s(pid), _loop_cpu_s(pid)
            rows["/v1/plan (free, none)"].append(service.call("POST", "/v1/plan", plan_bodies[i]))
            cpu["fk"] += c1 - c0
            cpu["fk loop"] += l1 - l0
            cpu["plan"] += _cpu_s(pid) - c1
            cpu["plan loop"] += _loop_cpu_s(pid) - l1
            t0 = time.perf_counter()
            plan_jobs.plan(plans[i])
            rows["in-process plan job"].append(time.perf_counter() - t0)
            l0 = _loop_cpu_s(pid)
            status, _, seconds = service.request("POST", "/v1/plan", bad_bodies[i])
            cpu["422 loop"] += _loop_cpu_s(pid) - l0
            assert status == 422, status
            rows["/v1/plan 422 (bad q)"].append(seconds)
        print(
            f"light client (http.client, one keep-alive connection per server), {n} requests "
            f"per row interleaved with the bare app; load average {load:.1f} at the start, "
            f"{os.getloadavg()[0]:.1f} at the end"
        )
        for name, lat in rows.items():
            print(f"{name:24} p50 {_pct(lat, 50):7.2f} ms   p95 {_pct(lat, 95):7.2f} ms")
        job_s1, job_n1 = _worker_job_seconds(service)
        bare_p50 = _pct(rows["bare FastAPI POST"], 50)
        def_p50 = _pct(rows["bare POST, def endpoint"], 50)
        fk_p50 = _pct(rows["/v1/fk"], 50)
        plan_p50 = _pct(rows["/v1/plan (free, none)"], 50)
        interleaved = _pct(rows["in-process plan job"], 50)
        worker_ms = (job_s1 - job_s0) / max(job_n1 - job_n0, 1) * 1e3
        print(
            f"/v1/fk p50 / bare p50 = {fk_p50 / bare_p50:.2f} (goal <= 1.3; over the def "
            f"endpoint's p50, the earlier floor: {fk_p50 / def_p50:.2f})"
        )
        ms = {k: v / n * 1e3 for k, v in cpu.items()}
        print(
            f"server CPU per request (schedstat, ns), the event loop's thread / the whole "
            f"process (the worker's not counted): /v1/fk {ms['fk loop']:.3f} / {ms['fk']:.3f} "
            f"ms, /v1/plan {ms['plan loop']:.3f} / {ms['plan']:.3f} ms (goal: the event "
            f"loop's <= 0.3 ms); the event loop's for a plan's 422 {ms['422 loop']:.3f} ms"
        )
        print(
            f"bare app CPU per request, its event loop's thread / the whole process: async "
            f"def endpoint (the floor) {ms['bare loop']:.3f} / {ms['bare']:.3f} ms, def "
            f"endpoint (thread pool; the earlier rounds' floor) {ms['bare def loop']:.3f} / "
            f"{ms['bare def']:.3f} ms; the service's loop over the floor's loop: /v1/fk "
            f"{ms['fk loop'] - ms['bare loop']:+.3f} ms, /v1/plan "
            f"{ms['plan loop'] - ms['bare loop']:+.3f} ms"
        )
        print(
            f"first requests after /v1/ready: plan {first_plan * 1e3:.2f} ms = "
            f"{first_plan * 1e3 / plan_p50:.1f} x the plan p50 (goal <= 2), fk "
            f"{first_fk * 1e3:.2f} ms = {first_fk * 1e3 / fk_p50:.1f} x the fk p50"
        )
        print(
            f"plan p50 - bare p50 = {plan_p50 - bare_p50:.2f} ms against 1.5 x in-process "
            f"{interleaved:.2f} ms (interleaved) = {1.5 * interleaved:.2f} ms (goal: at most "
            f"that); in-process in a tight loop {plan_local:.2f} ms; the job in the worker "
            f"(/metrics, mean, its JSON included) {worker_ms:.2f} ms; over the def endpoint's "
            f"p50 (the earlier floor): {plan_p50 - def_p50:.2f} ms"
        )
        if throughput:
            _throughput_rows(url, pid, rng, workers)
    finally:
        bare.terminate()
        bare.wait(timeout=30)


def _worker_job_seconds(client: LightClient) -> tuple[float, float]:
    """(sum of seconds, count) of the plan jobs the workers ran so far (``/metrics``)."""
    _, text, _ = client.request("GET", "/metrics")
    total = count = 0.0
    for line in text.decode().splitlines():
        if line.startswith("planner_job_duration_seconds_") and 'job="plan"' in line:
            name, value = line.rsplit(" ", 1)
            if name.startswith("planner_job_duration_seconds_sum"):
                total += float(value)
            elif name.startswith("planner_job_duration_seconds_count"):
                count += float(value)
    return total, count


def _children(pid: int) -> list[int]:
    """The child processes of ``pid`` (its worker processes), from /proc."""
    found: list[int] = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            found += [int(c) for c in (task / "children").read_text().split()]
        except OSError:
            pass
    return found


#: The throughput rows: (request kind of :func:`_requests`, what the row is called). The
#: small plans (~2 ms of job each) are the issue's measure; the far ones around a sphere (~5 ms)
#: show how the fixed cost per request weighs less as the job grows.
THROUGHPUT_KINDS = (
    ("plan+toppra", "small plans + toppra"),
    ("plan+toppra+far", "far plans around a sphere + toppra"),
)


def _throughput_rows(url: str, pid: int, rng: np.random.Generator, workers: int) -> None:
    """One :func:`_throughput_row` per kind of :data:`THROUGHPUT_KINDS`, the service warmed
    with 50 of its requests first."""
    for kind, label in THROUGHPUT_KINDS:
        plans = _solvable(kind, 200, rng)
        bodies = [r.model_dump_json().encode() for r in plans]
        warm = LightClient(url)
        for body in bodies[:50]:
            warm.call("POST", "/v1/plan", body)
        warm.close()
        _throughput_row(url, pid, plans, bodies, workers, label)


def _throughput_row(
    url: str, pid: int, plans: list, bodies: list[bytes], workers: int, label: str
) -> None:
    """Plans from ``2 x workers`` light clients at once, against ``workers`` x the in-process
    rate measured just before (goal: >= 0.9). The plans are timed by TOPPRA (a few ms of work
    each): for sub-millisecond jobs the HTTP parsing itself, on the same cores, bounds the rate.

    With the CPU accounting of the run (/proc): CPU seconds per request of the server's event
    loop process, of its workers and of the clients (this process), and what they imply: on
    ``cores`` cores no rate exceeds cores / (their sum), whatever the service does."""
    # a rate is jobs / time: the mean job time, not the median (the few slow plans, which the
    # clients' requests meet too, weigh in; the median overstated the ideal by ~8 % on an
    # AMD EPYC VM)
    local = statistics.fmean(_in_process(plan_jobs.plan, plans))  # the mix the clients send
    clients = 2 * workers
    counts = [0] * clients
    workers_pids = _children(pid)
    stop = time.perf_counter() + 10.0

    def client(k: int) -> None:
        light = LightClient(url)
        i = k
        while time.perf_counter() < stop:
            light.call("POST", "/v1/plan", bodies[i % len(bodies)])
            counts[k] += 1
            i += clients

    server0, workers0, client0 = _cpu_s(pid), sum(map(_cpu_s, workers_pids)), time.process_time()
    t0 = time.perf_counter()
    threads = [threading.Thread(target=client, args=(k,)) for k in range(clients)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    wall = time.perf_counter() - t0
    n = sum(counts)
    server_ms = (_cpu_s(pid) - server0) / n * 1e3
    workers_ms = (sum(map(_cpu_s, workers_pids)) - workers0) / n * 1e3
    client_ms = (time.process_time() - client0) / n * 1e3
    rate = n / wall
    ideal = workers / local
    cores = len(os.sched_getaffinity(0))
    bound = cores / (server_ms + workers_ms + client_ms) * 1e3
    print(
        f"throughput, {label}, {workers} workers, {clients} light clients, 10 s: "
        f"{rate:.0f} req/s against {workers} x in-process {1 / local:.0f}/s = {ideal:.0f}/s: "
        f"{rate / ideal:.2f} (goal >= 0.9; load average {os.getloadavg()[0]:.1f})"
    )
    print(
        f"  CPU per request: server event loop {server_ms:.2f} ms, workers {workers_ms:.2f} ms "
        f"(in-process job, mean {local * 1e3:.2f} ms), clients {client_ms:.2f} ms; on {cores} cores "
        f"at most {bound:.0f} req/s = {bound / ideal:.2f} x the ideal even on an idle machine"
    )


#: The obstacle of the heavier throughput row (as ``benchmarks/soak.py``'s plans around a sphere).
SPHERE = {"type": "sphere", "center": [0.5, 0.0, -0.4], "radius": 0.08}

#: The start of the Cartesian rows and its P (docs/cartesian.md's example).
CARTESIAN_START = {"q": [-0.2187, 2.8609, 0.2807], "assembly_mode": "+"}
CARTESIAN_P = np.array([0.45, 0.0, 0.1])


def _requests(kind: str, n: int, rng: np.random.Generator) -> list:
    if kind == "cartesian":
        d = rng.normal(size=(n, 3))
        ends = CARTESIAN_P + 0.1 * d / np.linalg.norm(d, axis=1, keepdims=True)
        return [
            CartesianRequest(
                start=CARTESIAN_START, waypoints=[end.tolist()], limits={"cartesian_speed": 0.25}
            )
            for end in ends
        ]
    q = np.column_stack([rng.uniform(-1, 1, n), rng.uniform(0.8, 1.2, n), rng.uniform(1.8, 2.2, n)])
    if kind == "fk":
        return [FKRequest(q=row.tolist(), assembly_mode="+") for row in q]
    if kind == "analyze":
        return [AnalyzeRequest(q=row.tolist(), assembly_mode="+") for row in q]
    if kind == "timing":
        steps = rng.uniform(-0.15, 0.15, (n, 4, 3))
        paths = np.concatenate([q[:, None, :], q[:, None, :] + np.cumsum(steps, axis=1)], axis=1)
        return [TimingRequest(waypoints=w.tolist()) for w in paths]
    far = kind == "plan+toppra+far"
    goal = q + rng.uniform(-0.1, 0.1, q.shape) * (8.0 if far else 1.0)
    method = "toppra" if kind.startswith("plan+toppra") else "none"
    obstacles = [SPHERE] if far else []
    return [
        PlanRequest(
            start={"q": a.tolist(), "assembly_mode": "+"},
            goal={"q": b.tolist(), "assembly_mode": "+"},
            planner={"seed": 1},
            timing={"method": method},
            obstacles=obstacles,
        )
        for a, b in zip(q, goal, strict=True)
    ]


def _solvable(kind: str, n: int, rng: np.random.Generator) -> list:
    """``n`` plan requests of ``kind`` that the planner solves (random starts near a
    serial singularity are invalid starts: they are drawn again)."""
    found: list = []
    while len(found) < n:
        found += [r for r in _requests(kind, n, rng) if plan_jobs.plan(r).status == "solved"]
    return found[:n]


async def _load(url: str, method: str, requests: list, concurrency: int) -> tuple[list, float]:
    latencies: list[float] = []
    queue = list(requests)

    async def worker(client: AsyncPlannerClient) -> None:
        call = getattr(client, method)
        while queue:
            body = queue.pop()
            t0 = time.perf_counter()
            if method in ("plan", "cartesian"):
                await call(body)
            elif method == "timing":
                await call(body.waypoints)
            else:
                await call(body.q, body.assembly_mode)
            latencies.append(time.perf_counter() - t0)

    async with AsyncPlannerClient(url, timeout=60) as client:  # httpx pools 100 connections
        t0 = time.perf_counter()
        await asyncio.gather(*(worker(client) for _ in range(concurrency)))
        wall = time.perf_counter() - t0
    return latencies, wall


def _in_process(job: Callable, requests: list) -> list[float]:
    times = []
    for body in requests:
        t0 = time.perf_counter()
        job(body)
        times.append(time.perf_counter() - t0)
    return times


def _pct(values: list[float], p: float) -> float:
    return float(np.percentile(values, p)) * 1e3


def _mode_change_body(design, start, goal, obstacles, budget: float) -> dict:
    """A ``/v1/plan`` body (JSON) for a joint-goal query of ``benchmarks/planning.py``: the
    design in the body, the scene's spheres, the search budget, no timing (the library's
    ``plan`` does not time either, so the two columns compare)."""
    from planner.wire import DesignModel

    return PlanRequest(
        design=DesignModel.from_design(design),
        start={"q": start.q.tolist(), "assembly_mode": start.assembly_mode},
        goal={"q": goal.q.tolist(), "assembly_mode": goal.assembly_mode},
        obstacles=[
            {"type": "sphere", "center": o.center.tolist(), "radius": float(o.radius)}
            for o in obstacles
        ],
        planner={"time_budget_s": budget},
        timing={"method": "none"},
    ).model_dump(mode="json", exclude_none=True)


def _http_plans(url: str, bodies: list[dict]) -> tuple[list[float], list[str], int]:
    """POST each body in turn (concurrency 1); client-side wall times (s), statuses, and
    how many answers say ``proven_infeasible``."""
    times, statuses, proven = [], [], 0
    with httpx.Client(timeout=120) as client:
        for body in bodies:
            t0 = time.perf_counter()
            r = client.post(f"{url}/v1/plan", json=body)
            times.append(time.perf_counter() - t0)
            r.raise_for_status()
            answer = r.json()
            statuses.append(answer["status"])
            proven += bool(answer["diagnostics"].get("proven_infeasible"))
    return times, statuses, proven


def _library_plans(design, queries, obstacles, budget: float) -> tuple[list[float], list[str], int]:
    """The same queries through the library's ``plan`` in this process."""
    from planner.planning import PlanOptions, plan
    from planner.validity import Margins

    times, statuses, proven = [], [], 0
    options = PlanOptions(time_budget_s=budget)
    for start, goal in queries:
        t0 = time.perf_counter()
        res = plan(design, start, goal, obstacles=obstacles, margins=Margins(), options=options)
        times.append(time.perf_counter() - t0)
        statuses.append(res.status.value)
        proven += res.diagnostics.proven_infeasible
    return times, statuses, proven


def _flip_counts(design, queries) -> str:
    """How many queries change 1, 2 and 3 signs of the working mode (start against goal)."""
    from planner.planning import posture_mode

    flips = [
        sum(a != b for a, b in zip(posture_mode(design, s), posture_mode(design, g), strict=True))
        for s, g in queries
    ]
    return "/".join(str(flips.count(k)) for k in (1, 2, 3))


def _modes_rows(url: str, n: int, budget: float) -> None:
    """The ``--modes`` table: per scene, HTTP and in-process side by side (module docstring)."""
    from planning import (
        CUT,
        DESIGNS,
        MODE_SCENES,
        build_mode_change_queries,
        build_scene,
        disconnected_queries,
    )

    from planner.warmup import warm_up

    warm_up()  # this process pays the library's first-call costs as a worker does
    scenes = []
    for name, design in DESIGNS.items():
        for kind in MODE_SCENES:
            queries = build_mode_change_queries(kind, n, design=design)
            label = f"{'modes + spheres' if kind == 'modes_spheres' else 'modes'} {name}"
            scenes.append((label, design, queries, build_scene(kind)[1], budget, "solved"))
    scenes.append(
        ("disconnected (cut 0.3/0.3/0.4)", CUT, disconnected_queries(n), [], 5.0, "proven")
    )
    print(
        "load average (1, 5, 15 min) at the start: "
        + ", ".join(f"{x:.1f}" for x in os.getloadavg())
    )
    print(
        f"mode changes and proofs through /v1/plan (concurrency 1, timing none) against the "
        f"library's plan in-process; {budget:g} s budget (disconnected: 5 s); ms wall"
    )
    header = (
        f"{'scene':<36} {'n':>3} {'flips 1/2/3':>11} {'set-up':>8} {'ok':>3} {'first':>8} "
        f"{'p50':>8} {'p95':>8} {'max':>8}"
    )
    print(header)
    print("-" * len(header))
    _, design, queries, obstacles, scene_budget, _ = scenes[0]  # the default design's
    _http_plans(url, [_mode_change_body(design, *queries[0], obstacles, scene_budget)])
    # (the service's first request pays one-off costs: not counted in the table)
    for label, design, queries, obstacles, scene_budget, want in scenes:
        bodies = [_mode_change_body(design, s, g, obstacles, scene_budget) for s, g in queries]
        flips = _flip_counts(design, queries) if want == "solved" else "-"
        runs = (
            ("HTTP", _http_plans(url, bodies)),
            ("library", _library_plans(design, queries, obstacles, scene_budget)),
        )
        for setup, (times, statuses, proven) in runs:
            ok = statuses.count("solved") if want == "solved" else proven
            rest = times[1:]
            print(
                f"{label:<36} {len(times):>3} {flips:>11} {setup:>8} {ok:>3} "
                f"{times[0] * 1e3:8.1f} {_pct(rest, 50):8.2f} {_pct(rest, 95):8.2f} "
                f"{max(rest) * 1e3:8.1f}"
            )
    print("ok: solved (disconnected: proven_infeasible); first: the row's first request")
    print(
        "load average (1, 5, 15 min) at the end: " + ", ".join(f"{x:.1f}" for x in os.getloadavg())
    )


def _hot_rows(n: int = 2000) -> None:
    """The event loop's CPU per request with its caches warm: each server alone, ``n``
    keep-alive requests back to back (``--hot``). The interleaved rows of
    :func:`_floor_rows` send each request to a process whose caches the other server and the
    client have just used: there every process's CPU per request is ~2-3x its hot figure,
    the floor's too. Both measure the same code; the goal's 0.3 ms is read against both.
    The second floor, the bare app with a hand-over to another process (``/echo-hop``),
    is what a plan's hand-over to its worker costs the loop at the least: a plan's figure
    above it is the service's own work, not the process hop."""
    bare, bare_url = _start_bare()
    proc, url = _start_server(1)
    plan = {
        "start": {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"},
        "goal": {"q": [0.3, 2.2, 1.1], "assembly_mode": "+"},
        "timing": {"method": "none"},
    }
    rows = (
        ("bare FastAPI POST (async def)", bare, bare_url, "/echo", {"q": [0.1, 0.2, 0.3]}, n),
        ("bare + a process hop", bare, bare_url, "/echo-hop", {"q": [0.1, 0.2, 0.3]}, n),
        ("/v1/fk", proc, url, "/v1/fk", {"q": [0.2, 1.0, 2.0], "assembly_mode": "+"}, n),
        ("/v1/plan (free, none)", proc, url, "/v1/plan", plan, n // 2),
    )
    try:
        print(
            f"event loop CPU per request, hot (each server alone, back to back); load "
            f"{os.getloadavg()[0]:.1f}"
        )
        figures: dict[str, float] = {}
        for name, server, base, path, body, count in rows:
            client = LightClient(base)
            for _ in range(200):  # its caches and the connection warm
                status, _, _ = client.request("POST", path, body)
            assert status == 200, (path, status)
            c0 = _loop_cpu_s(server.pid)
            walls = [client.request("POST", path, body)[2] for _ in range(count)]
            ms = (_loop_cpu_s(server.pid) - c0) / count * 1e3
            print(f"{name:30} loop CPU {ms:6.3f} ms   p50 {_pct(walls, 50):6.3f} ms")
            figures[name] = ms
        hop, plan_ms = figures["bare + a process hop"], figures["/v1/plan (free, none)"]
        print(f"/v1/plan over the process hop's floor: {plan_ms - hop:6.3f} ms of loop CPU")
    finally:
        for server in (bare, proc):
            server.terminate()
            server.wait(timeout=30)


def main() -> None:
    print_machine()
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--requests", type=int, default=400)
    parser.add_argument("--floor-only", action="store_true", help="only the overhead rows")
    parser.add_argument(
        "--no-throughput", action="store_true", help="the overhead rows without the throughput"
    )
    parser.add_argument(
        "--throughput-only", action="store_true", help="only the throughput row and its CPU"
    )
    parser.add_argument("--endpoints", nargs="*", help="only these rows (default: all)")
    parser.add_argument(
        "--modes", action="store_true", help="only the mode-change and proof table (issue 17)"
    )
    parser.add_argument(
        "--hot", action="store_true", help="only the event loop's CPU with its caches warm"
    )
    parser.add_argument("--modes-queries", type=int, default=20)
    parser.add_argument("--modes-budget", type=float, default=2.0)
    args = parser.parse_args()
    if args.hot:
        _hot_rows()
        return
    if args.modes:
        proc, url = _start_server(args.workers)
        try:
            print(f"service on {url}, {args.workers} worker processes")
            _modes_rows(url, args.modes_queries, args.modes_budget)
        finally:
            proc.terminate()
            proc.wait(timeout=30)
        return
    rng = np.random.default_rng(0)
    if args.throughput_only:
        proc, url = _start_server(args.workers)
        try:
            _throughput_rows(url, proc.pid, rng, args.workers)
        finally:
            proc.terminate()
            proc.wait(timeout=30)
        return
    endpoints = [
        ("fk", "fk", kinematics_jobs.fk),
        ("analyze", "analyze", kinematics_jobs.analyze),
        ("timing", "timing", timing_jobs.timing),
    ]
    if importlib.util.find_spec("planner.planning") is not None:
        endpoints.append(("plan", "plan", plan_jobs.plan))
        endpoints.append(("plan+toppra", "plan", plan_jobs.plan))
        endpoints.append(("cartesian", "cartesian", cartesian_jobs.cartesian))
    if args.endpoints:
        endpoints = [e for e in endpoints if e[0] in args.endpoints]
    proc, url = _start_server(args.workers)
    try:
        print(
            f"service on {url}, {args.workers} worker processes, {args.requests} requests "
            "per row; latencies in ms"
        )
        print(
            f"{'endpoint':11} {'conc':>4} {'p50':>8} {'p95':>8} {'p99':>8} {'req/s':>8} "
            f"{'in-proc p50':>12} {'p50 ratio':>10}"
        )
        print("per-request overhead, concurrency 1")
        _floor_rows(
            url, proc.pid, min(args.requests, 300), rng, args.workers, not args.no_throughput
        )
        print()
        if args.floor_only:
            return
        for name, method, job in endpoints:
            make = _solvable if name.startswith("plan") else _requests
            requests = make(name, args.requests, rng)
            _in_process(job, requests[:20])  # warm-up (JIT caches) before timing
            local = _in_process(job, requests)
            local_p50 = statistics.median(local) * 1e3
            asyncio.run(_load(url, method, requests[:50], 8))  # warm the workers
            for concurrency in (1, 8, 32):
                lat, wall = asyncio.run(_load(url, method, requests, concurrency))
                print(
                    f"{name:11} {concurrency:>4} {_pct(lat, 50):8.2f} {_pct(lat, 95):8.2f} "
                    f"{_pct(lat, 99):8.2f} {len(lat) / wall:8.0f} {local_p50:12.3f} "
                    f"{_pct(lat, 50) / local_p50:10.1f}"
                )
    finally:
        proc.terminate()
        proc.wait(timeout=30)


if __name__ == "__main__":
    main()
