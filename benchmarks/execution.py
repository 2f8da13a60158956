"""Execution: replacement mid-motion and stops, on random running trajectories.

    .venv/bin/python benchmarks/execution.py [--splices 1000] [--stops 1000] [--seed 1]

* **Splices.** ``--splices`` random replacements (half toppra, half ruckig): a random running
  trajectory (a free-space plan between random postures near the default design's centre,
  timed at 250 Hz), a random sample time ``at`` on it, a random free-space goal; the request
  ``{"replace": {"trajectory", "at"}, "goal", "timing"}`` answered in this process
  (:func:`planner.endpoints.plan.plan`: wire conversion, planning, timing, lead-in, response).
  Each answer is checked: the splice (q, qd, qdd of the first sample against the running
  state, 1e-9), the limits by finite differences of the samples (velocity, acceleration,
  and jerk for ruckig), and the independent plan checker (tests/plan_checker.py: validity
  of every sample and the chords between them, limits, the path). Counted: discontinuities,
  limit violations, checker failures, answers not solved. Latency: wall and CPU time of the
  call, p50 and p95 (goal, issue 40: p50 <= 10 ms for a free-space goal).
* **Stops.** ``--stops`` random (running trajectory, ``at``): the core's
  :func:`planner.timing.braking.stop_trajectory` (checkers built once per running
  trajectory, as a controller's session would) and the whole endpoint
  :func:`planner.endpoints.stop.stop` (conversion and checker construction included):
  latency p50 / p95, share kept along the running path, and the same splice and
  finite-difference checks (goal: <= 1 ms in-process).
* **Stream.** ``--stream-s`` seconds (default 60; 0 skips) of ``/v1/stream`` at ``--rate``
  (1 kHz) from a ``planner serve`` child process to a real-time client in this process
  (:meth:`planner.client.PlannerClient.stream` with ``auto_ack=False``: it acknowledges its own
  clock every millisecond, lookahead 50 ms), plan after plan: each setpoint's lateness is its
  arrival on the client's clock less its time (<= 0: early, as the lookahead means), p50 /
  p99 / max (goal, issue 40: p99 <= 1 ms), and the time from a ``replace`` to its
  ``switched`` answer.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from _machine import print_machine

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from plan_checker import check_plan

from planner import Design
from planner.endpoints.plan import plan
from planner.endpoints.stop import stop as stop_endpoint
from planner.timing import JointLimits
from planner.timing.braking import stop_trajectory
from planner.timing.running import RunningTrajectory
from planner.validity import Margins, ValidityChecker
from planner.wire import PlanRequest, StopRequest

CENTRE = np.array([0.0, 2.0, 1.0])
SPREAD = 0.35
RATE = 250.0
V, A, J = 2.0, 8.0, 200.0


def posture(q) -> dict:
    return {"q": [float(x) for x in q], "assembly_mode": "+"}


def solved(body: dict) -> dict | None:
    answer = plan(PlanRequest.model_validate(body)).model_dump(mode="json")
    return answer if answer["status"] == "solved" else None


def running_pool(rng: np.random.Generator, method: str, n: int) -> list[dict]:
    """``n`` running trajectories: free-space plans between random postures."""
    pool: list[dict] = []
    while len(pool) < n:
        a, b = CENTRE + rng.uniform(-SPREAD, SPREAD, (2, 3))
        body = {
            "start": posture(a),
            "goal": posture(b),
            "planner": {"seed": 1},
            "timing": {"method": method, "sample_rate_hz": RATE},
        }
        answer = solved(body)
        if answer is not None:
            pool.append(answer["trajectory"])
    return pool


def fd_violations(traj: dict, jerk: bool, inherited: bool = False) -> int:
    """Samples whose finite differences exceed a limit (mean value theorem). ``inherited``:
    the first sample's velocity and acceleration raise the limits they exceed (a stop from
    a state the quintic reading puts beyond a limit may keep, never add to, that excess)."""
    t = np.asarray(traj["t"])
    q, qd, qdd = (np.asarray(traj[k]) for k in ("q", "qd", "qdd"))
    dt = np.diff(t)[:, None]
    slack = 1 + 1e-6
    v, a = np.full(3, V), np.full(3, A)
    if inherited:
        v, a = np.maximum(v, np.abs(qd[0])), np.maximum(a, np.abs(qdd[0]))
    bad = np.abs(np.diff(q, axis=0)) > v * dt * slack + 1e-12
    bad |= np.abs(np.diff(qd, axis=0)) > a * dt * slack + 1e-12
    if jerk:
        bad |= np.abs(np.diff(qdd, axis=0)) > J * dt * slack + 1e-9
    return int(np.any(bad, axis=1).sum())


def splice_gap(traj: dict, running: dict, k: int) -> float:
    return max(
        float(np.max(np.abs(np.asarray(traj[key][0]) - np.asarray(running[key][k]))))
        for key in ("q", "qd", "qdd")
    )


def splices(rng: np.random.Generator, count: int) -> None:
    pools = {m: running_pool(rng, m, 10) for m in ("toppra", "ruckig")}
    wall: list[float] = []
    cpu: list[float] = []
    counts = dict.fromkeys(("discontinuities", "limits", "checker", "not solved"), 0)
    for i in range(count):
        method = "toppra" if i % 2 == 0 else "ruckig"
        running = pools[method][int(rng.integers(len(pools[method])))]
        k = int(rng.integers(0, len(running["t"])))
        goal = CENTRE + rng.uniform(-SPREAD, SPREAD, 3)
        body = {
            "replace": {"trajectory": running, "at": running["t"][k]},
            "goal": posture(goal),
            "planner": {"seed": 1},
            "timing": {"method": method, "sample_rate_hz": RATE},
        }
        w0, c0 = time.perf_counter(), time.process_time()
        answer = solved(body)
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
        if answer is None:
            counts["not solved"] += 1
            continue
        traj = answer["trajectory"]
        counts["discontinuities"] += int(
            splice_gap(traj, running, k) > 1e-9 or traj["t"][0] != running["t"][k]
        )
        counts["limits"] += int(fd_violations(traj, method == "ruckig") > 0)
        state = {key: running[key][k] for key in ("q", "qd", "qdd")}
        lead = answer["diagnostics"]["lead_in"]
        report = check_plan(
            {**body, "start": {**posture(state["q"]), **state}},
            answer,
            start_state=state,
            lead_in_s=0.0 if lead is None else lead["duration"],
        )
        counts["checker"] += int(not report.ok)
    ms = [x * 1e3 for x in wall]
    cpu_ms = [x * 1e3 for x in cpu]
    print(f"\n## Replacement: {count} random splices (half toppra, half ruckig, {RATE:g} Hz)\n")
    print("| | p50 | p95 |\n|---|---|---|")
    print(
        f"| latency, wall (plan endpoint in-process) | {pct(ms, 50):.2f} ms | {pct(ms, 95):.2f} ms |"
    )
    print(f"| latency, CPU | {pct(cpu_ms, 50):.2f} ms | {pct(cpu_ms, 95):.2f} ms |")
    print("\n| discontinuities | limit violations (FD) | plan checker failures | not solved |")
    print("|---|---|---|---|")
    print(
        f"| {counts['discontinuities']} | {counts['limits']} | {counts['checker']} | {counts['not solved']} |"
    )


def pct(values: list[float], p: float) -> float:
    return float(np.percentile(values, p)) if values else float("nan")


def stops(rng: np.random.Generator, count: int) -> None:
    design = Design.default()
    limits = JointLimits(velocity=(V,) * 3, acceleration=(A,) * 3, jerk=(J,) * 3)
    free = ValidityChecker(design, Margins(), [], "+", "+++", serial_rules=False)
    pools = {m: running_pool(rng, m, 10) for m in ("toppra", "ruckig")}
    core: list[float] = []
    core_cpu: list[float] = []
    whole: list[float] = []
    along = bad = gaps = unstopped = 0
    for i in range(count):
        method = "toppra" if i % 2 == 0 else "ruckig"
        running = pools[method][int(rng.integers(len(pools[method])))]
        reading = RunningTrajectory.of(running["t"], running["q"], running["qd"], running["qdd"])
        at = float(rng.uniform(reading.start, reading.end))
        t0, c0 = time.perf_counter(), time.process_time()
        result = stop_trajectory(
            reading,
            at,
            design=design,
            assembly_mode="+",
            limits=limits,
            path_rules=free.is_valid,
            brake_rules=free.is_valid,
            jerk_limited=method == "ruckig",
            sample_rate_hz=RATE,
        )
        core.append(time.perf_counter() - t0)
        core_cpu.append(time.process_time() - c0)
        request = StopRequest.model_validate(
            {"trajectory": running, "at": at, "method": method, "sample_rate_hz": RATE}
        )
        t0 = time.perf_counter()
        answer = stop_endpoint(request)
        whole.append(time.perf_counter() - t0)
        if result.status != "solved":
            unstopped += 1
            continue
        along += int(result.along_path)
        arrays = {"t": result.t, "q": result.q, "qd": result.qd, "qdd": result.qdd}
        bad += int(fd_violations(arrays, method == "ruckig", inherited=True) > 0)
        state = reading.state_at(at)
        gaps += int(
            max(
                float(np.max(np.abs(a[0] - b)))
                for a, b in zip((result.q, result.qd, result.qdd), state, strict=True)
            )
            > 1e-9
        )
        assert answer.status == result.status
    core_ms = [x * 1e3 for x in core]
    cpu_ms = [x * 1e3 for x in core_cpu]
    whole_ms = [x * 1e3 for x in whole]
    print(f"\n## Stops: {count} random states on random running trajectories\n")
    print("| | p50 | p95 |\n|---|---|---|")
    rows = (
        ("stop, core (stop_trajectory), wall", core_ms),
        ("stop, core, CPU", cpu_ms),
        ("stop, endpoint (conversion, checkers), wall", whole_ms),
    )
    for name, values in rows:
        print(f"| {name} | {pct(values, 50):.3f} ms | {pct(values, 95):.3f} ms |")
    print(
        f"\nalong the running path: {along} of {count}; discontinuities: {gaps}; "
        f"limit violations (FD): {bad}; no stop (invalid_start): {unstopped}"
    )


def stream_lateness(seconds: float, rate: float) -> None:
    """The stream section of the module docstring."""
    from _server import start_service

    from planner.client import PlannerClient

    proc, url = start_service({"PLANNER_WORKERS": "1"}, quiet=True)
    late: dict[bool, list[float]] = {False: [], True: []}  # without / with a replacement
    switch_ms: list[float] = []
    splice_ms: list[float] = []
    rng = np.random.default_rng(2)
    try:
        with PlannerClient(url, timeout=30) as client:
            end = time.monotonic() + seconds
            replace = False
            while time.monotonic() < end:
                goal = CENTRE + rng.uniform(-SPREAD, SPREAD, 3)
                body = {
                    "start": posture(CENTRE),
                    "goal": posture(goal),
                    "timing": {"method": "ruckig"},
                }
                late[replace] += _one_stream(
                    client, body, rate, switch_ms if replace else None, splice_ms
                )
                replace = not replace
    finally:
        proc.terminate()
        proc.wait(30)
    print(f"\n## Stream: {seconds:g} s at {rate:g} Hz to a local real-time client\n")
    print("| lateness (arrival - time), streams | setpoints | p50 | p99 | max |")
    print("|---|---|---|---|---|")
    for replaced, values in late.items():
        ms = list(np.asarray(values) * 1e3)
        name = "with a replacement each" if replaced else "plain"
        row = f"{pct(ms, 50):.3f} ms | {pct(ms, 99):.3f} ms | {max(ms):.3f} ms"
        print(f"| {name} | {len(ms)} | {row} |")
    print(
        f"\nreplace -> switched: p50 {pct(switch_ms, 50):.1f} ms, p99 {pct(switch_ms, 99):.1f} ms "
        f"over {len(switch_ms)} replacements; splice time - client's clock at the replace: "
        f"p50 {pct(splice_ms, 50):.1f} ms, max {max(splice_ms):.1f} ms"
    )


def _one_stream(
    client, body: dict, rate: float, switch_ms: list[float] | None, splice_ms: list[float]
) -> list[float]:
    """One plan streamed in real time (with ``switch_ms``, a replacement after 0.3 s, its
    latency appended, and to ``splice_ms`` its splice time less the client's clock when it was
    sent): each setpoint's lateness, s."""
    late: list[float] = []
    with client.stream(body, rate_hz=rate, lookahead_s=0.05, auto_ack=False) as session:
        w0 = None  # the client's clock: on time with the first setpoint
        replaced_at = None
        while True:
            message = session.receive(timeout=0.001)
            now = time.monotonic()
            if w0 is not None:
                session.ack(now - w0)
            if message is None:
                continue
            if message["type"] == "setpoints":
                if w0 is None:
                    w0 = now - message["t0"]
                t = message["t0"] + message["dt"] * np.arange(len(message["q"]))
                late += list((now - w0) - t)
                if switch_ms is not None and replaced_at is None and message["t0"] > 0.3:
                    session.replace({"goal": body["start"], "timing": body["timing"]})
                    replaced_at = now
            elif message["type"] == "switched" and switch_ms is not None:
                switch_ms.append((now - replaced_at) * 1e3)
                splice_ms.append((message["at"] - (replaced_at - w0)) * 1e3)
            elif message["type"] == "done":
                return late


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--splices", type=int, default=1000)
    parser.add_argument("--stops", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--stream-s", type=float, default=60.0)
    parser.add_argument("--rate", type=float, default=1000.0)
    args = parser.parse_args()
    print_machine()
    print(f"# Execution (seed {args.seed})")
    rng = np.random.default_rng(args.seed)
    solved({"start": posture(CENTRE), "goal": posture(CENTRE + 0.1)})  # first-call costs
    splices(rng, args.splices)
    stops(rng, args.stops)
    if args.stream_s > 0:
        stream_lateness(args.stream_s, args.rate)


if __name__ == "__main__":
    main()
