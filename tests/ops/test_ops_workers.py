"""The worker processes of a real service process (``planner serve``): ready means warm (the
first plan on every worker after ``/v1/ready`` is as cheap as any), a worker killed mid-job
fails only its own request and is replaced, and a killed server leaves no process behind.

The timing assertion below is not a speed test: a cold worker spends seconds importing OMPL,
toppra and numba's cache before its first plan (3-5 s measured on a 2-core machine), a warm one
milliseconds; the bound sits at half of the plan's own budget, between the two with a factor
of more than ten either side.
"""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from pathlib import Path

import httpx
import pytest

ROOT = Path(__file__).resolve().parents[2]
STARTUP_TIMEOUT_S = 180.0  # as tests/conftest.py
#: A real plan: a joint goal in free space, timed by TOPPRA (the default timing); the tests'
#: ``sleep_pid`` job sleeps its ``time_budget_s`` instead.
PLAN = {
    "start": {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"},
    "goal": {"q": [0.6, 2.3, 0.8], "assembly_mode": "+"},
    "planner": {"seed": 1, "time_budget_s": 5.0},
}


def _children(pid: int) -> list[int]:
    """Process ids whose parent is ``pid`` (from /proc)."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (FileNotFoundError, ProcessLookupError, IndexError):
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            out.append(int(stat.parent.name))
    return out


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


def _workers(server: int) -> list[int]:
    """The server's worker processes: the children of its warm template (the one spawned
    Python child; multiprocessing's resource tracker is not spawned so)."""
    spawned = []
    for pid in _children(server):
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes()
        except FileNotFoundError:
            continue
        if b"spawn_main" in cmd:
            spawned.append(pid)
    assert len(spawned) <= 1, f"more than one template: {spawned}"
    return [pid for template in spawned for pid in _children(template)]


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """One ``planner serve`` process with two warm workers and JSON logs at INFO, ready;
    (process, url, log). Shared by the module's tests in file order: the first plan's test
    first (its workers never used before), the SIGTERM test last (it stops the server). A
    test that runs without the other one (xdist, -k) gets a server of its own, as fresh."""
    from conftest import serve_process

    log = tmp_path_factory.mktemp("ops_workers") / "server.log"
    env = {"PLANNER_WORKERS": "2", "PLANNER_LOG_FORMAT": "json"}
    with serve_process(log, log_level="info", **env) as (process, url):
        yield process, url, log


def _post_all(url: str, bodies: list[dict]) -> list[httpx.Response | Exception]:
    """POST every body to /v1/plan at once (one thread each); answers in order."""
    out: list[httpx.Response | Exception] = [RuntimeError("no answer")] * len(bodies)

    def go(i: int) -> None:
        try:
            out[i] = httpx.post(f"{url}/v1/plan", json=bodies[i], timeout=60)
        except httpx.HTTPError as exc:  # pragma: no cover - reported by the assertions
            out[i] = exc

    threads = [threading.Thread(target=go, args=(i,)) for i in range(len(bodies))]
    for t in threads:
        t.start()
    for t in threads:
        t.join(90)
    return out


def test_first_plan_on_every_worker_after_ready_is_warm(server):
    process, url, _ = server
    assert httpx.get(f"{url}/v1/ready").json() == {
        "status": "ready",
        "workers": 2,
        "warm": 2,
        "store": "ok",
    }
    assert len(_workers(process.pid)) == 2
    first = _post_all(url, [PLAN, PLAN])  # one per worker: both idle, both never used
    for r in first:
        assert isinstance(r, httpx.Response) and r.status_code == 200, r
        body = r.json()
        assert body["status"] == "solved", body["message"]
        d = body["diagnostics"]
        work = d["planning_time_s"] + d["timing_time_s"]
        assert work < PLAN["planner"]["time_budget_s"] / 2, d  # no import, no compile


def test_a_worker_killed_mid_job_fails_only_its_request(tmp_path):
    """Two long jobs, one per worker (the tests' ``sleep_pid`` job: a real search of this
    length is proven infeasible by the planner within milliseconds now); one worker is
    killed: its request gets a 502 ``worker_crashed``, the other's answer arrives, and a
    replacement restores readiness. The workers skip the warm-up (the jobs need none); that
    a replacement is warm before it counts is test_api_service.py's dead-worker test."""
    from conftest import free_port
    from test_ops_shutdown import _start

    port = free_port()
    process, log = _start(tmp_path, port, PLANNER_WORKERS="2")
    url = f"http://127.0.0.1:{port}"
    try:
        before = _workers(process.pid)
        assert len(before) == 2
        long_job = {**PLAN, "planner": {"time_budget_s": 4.0}}
        out: list = []
        thread = threading.Thread(target=lambda: out.extend(_post_all(url, [long_job] * 2)))
        thread.start()
        # wait until both workers are busy (the metrics count jobs in flight)
        end = time.monotonic() + 60
        while "planner_pool_busy_workers 2.0" not in httpx.get(f"{url}/metrics").text:
            assert time.monotonic() < end, "the two jobs never ran at once"
            time.sleep(0.05)
        os.kill(before[0], signal.SIGKILL)
        thread.join(90)
        codes = sorted(r.status_code for r in out)
        assert codes == [200, 502], [r.text for r in out]
        crashed = next(r for r in out if r.status_code == 502).json()["detail"][0]
        assert crashed["type"] == "worker_crashed" and "SIGKILL" in crashed["msg"]
        survivor = next(r for r in out if r.status_code == 200).json()
        assert survivor["message"] == str(before[1])  # answered by the other worker
        # the replacement warms up in the background; then the service is ready again
        end = time.monotonic() + STARTUP_TIMEOUT_S
        while httpx.get(f"{url}/v1/ready").status_code != 200:
            assert time.monotonic() < end, log.read_text()[-3000:]
            time.sleep(0.1)
        after = _workers(process.pid)
        assert len(after) == 2 and before[0] not in after and before[1] in after
        quick = {**PLAN, "planner": {"time_budget_s": 0.01}}
        r = httpx.post(f"{url}/v1/plan", json=quick, timeout=60)
        assert r.status_code == 200 and r.json()["message"] in {str(pid) for pid in after}
    finally:
        process.terminate()
        process.wait(timeout=30)


def test_a_killed_server_leaves_no_process_behind(tmp_path):
    """SIGKILL on the server: its warm template, its two workers (forked from the template,
    they die with the server through the hang-up of their jobs pipe, whatever they were doing)
    and multiprocessing's resource tracker exit."""
    from conftest import free_port
    from test_ops_shutdown import _start

    process, _ = _start(tmp_path, free_port(), PLANNER_WORKERS="2")
    try:
        workers = _workers(process.pid)
        # the template, multiprocessing's resource tracker and the workers the template forked
        ours = _children(process.pid) + workers
        assert len(workers) == 2 and len(ours) >= 4
        process.send_signal(signal.SIGKILL)
        process.wait()
        end = time.monotonic() + 10
        while any(_alive(p) for p in ours):
            assert time.monotonic() < end, [p for p in ours if _alive(p)]
            time.sleep(0.1)
    finally:
        if process.poll() is None:  # pragma: no cover - the kill failed
            process.kill()
            process.wait()


def test_every_log_line_is_json_and_an_idle_stop_is_quiet(server):
    """Requests that used to leave non-JSON lines (a figure whose legend had nothing to show,
    library warnings), then a SIGTERM on an idle server: every line of the log is JSON, and
    nothing claims a worker was busy or a semaphore leaked."""
    process, url, log = server
    for name in ("working_modes", "serial_singularity", "isoconditioning"):
        r = httpx.get(f"{url}/v1/figures/{name}.png", params={"dpi": 20, "resolution": 16})
        assert r.status_code == 200, r.text
    assert httpx.post(f"{url}/v1/plan", json=PLAN, timeout=60).status_code == 200
    process.send_signal(signal.SIGTERM)
    assert process.wait(timeout=60) in (0, -signal.SIGTERM)
    lines = log.read_text().splitlines()
    assert lines
    for line in lines:
        record = json.loads(line)  # every line parses
        assert "still busy" not in record["message"], record
        assert "leaked" not in record["message"], record
        assert record["level"] != "error", record
