"""The service as the benchmarks start it: ``planner serve`` from this checkout's source in a
child process on a free local port, waited for until ``/v1/ready`` answers 200 (every worker
warm). Shared by ``service.py``, ``soak.py``, ``overrun.py`` and ``viewer_cloud.py``."""

from __future__ import annotations

import http.client
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

from _light import LightClient

__all__ = ["ROOT", "free_port", "start_service", "wait_ready"]

ROOT = Path(__file__).resolve().parents[1]


def free_port() -> int:
    """A TCP port free on 127.0.0.1 at the time of asking."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_ready(url: str, limit_s: float = 300.0, proc: subprocess.Popen | None = None) -> None:
    """Until ``url``'s ``/v1/ready`` answers 200; ``RuntimeError`` after ``limit_s`` or when
    ``proc`` (the service) has exited."""
    end = time.monotonic() + limit_s
    while True:
        try:
            if LightClient(url, timeout_s=5.0).request("GET", "/v1/ready")[0] == 200:
                return
        except (OSError, http.client.HTTPException):
            pass
        if time.monotonic() > end or (proc is not None and proc.poll() is not None):
            raise RuntimeError("the service did not become ready")
        time.sleep(0.2)


def start_service(
    settings: dict[str, str], *, ready_s: float = 300.0, quiet: bool = False
) -> tuple[subprocess.Popen[bytes], str]:
    """``planner serve`` with the ``PLANNER_*`` ``settings`` over this environment, ready:
    (its process, its base URL). The caller stops it (``proc.terminate()``)."""
    port = free_port()
    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'src'}{os.pathsep}{ROOT}", **settings}
    cmd = [
        sys.executable,
        "-m",
        "planner_cli",
        "serve",
        "--port",
        str(port),
        "--log-level",
        "warning",
    ]
    out = subprocess.DEVNULL if quiet else None
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=out, stderr=out)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_ready(url, ready_s, proc)
    except RuntimeError:
        proc.kill()
        raise
    return proc, url
