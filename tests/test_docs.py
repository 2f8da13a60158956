"""The documents a newcomer reads stay true to the code: the client's method list in
docs/service.md is the client's, docs/service.md's endpoint table is the app's routes, every
curl example of the README and docs/*.md runs against a live service and every route has
one, no document cites an issue number (a reader has no tracker), the README's library
example of a timed plan runs as written, and `make run` serves on the port the README says."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path
from urllib.parse import urlsplit

import pytest
from doc_examples import (
    CURL_WRAPPER,
    curl_blocks,
    endpoint_rows,
    method_and_path,
    read_calls,
    shell_statements,
)
from starlette.routing import Match

from planner.client import AsyncPlannerClient, PlannerClient

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _public_methods(cls: type) -> set[str]:
    own = {"close", "aclose"}  # the connection's life, not an endpoint
    return {n for n in vars(cls) if not n.startswith("_") and n not in own}


def test_service_doc_lists_every_client_method():
    text = (ROOT / "docs" / "service.md").read_text()
    block = re.search(r"Methods: (.*?); the async client", text, re.S)
    assert block, "docs/service.md lost its 'Methods: ...' sentence"
    listed = set(re.findall(r"`([a-z_]+)`", block.group(1)))
    assert listed == _public_methods(PlannerClient)
    assert _public_methods(AsyncPlannerClient) == _public_methods(PlannerClient)


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_no_document_cites_an_issue(doc: Path):
    text = doc.read_text()
    assert not re.findall(r"(?i)\bissues? #?\d+|\bthe (service|timing|planning) issue\b", text)


def test_the_readme_timed_plan_runs():
    """The README's ``solve`` example, run as written: a solved, timed plan."""
    text = (ROOT / "README.md").read_text()
    blocks = [b for b in re.findall(r"```python\n(.*?)```", text, re.S) if "solve(" in b]
    assert len(blocks) == 1
    scope: dict = {}
    exec(compile(blocks[0].replace("print(", "(lambda *a: None)("), "README", "exec"), scope)
    s = scope["s"]
    assert s.solved and s.trajectory.duration > 0


# ---------------------------------------------------------------------------- endpoint table
def _served(app, method: str, path: str) -> bool:
    """Whether a route of ``app`` answers ``method path`` (a ``{param}`` as a sample value; a
    WebSocket route answers its path whatever the method word)."""
    concrete = re.sub(r"\{[^}]*\}", "x", path)
    for kind in ("http", "websocket"):
        scope = {
            "type": kind,
            "path": concrete,
            "method": method,
            "root_path": "",
            "path_params": {},
            "headers": [],
            "query_string": b"",
        }
        if any(route.matches(scope)[0] is Match.FULL for route in app.router.routes):
            return True
    return False


def _template(path: str) -> re.Pattern[str]:
    return re.compile(re.sub(r"\\\{[^}]*\\\}", "[^/]+", re.escape(path)) + "$")


def test_service_doc_endpoint_table_is_the_apps_routes():
    """Every row of docs/service.md's endpoint table is a route the app serves, and every
    operation of the OpenAPI document has its row (a route added later must get one)."""
    from planner_api.app import create_app

    app = create_app(warm_up=False)
    rows = endpoint_rows((ROOT / "docs" / "service.md").read_text())
    assert len(rows) >= 20, rows
    unserved = [f"{m} {p}" for m, p in rows if not _served(app, m, p)]
    assert not unserved, f"docs/service.md lists routes the app does not serve: {unserved}"
    samples = [(m, re.sub(r"\{[^}]*\}", "x", p)) for m, p in rows]
    missing = [
        f"{method.upper()} {path}"
        for path, item in app.openapi()["paths"].items()
        for method in item
        if not any(m == method.upper() and _template(path).match(p) for m, p in samples)
    ]
    assert not missing, f"docs/service.md's endpoint table lacks: {missing}"


# ---------------------------------------------------------------------------- curl examples
def test_curl_examples_are_read_whole():
    """The reader's shell: a quoted body over several lines and backslash continuations make
    one statement, comments none."""
    block = "curl -s a \\\n  -d '{\"x\": [1,\n 2]}'\n# -> {...}\ncurl b  # why\ndocker run x\n"
    assert shell_statements(block) == [
        "curl -s a \\\n  -d '{\"x\": [1,\n 2]}'",
        "curl b  # why",
        "docker run x",
    ]


def test_every_curl_example_runs_and_every_route_has_one(live_server, tmp_path):
    """Each curl example of README.md and docs/*.md, run as written against a live service
    (its host and port pointed at it): no HTTP error, no curl error, every file it writes
    non-empty; and together they call every operation of the OpenAPI document."""
    blocks = curl_blocks(DOCS, ROOT)
    assert len(blocks) >= 15 and {b.doc for b in blocks} >= {"README.md", "docs/service.md"}
    port = urlsplit(live_server).port
    assert port is not None
    log, failed = tmp_path / "calls", tmp_path / "failed"
    env = {**os.environ, "PORT": str(port), "CURL_LOG": str(log), "CURL_FAILED": str(failed)}
    problems = []
    for i, block in enumerate(blocks):
        cwd = tmp_path / f"block{i}"
        cwd.mkdir()
        script = CURL_WRAPPER + "\n".join(block.statements) + "\n"
        run = subprocess.run(
            ["bash", "-c", script], cwd=cwd, env=env, capture_output=True, text=True, timeout=120
        )
        if failed.exists():
            problems.append(f"{block.where}: {failed.read_text()}{run.stdout[-500:]}")
            failed.unlink()
        elif run.returncode != 0:
            problems.append(f"{block.where}: exit {run.returncode}: {run.stderr[-500:]}")
        empty = [f.name for f in cwd.iterdir() if f.stat().st_size == 0]
        if empty:
            problems.append(f"{block.where}: wrote empty files {empty}")
    assert not problems, "\n".join(problems)
    called = {c for c in (method_and_path(a, port) for a in read_calls(log.read_bytes())) if c}
    from planner_api.app import create_app

    paths = create_app(warm_up=False).openapi()["paths"]
    uncalled = [
        f"{method.upper()} {path}"
        for path, item in paths.items()
        for method in item
        if not any(m == method.upper() and _template(path).match(p) for m, p in called)
    ]
    assert not uncalled, f"no curl example in README.md or docs/*.md calls: {uncalled}"


# ---------------------------------------------------------------------------- make run
def test_make_run_serves_on_the_port_the_readme_names():
    """``PLANNER_PORT=8821 make run`` (the README's words) starts ``planner serve`` on 8821,
    PLANNER_HOST likewise; make's own ``PORT=`` still wins."""
    assert "PLANNER_PORT=8821 make run" in (ROOT / "README.md").read_text()
    make = shutil.which("make")
    assert make is not None, "make is what the README runs"

    clean = {k: v for k, v in os.environ.items() if k not in ("PLANNER_PORT", "PLANNER_HOST")}

    def serve_line(*args: str, **env: str) -> str:
        run = subprocess.run(
            [make, "-n", "run", *args],
            cwd=ROOT,
            capture_output=True,
            text=True,
            env={**clean, **env},
            check=True,
        )
        return [ln for ln in run.stdout.splitlines() if "planner serve" in ln][-1]

    assert serve_line().endswith("--host 127.0.0.1 --port 8000")
    assert serve_line(PLANNER_PORT="8821").endswith("--port 8821")
    assert "--host 0.0.0.0 " in serve_line(PLANNER_HOST="0.0.0.0")
    assert serve_line("PORT=9001", PLANNER_PORT="8821").endswith("--port 9001")
