"""Shared fixtures: an in-process app (FastAPI's TestClient) and a real service process.

``live_server`` starts ``planner serve`` (uvicorn) in a subprocess on a free loopback port,
waits for ``/v1/ready`` (every worker warm) and yields its base URL; the client tests and the
examples use it. ``serve_factory`` starts one with other settings (e.g. an API key) as a
context manager; ``server_factory`` starts processes that a test may signal or kill.
``postgres_factory`` starts a PostgreSQL server of a test's own (Debian's ``postgresql``
package), which the test may stop and start again. ``pytest_collection_modifyitems`` runs
the modules of :data:`RUN_FIRST` (the longest single tests) first, so that under ``-n 2`` no
long test starts near the end while the other worker idles.
"""

from __future__ import annotations

import glob
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, ExitStack, contextmanager
from pathlib import Path

import httpx
import pytest
from fastapi.testclient import TestClient

from planner_api.app import create_app
from planner_api.settings import Settings

ROOT = Path(__file__).resolve().parents[1]
# named scenes of the tests' services go to a file of this run (each xdist worker its own),
# never to the user's default store (planner_api.scene_store.default_store_path)
os.environ.setdefault(
    "PLANNER_SCENE_STORE", str(Path(tempfile.mkdtemp(prefix="planner-scenes-")) / "scenes.db")
)
#: Seconds allowed for a service to be ready (every worker warm) after it starts: the first
#: warm-up of a fresh checkout compiles and imports for tens of seconds on a slow machine.
STARTUP_TIMEOUT_S = 180.0
#: The base URL of the in-process clients: a loopback name, which a keyless service answers
#: by default (TestClient's own ``testserver`` is no allowed host: PLANNER_ALLOWED_HOSTS).
LOCAL_URL = "http://localhost"


def free_port() -> int:
    """A TCP port free on 127.0.0.1 right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class ReadyClient(TestClient):
    """A TestClient whose ``with`` block starts once ``/v1/ready`` answers 200, i.e. every
    worker is warm, as a client of a real deployment waits for readiness (a request sent
    earlier would spend its time budget waiting for the workers' warm-up)."""

    wait_ready = True

    def __enter__(self) -> ReadyClient:
        super().__enter__()
        if self.wait_ready:
            wait_ready(self)
        return self


def wait_ready(client: httpx.Client | TestClient, timeout_s: float = STARTUP_TIMEOUT_S) -> None:
    """Wait until ``client``'s service answers ``/v1/ready`` with 200 (no key needed)."""
    end = time.monotonic() + timeout_s
    while True:
        r = client.get("/v1/ready")
        if r.status_code == 200:
            return
        assert r.status_code == 503, r.text
        assert time.monotonic() < end, f"the workers never became ready: {r.text}"
        time.sleep(0.05)


def make_client(*, wait_ready: bool = True, warm: bool = True, **settings: object) -> TestClient:
    """A TestClient of an app built with these settings (one worker unless told); entering
    it waits for readiness unless ``wait_ready`` is False.

    ``warm=False``: the workers skip the service's warm-up (a worker is ready once started,
    under a second, against several seconds of CPU for a warm one); for tests of what the
    service does before or around a job (gate, key, limits, metrics, the pool), whose jobs,
    if any, are cheap and not timed against a tight budget."""
    settings.setdefault("workers", 1)
    app = create_app(Settings(**settings), warm_up=warm)
    client = ReadyClient(app, base_url=LOCAL_URL, raise_server_exceptions=False)
    client.wait_ready = wait_ready
    return client


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


#: The settings the routes read from ``app.state.settings`` on every request; the others are
#: fixed when the app is built (the gate's API key, body size and request budget; the pool).
PER_REQUEST_SETTINGS = frozenset(
    {
        "default_design",
        "max_batch",
        "max_obstacles",
        "max_response_bytes",
        "max_section_resolution",
        "max_sequence_targets",
        "max_trajectory_samples",
    }
)


@pytest.fixture
def api_with(api: TestClient) -> Iterator[Callable[..., TestClient]]:
    """The session's warm ``api`` with some settings changed for one test:
    ``api_with(max_section_resolution=8)`` returns ``api``, whose routes then read the new
    settings (validated like the environment's); restored at the test's end. A test of a
    per-request limit or default needs no pool of its own. Only
    :data:`PER_REQUEST_SETTINGS`: a test of the gate's or the pool's settings builds its own
    app (``client_factory(..., warm=False)``). Should a route stop reading its settings per
    request, the test sees the default instead and fails: it cannot pass by mistake."""

    saved: Settings = api.app.state.settings

    def use(**changes: object) -> TestClient:
        unknown = set(changes) - PER_REQUEST_SETTINGS
        assert not unknown, f"fixed when the app is built, not per request: {unknown}"
        api.app.state.settings = Settings(**{**dict(saved), **changes})
        return api

    try:
        yield use
    finally:
        api.app.state.settings = saved


def wait_live_ready(url: str, process: subprocess.Popen[bytes], log: Path) -> None:
    """Wait until the service process at ``url`` answers ``/v1/ready`` with 200 (every
    worker warm); fail with the end of its log if it exits or never gets there."""
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise RuntimeError(
                f"the service exited with {process.returncode}:\n{log.read_text()[-4000:]}"
            )
        try:
            if httpx.get(f"{url}/v1/ready", timeout=1.0).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        time.sleep(0.1)
    raise RuntimeError(
        f"the service was not ready within {STARTUP_TIMEOUT_S} s:\n{log.read_text()[-4000:]}"
    )


@contextmanager
def serve(log: Path, **env_vars: str) -> Iterator[str]:
    """A real ``planner serve`` process (uvicorn) on a free loopback port, its environment
    without ``PLANNER_API_KEY`` unless given in ``env_vars`` (2 workers unless told); yields
    its base URL once ``/v1/ready`` answers (every worker warm), and stops it at the end."""
    with serve_process(log, **env_vars) as (_, url):
        yield url


@contextmanager
def serve_process(
    log: Path, *, log_level: str = "warning", warm: bool = True, **env_vars: str
) -> Iterator[tuple[subprocess.Popen[bytes], str]]:
    """:func:`serve`, yielding the process too (process, base URL).

    ``warm=False``: the same server (:func:`planner_api.server.run`, through
    ``ops_jobs.serve``) with workers that skip the warm-up, for tests of the server around
    the jobs (the gate on a real socket, signals) whose jobs are cheap."""
    port = free_port()
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(
            [str(ROOT / "src"), str(ROOT), os.environ.get("PYTHONPATH", "")]
        ),
        "PLANNER_WORKERS": "2",
        "PLANNER_DRAIN_S": "0",  # stopped at once at the end (the drain: test_ops_drain.py)
    }
    env.pop("PLANNER_API_KEY", None)
    env.update(env_vars)
    if warm:
        options = ["--host", "127.0.0.1", "--port", str(port), "--log-level", log_level]
        command = [sys.executable, "-m", "planner_cli", "serve", *options]
    else:
        env.update(PLANNER_HOST="127.0.0.1", PLANNER_PORT=str(port), PLANNER_LOG_LEVEL=log_level)
        env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "tests"), env["PYTHONPATH"]])
        command = [sys.executable, "-c", "import ops_jobs; ops_jobs.serve(None, warm_up=False)"]
    with log.open("wb") as out:
        process = subprocess.Popen(
            command,
            cwd=ROOT,
            env=env,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    url = f"http://127.0.0.1:{port}"
    try:
        wait_live_ready(url, process, log)
        yield process, url
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


@pytest.fixture
def server_factory(
    tmp_path: Path,
) -> Iterator[Callable[..., tuple[subprocess.Popen[bytes], str, Path]]]:
    """Start ``planner serve`` processes with extra ``PLANNER_*`` settings (keyword
    arguments, e.g. ``workers="2"``; ``warm=False``: see :func:`serve_process`), JSON logs
    at INFO, each ready (every worker warm); yields the starter, which returns (process, base
    URL, log path), for tests that signal or kill the process. Every process is stopped at
    the end of the test."""
    count = iter(range(1_000))
    with ExitStack() as stack:

        def start(
            *, warm: bool = True, **settings: str
        ) -> tuple[subprocess.Popen[bytes], str, Path]:
            log = tmp_path / f"server-{next(count)}.log"
            env = {"PLANNER_LOG_FORMAT": "json"}
            env.update({f"PLANNER_{k.upper()}": v for k, v in settings.items()})
            context = serve_process(log, log_level="info", warm=warm, **env)
            process, url = stack.enter_context(context)
            return process, url, log

        yield start


class PostgresServer:
    """A PostgreSQL server in a temporary folder on a free loopback port (initdb and pg_ctl
    of Debian's ``postgresql`` package), trusting the user ``planner``; ``stop()`` and
    ``start()`` it at will (the same data, the same port)."""

    def __init__(self, bindir: Path) -> None:
        self.bindir = bindir
        # a folder of its own under the system's temporary folder: pytest's is private to
        # the user running the tests, which the server's user (below) may not be
        self.root = Path(tempfile.mkdtemp(prefix="planner-pg-"))
        self.data, self.port = self.root / "data", free_port()
        self.url = f"postgresql://planner@127.0.0.1:{self.port}/postgres"
        # initdb refuses to run as root: run the server as the package's postgres user then
        self.as_user: list[str] = []
        if os.geteuid() == 0:
            self.as_user = ["runuser", "-u", "postgres", "--"]
            shutil.chown(self.root, "postgres")
        # --no-sync: a throwaway cluster need not wait for its files to reach the disk (4 s
        # of initdb's 5 here; the server runs with fsync=off for the same reason)
        command = ["-D", str(self.data), "-U", "planner", "--auth=trust", "-E", "UTF8"]
        self._pg("initdb", *command, "--no-sync")

    def _pg(self, tool: str, *args: str, check: bool = True) -> None:
        subprocess.run(
            [*self.as_user, str(self.bindir / tool), *args],
            check=check,
            capture_output=True,
            timeout=120,
        )

    def start(self) -> None:
        options = f"-p {self.port} -k {self.root} -c listen_addresses=127.0.0.1 -c fsync=off"
        self._pg(
            "pg_ctl",
            "-D",
            str(self.data),
            "-o",
            options,
            "-l",
            str(self.root / "log"),
            "-w",
            "start",
        )

    def stop(self) -> None:
        self._pg("pg_ctl", "-D", str(self.data), "-m", "immediate", "-w", "stop", check=False)

    def remove(self) -> None:
        self.stop()
        shutil.rmtree(self.root, ignore_errors=True)


@pytest.fixture(scope="session")
def postgres_factory() -> Callable[[], AbstractContextManager[PostgresServer]]:
    """Start a :class:`PostgresServer` (a few seconds), as a context manager; skipped with
    the reason when the package, the psycopg driver or (as root) runuser is missing."""
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"))
    if not found:
        pytest.skip("PostgreSQL is not installed (Debian package postgresql: initdb, pg_ctl)")
    try:
        import psycopg  # noqa: F401
    except ImportError:
        pytest.skip("the psycopg driver is not installed (pip install psycopg)")
    if os.geteuid() == 0 and shutil.which("runuser") is None:
        pytest.skip("running as root without runuser: cannot start PostgreSQL as postgres")

    @contextmanager
    def start() -> Iterator[PostgresServer]:
        server = PostgresServer(Path(found[-1]).parent)
        try:
            server.start()
            yield server
        finally:
            server.remove()

    return start


@pytest.fixture(scope="session")
def browser() -> Iterator[object]:
    """One headless chromium for every viewer test of the session (a launch costs a second
    or two); each module opens its own context and page on it (``viewer_browser.py``). Here,
    not in a ``tests/viewer/conftest.py``: a second module named ``conftest`` would shadow
    this one for the tests that import its helpers."""
    from viewer_browser import launch

    with launch() as b:
        yield b


#: Test modules whose single tests are the suite's longest (tens of seconds each on 2 cores:
#: schemathesis's shards, a local Ray cluster, a live server's slow clients and worker kills,
#: every figure of every preset, 64 time-bounded plans), longest first. They run first:
#: under ``-n 2`` a 30 s test started near the end keeps one worker busy while the other
#: idles, so long tests go first and the short ones fill in behind them (xdist hands out the
#: rest as workers free up). Whole modules move, in their own order, so a module-scoped
#: fixture is still set up once per worker. A module missing here only runs later; a name
#: that no longer exists moves nothing.
RUN_FIRST = (
    "tests/service/test_api_openapi.py",
    "tests/ops/test_ops_ray.py",
    "tests/ops/test_ops_slow_clients.py",
    "tests/ops/test_ops_workers.py",
    "tests/service/test_api_worker_body.py",
    "tests/service/test_api_workspace.py",
    "tests/analysis/test_obstacle_regions.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Move the modules of :data:`RUN_FIRST` to the front, in that order (a stable sort: the
    others keep their collection order). Every xdist worker sorts alike, as xdist requires."""
    rank = {name: k for k, name in enumerate(RUN_FIRST)}

    def key(item: pytest.Item) -> int:
        try:
            module = item.path.relative_to(ROOT).as_posix()
        except ValueError:
            return len(RUN_FIRST)
        return rank.get(module, len(RUN_FIRST))

    items.sort(key=key)
