"""The drain after SIGTERM on a real service process (:mod:`planner_api.server`): for
``PLANNER_DRAIN_S`` the service still accepts connections and serves, while ``/v1/ready``
answers 503 ``stopping`` and every answer says ``Connection: close``; then it stops listening
and exits. A second signal ends the drain at once.

The oracle is what a load balancer sees: a new connection's probe and request, and then a
refused connection."""

from __future__ import annotations

import signal
import time

import httpx
import pytest


def _exit_code(process, bound_s: float) -> int:  # type: ignore[no-untyped-def]
    try:
        return process.wait(timeout=bound_s)
    except Exception:  # pragma: no cover - reported by the assertion
        pytest.fail(f"the service had not exited {bound_s} s after the drain")


def test_sigterm_drains_then_stops_listening(server_factory):
    drain_s = 4.0
    process, url, log = server_factory(warm=False, workers="1", drain_s=str(drain_s))
    with httpx.Client(base_url=url, timeout=30) as client:
        assert client.get("/v1/ready").status_code == 200
        fk = {"q": [0.0, 1.0, 2.0]}
        assert client.post("/v1/fk", json=fk).status_code == 200  # the worker's imports
    process.send_signal(signal.SIGTERM)
    signalled = time.monotonic()
    time.sleep(0.3)
    # new connections, as a load balancer's probes and requests in the drain
    with httpx.Client(base_url=url, timeout=10) as client:
        ready = client.get("/v1/ready")
        health = client.get("/v1/health")
        fk = client.post("/v1/fk", json={"q": [0.0, 1.0, 2.0]})
    assert time.monotonic() - signalled < drain_s  # (else the checks below prove nothing)
    assert ready.status_code == 503, ready.text
    assert ready.json()["status"] == "stopping"
    assert ready.headers["retry-after"] == "1"
    assert fk.status_code == 200 and fk.json()["postures"], fk.text
    assert fk.headers["connection"] == "close"
    assert health.status_code == 200
    code = _exit_code(process, drain_s + 30)
    assert time.monotonic() - signalled >= 0.9 * drain_s  # it listened for the drain
    assert code in (0, -signal.SIGTERM), log.read_text()[-3000:]
    with pytest.raises(httpx.ConnectError):
        httpx.get(f"{url}/v1/health", timeout=2)
    text = log.read_text()
    assert "draining for 4 s" in text and "Application shutdown complete" in text


def test_a_second_signal_ends_the_drain(server_factory):
    process, url, log = server_factory(warm=False, workers="1", drain_s="60")
    process.send_signal(signal.SIGTERM)
    time.sleep(0.3)
    assert httpx.get(f"{url}/v1/ready", timeout=10).json()["status"] == "stopping"
    signalled = time.monotonic()
    process.send_signal(signal.SIGTERM)
    code = _exit_code(process, 40)
    assert time.monotonic() - signalled < 40  # not the 60 s drain
    assert code in (0, -signal.SIGTERM), log.read_text()[-3000:]
