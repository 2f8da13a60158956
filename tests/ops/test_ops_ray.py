"""The Ray Serve deployment (deploy/ray_serve.py): a local Ray instance serves the same app,
through Ray's HTTP proxy on a loopback port, with its worker pool inside the replica."""

from __future__ import annotations

import os
import time
from pathlib import Path

import httpx
import numpy as np
import pytest

from planner import Design, forward_batch

# Ray's node address on loopback (read when ray is imported; on Linux Ray otherwise uses the
# machine's own address for its internal services) and no usage telemetry.
os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
# Ray Serve kills its HTTP proxy when it is not ready within 5 s (and on health checks of
# 10 s): a slow or loaded machine (one core, another suite running) takes longer to start
# it. The test is about serving the app, not Ray's start-up speed: give it room.
os.environ.setdefault("RAY_SERVE_PROXY_READY_CHECK_TIMEOUT_S", "240")
os.environ.setdefault("RAY_SERVE_PROXY_HEALTH_CHECK_TIMEOUT_S", "60")

ROOT = Path(__file__).resolve().parents[2]


def _wait_ready(url: str, timeout_s: float = 180.0) -> None:
    end = time.monotonic() + timeout_s
    while True:
        try:
            if httpx.get(f"{url}/v1/ready", timeout=2.0).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        assert time.monotonic() < end, "the Ray Serve replica never became ready"
        time.sleep(0.2)


#: How long serve.start may wait for the HTTP proxy, s (Ray's own wait is a fixed 60 s, which
#: a single core shared with another suite has been seen to exceed).
PROXY_START_S = 300


def test_ray_serve_serves_the_app(unused_port, monkeypatch):
    # imported here, not at collection: Ray's import alone is most of a second of every run
    pytest.importorskip("ray.serve", reason="Ray Serve is not installed (pip install '.[ray]')")
    import ray
    import ray.serve._private.api as serve_api
    from ray import serve

    # Ray reads the constant at import into its api module; the wait is patched there, and a
    # renamed constant in a newer Ray fails here loudly rather than silently keeping 60 s
    monkeypatch.setattr(serve_api, "HTTP_PROXY_TIMEOUT", PROXY_START_S, raising=True)

    from deploy.ray_serve import app_builder

    path = os.pathsep.join([str(ROOT / "src"), str(ROOT), os.environ.get("PYTHONPATH", "")])
    ray.init(
        num_cpus=2,
        include_dashboard=False,
        runtime_env={"env_vars": {"PYTHONPATH": path}},
        log_to_driver=False,
    )
    try:
        serve.start(http_options={"host": "127.0.0.1", "port": unused_port})
        app = app_builder({"workers": "1", "request_timeout_s": "20"})  # as `serve run` does
        serve.run(app, route_prefix="/", blocking=False)
        url = f"http://127.0.0.1:{unused_port}"
        _wait_ready(url)

        # kinematics through the replica's worker pool, checked against the library here
        q = [0.3, 1.0, 2.1]
        r = httpx.post(
            f"{url}/v1/fk",
            json={"q": q, "assembly_mode": "+"},
            headers={"X-Request-ID": "ray-1"},
            timeout=20,
        )
        assert r.status_code == 200, r.text
        # Ray's proxy echoes the id as well (same value): one id, whoever wrote it
        assert {v.strip() for v in r.headers["x-request-id"].split(",")} == {"ray-1"}
        expected = forward_batch(Design.default(), np.array([q]), "+").p[0]
        np.testing.assert_allclose(r.json()["postures"][0]["p"], expected, atol=1e-12)

        # one plan through it
        plan = {
            "start": {"q": [0.0, 1.0, 2.0], "assembly_mode": "+"},
            "goal": {"q": [0.2, 1.1, 2.1], "assembly_mode": "+"},
            "planner": {"seed": 1, "time_budget_s": 5.0},
            "timing": {"method": "none"},
        }
        r = httpx.post(f"{url}/v1/plan", json=plan, timeout=30)
        assert r.status_code == 200, r.text
        body = r.json()
        assert body["status"] == "solved", body
        np.testing.assert_allclose(body["path"]["waypoints"][0], plan["start"]["q"])
        np.testing.assert_allclose(body["path"]["waypoints"][-1], plan["goal"]["q"])

        # the replica's metrics saw those requests
        text = httpx.get(f"{url}/metrics", timeout=10).text
        assert 'planner_http_requests_total{method="POST",route="/v1/fk",status="200"} 1.0' in text
    finally:
        serve.shutdown()
        ray.shutdown()
