"""Graceful shutdown of a real service process (uvicorn, planner_api.server): on SIGTERM a plan in
flight finishes and is answered when it fits the grace; one that does not is answered with a
clean 503 ``shutting_down`` at the end of the grace and its worker is stopped; the process
exits cleanly either way, leaving no worker behind. Its log is JSON with the request ids.

The servers here run the tests' ``sleep_pid`` job on workers that skip the warm-up: what is
tested is the server around a job, not the job."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx
import pytest

ROOT = Path(__file__).resolve().parents[2]
PLAN = {"start": {"q": [0.0, 1.0, 2.0], "assembly_mode": "+"}, "goal": {"p": [0.3, 0.1, 0.2]}}


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie (exited, not yet reaped) is not running
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except FileNotFoundError:
        return False


def _start(tmp_path: Path, port: int, **env: str) -> tuple[subprocess.Popen[bytes], Path]:
    """A server process (JSON logs, one worker unless told) whose plan job is ``sleep_pid``,
    its workers not warmed up; (process, log) once ``/v1/ready`` answers."""
    log = tmp_path / "server.log"
    full_env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), str(ROOT), str(ROOT / "tests")]),
        "PLANNER_HOST": "127.0.0.1",
        "PLANNER_PORT": str(port),
        "PLANNER_WORKERS": "1",
        "PLANNER_LOG_FORMAT": "json",
        "PLANNER_DRAIN_S": "0",  # the stop after the drain (the drain: test_ops_drain.py)
        "OPS_PID_FILE": str(tmp_path / "worker.pid"),
        **env,
    }
    full_env.pop("PLANNER_API_KEY", None)
    with log.open("wb") as out:
        process = subprocess.Popen(
            [sys.executable, "-c", "import ops_jobs; ops_jobs.serve('sleep_pid', warm_up=False)"],
            cwd=ROOT,
            env=full_env,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    url = f"http://127.0.0.1:{port}"
    end = time.monotonic() + 180  # every worker started: slow on a loaded machine
    while True:
        assert process.poll() is None, log.read_text()[-3000:]
        try:
            if httpx.get(f"{url}/v1/ready", timeout=1).status_code == 200:
                return process, log
        except httpx.HTTPError:
            pass
        assert time.monotonic() < end, log.read_text()[-3000:]
        time.sleep(0.1)


def _plan_in_thread(url: str, sleep_s: float, request_id: str) -> tuple[threading.Thread, list]:
    out: list = []

    def go() -> None:
        body = {**PLAN, "planner": {"time_budget_s": sleep_s}}
        try:
            out.append(
                httpx.post(
                    f"{url}/v1/plan", json=body, timeout=60, headers={"X-Request-ID": request_id}
                )
            )
        except httpx.HTTPError as exc:  # pragma: no cover - reported by the assertion
            out.append(exc)

    t = threading.Thread(target=go)
    t.start()
    return t, out


def _wait_started(pid_file: Path) -> int:
    end = time.monotonic() + 20
    while not pid_file.exists() or not pid_file.read_text():
        assert time.monotonic() < end, "the job never started"
        time.sleep(0.02)
    return int(pid_file.read_text())


def _stop(process: subprocess.Popen[bytes], log: Path, timeout_s: float) -> float:
    start = time.monotonic()
    process.send_signal(signal.SIGTERM)
    try:
        # uvicorn re-raises the signal once it has shut down cleanly (exit status 143)
        code = process.wait(timeout=timeout_s)
        assert code in (0, -signal.SIGTERM), log.read_text()[-3000:]
        assert "Application shutdown complete" in log.read_text()
    finally:
        if process.poll() is None:  # pragma: no cover - a hung shutdown
            process.kill()
            process.wait()
    return time.monotonic() - start


def test_in_flight_plan_finishes_within_the_grace(tmp_path, unused_port):
    process, log = _start(tmp_path, unused_port, PLANNER_SHUTDOWN_TIMEOUT_S="40")
    url = f"http://127.0.0.1:{unused_port}"
    thread, out = _plan_in_thread(url, 1.5, "drain-1")
    worker = _wait_started(tmp_path / "worker.pid")
    elapsed = _stop(process, log, timeout_s=45)
    thread.join(10)
    (r,) = out
    assert isinstance(r, httpx.Response) and r.status_code == 200, r
    assert r.json()["message"] == str(worker)  # the job's own answer, not a cut connection
    assert r.headers["x-request-id"] == "drain-1"
    assert elapsed < 30  # it did not wait the whole grace (40 s): it stopped after the job
    assert not _alive(worker)
    with pytest.raises(httpx.ConnectError):  # nothing listens any more
        httpx.get(f"{url}/v1/health", timeout=1)
    lines = [json.loads(x) for x in log.read_text().splitlines() if x.startswith("{")]
    access = [x for x in lines if x["logger"] == "api.access" and x["path"] == "/v1/plan"]
    assert [(x["request_id"], x["status"]) for x in access] == [("drain-1", 200)]
    job = [x for x in lines if x["logger"] == "tests.ops_jobs"]
    assert [(x["request_id"], x["pid"]) for x in job] == [("drain-1", worker)]


def test_plan_beyond_the_grace_is_cancelled_cleanly(tmp_path, unused_port):
    grace = 2.0
    process, log = _start(tmp_path, unused_port, PLANNER_SHUTDOWN_TIMEOUT_S=str(grace))
    url = f"http://127.0.0.1:{unused_port}"
    thread, out = _plan_in_thread(url, 25.0, "cut-1")
    worker = _wait_started(tmp_path / "worker.pid")
    elapsed = _stop(process, log, timeout_s=20)
    thread.join(10)
    (r,) = out
    assert isinstance(r, httpx.Response) and r.status_code == 503, r
    assert r.json()["detail"][0]["type"] == "shutting_down"
    assert r.headers["retry-after"] == "1"
    assert r.headers["x-request-id"] == "cut-1"
    # the answer came at the end of the job's share of the grace, the exit soon after
    assert grace * 0.5 < elapsed < grace + 20
    assert not _alive(worker)  # the busy worker was terminated, not left running
