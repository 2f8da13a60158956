"""Shared fixtures: an in-process app (FastAPI's TestClient) and a real service process.

``live_server`` starts ``planner serve`` (uvicorn) in a subprocess on a free loopback port,
waits for ``/v1/health`` and yields its base URL; the client tests and the examples use it.
``serve_factory`` starts one with other settings (e.g. an API key).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from pathlib import Path

import httpx
import pytest
from fastapi.testclient import TestClient

from api.app import create_app
from api.settings import Settings

ROOT = Path(__file__).resolve().parents[1]
#: Seconds allowed for a service process to answer /v1/health after it starts.
STARTUP_TIMEOUT_S = 60.0


def free_port() -> int:
    """A TCP port free on 127.0.0.1 right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def make_client(**settings: object) -> TestClient:
    """A TestClient of an app built with these settings (one worker unless told)."""
    settings.setdefault("workers", 1)
    return TestClient(create_app(Settings(**settings)), raise_server_exceptions=False)


@pytest.fixture(scope="session")
def client_factory() -> Callable[..., TestClient]:
    """:func:`make_client`, as a fixture (test modules do not import conftest)."""
    return make_client


@pytest.fixture
def unused_port() -> int:
    """A loopback TCP port nobody listens on."""
    return free_port()


@pytest.fixture(scope="session")
def api() -> Iterator[TestClient]:
    """One in-process service (one worker process) for the whole session."""
    with make_client() as client:
        yield client


def _wait_healthy(url: str, process: subprocess.Popen[bytes], log: Path) -> None:
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise RuntimeError(
                f"the service exited with {process.returncode}:\n{log.read_text()[-4000:]}"
            )
        try:
            if httpx.get(f"{url}/v1/health", timeout=1.0).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        time.sleep(0.1)
    raise RuntimeError(
        f"the service did not answer within {STARTUP_TIMEOUT_S} s:\n{log.read_text()[-4000:]}"
    )


@contextmanager
def serve(log: Path, **env_vars: str) -> Iterator[str]:
    """A real ``planner serve`` process (uvicorn) on a free loopback port, its environment
    without ``PLANNER_API_KEY`` unless given in ``env_vars`` (2 workers unless told); yields
    its base URL once ``/v1/health`` answers, and stops it at the end."""
    port = free_port()
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(
            [str(ROOT / "src"), str(ROOT), os.environ.get("PYTHONPATH", "")]
        ),
        "PLANNER_WORKERS": "2",
    }
    env.pop("PLANNER_API_KEY", None)
    env.update(env_vars)
    with log.open("wb") as out:
        process = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "planner.cli",
                "serve",
                "--host",
                "127.0.0.1",
                "--port",
                str(port),
                "--log-level",
                "warning",
            ],
            cwd=ROOT,
            env=env,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    url = f"http://127.0.0.1:{port}"
    try:
        _wait_healthy(url, process, log)
        yield url
    finally:
        process.terminate()
        try:
            process.wait(timeout=15)
        except subprocess.TimeoutExpired:  # pragma: no cover - a hung shutdown
            process.kill()
            process.wait()


@pytest.fixture(scope="session")
def serve_factory() -> Callable[..., AbstractContextManager[str]]:
    """:func:`serve`, as a fixture: a service process with its own settings."""
    return serve


@pytest.fixture(scope="session")
def live_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """Base URL of a real ``planner serve`` process (uvicorn, 2 workers) on a free port."""
    with serve(tmp_path_factory.mktemp("live_server") / "server.log") as url:
        yield url
