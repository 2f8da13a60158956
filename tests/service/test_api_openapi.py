"""The OpenAPI document says everything (statuses, security, figure names), the API docs
render from the service's own files (no CDN), and schemathesis finds no failure on any
operation of a real server (bounded examples, every check)."""

from __future__ import annotations

import re
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import urljoin, urlparse

import pytest

from planner_api.routes.workspace import FIGURE_NAMES

ROOT = Path(__file__).resolve().parents[2]


def test_every_operation_documents_what_it_can_answer(api):
    paths = api.get("/openapi.json").json()["paths"]
    post = paths["/v1/plan"]["post"]["responses"]
    assert {"200", "408", "413", "415", "422", "502", "503", "504"} <= set(post)
    assert "401" not in post  # no key configured: no 401 can happen
    for path, item in paths.items():
        for method, op in item.items():
            codes = set(op["responses"])
            if method == "post":
                assert {"408", "413", "415", "422"} <= codes, (path, codes)
            if path != "/v1/health" and path.startswith("/v1/"):
                assert "503" in codes, (path, codes)
            for code, answer in op["responses"].items():
                if code != "200" and code.startswith(("4", "5")):
                    assert "application/json" in answer.get("content", {}), (path, code)


def test_security_schemes_and_401_when_a_key_is_configured(client_factory):
    with client_factory(api_key="s3cret", wait_ready=False) as c:
        spec = c.get("/openapi.json").json()
    schemes = spec["components"]["securitySchemes"]
    assert schemes["ApiKey"] == {"type": "apiKey", "in": "header", "name": "X-API-Key"}
    assert schemes["Bearer"]["scheme"] == "bearer"
    for path, item in spec["paths"].items():
        for op in item.values():
            guarded = path.startswith("/v1/") and path not in ("/v1/health", "/v1/ready")
            assert ("401" in op["responses"]) == guarded, path
            assert bool(op.get("security")) == guarded, path


def test_figure_names_are_an_enum(api):
    params = api.get("/openapi.json").json()["paths"]["/v1/figures/{filename}"]["get"]
    (name,) = [p for p in params["parameters"] if p["name"] == "filename"]
    enum = set(name["schema"]["enum"])
    assert enum == {f"{n}.{f}" for n in FIGURE_NAMES for f in ("png", "svg")}


def test_the_obstacles_type_is_required_as_the_service_refuses_a_body_without_it(api):
    schemas = api.get("/openapi.json").json()["components"]["schemas"]
    for name in ("SphereObstacle", "BoxObstacle", "CapsuleObstacle", "PointsObstacle"):
        assert "type" in schemas[name]["required"], (name, schemas[name]["required"])
        assert "default" not in schemas[name]["properties"]["type"], name
    sphere = {"center": [1.5, 0, 0], "radius": 0.1}
    posture = {"q": [0, 1, 2], "assembly_mode": "+"}
    r = api.post("/v1/plan", json={"start": posture, "goal": posture, "obstacles": [sphere]})
    assert r.status_code == 422
    (item,) = r.json()["detail"]
    assert item["loc"] == ["body", "obstacles", 0] and item["type"] == "union_tag_not_found"


class _Assets(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.urls: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        for key, value in attrs:
            if key in ("src", "href") and value:
                self.urls.append(value)


@pytest.mark.parametrize("page", ["/docs", "/redoc"])
def test_api_docs_load_nothing_from_outside(api, page):
    r = api.get(page)
    assert r.status_code == 200 and "text/html" in r.headers["content-type"]
    parser = _Assets()
    parser.feed(r.text)
    # URLs in inline scripts too (Swagger UI's initialiser names the OpenAPI URL)
    urls = parser.urls + re.findall(r"""url:\s*['"]([^'"]+)['"]""", r.text)
    assert len(urls) >= 2, urls
    for url in urls:
        full = urljoin("http://testserver" + page, url)
        assert urlparse(full).netloc == "testserver", url  # never a CDN or a font host
        assert api.get(urlparse(full).path).status_code == 200, url
    assert "googleapis" not in r.text and "cdn." not in r.text


#: The operations are fuzzed in this many shards, one test each (one schemathesis worker
#: per shard): xdist spreads them over its workers, where one run of every operation held
#: one worker for most of the suite's time.
SCHEMATHESIS_SHARDS = 4

#: Seconds one path's run took alone (schemathesis with this test's options against a warm
#: ``planner serve`` on 2 cores, its ~1 s start-up included), to balance the shards: dealt
#: round-robin in path order, one shard took 38 s and another 17 s, and the longest decides
#: when the suite ends. A path missing here counts :data:`DEFAULT_PATH_COST_S`; the figures
#: only balance, they are never asserted.
PATH_COST_S = {
    "/v1/analyze": 6.3,
    "/v1/calibrate": 4.7,
    "/v1/calibrate/poses": 6.9,
    "/v1/cartesian": 7.7,
    "/v1/design/check": 3.7,
    "/v1/design/mjcf": 4.1,
    "/v1/design/optimize": 9.7,
    "/v1/design/regions": 3.0,
    "/v1/designs": 1.1,
    "/v1/dynamics": 2.5,
    "/v1/figures/{filename}": 3.6,
    "/v1/fk": 3.5,
    "/v1/health": 2.0,
    "/v1/identify": 3.0,
    "/v1/ik": 2.5,
    "/v1/jobs": 2.0,
    "/v1/jobs/{job_id}": 4.0,
    "/v1/plan": 7.2,
    "/v1/plan/batch": 3.3,
    "/v1/ready": 1.9,
    "/v1/scenes": 1.3,
    "/v1/scenes/{name}": 5.3,
    "/v1/sequence": 6.5,
    "/v1/simulate": 2.1,
    "/v1/simulate/bag": 1.8,
    "/v1/stop": 4.5,
    "/v1/timing": 5.5,
    "/v1/version": 1.2,
    "/v1/workspace": 6.1,
}
DEFAULT_PATH_COST_S = 4.0


def _resource(path: str) -> str:
    """A path without its last ``/{parameter}`` segment: ``/v1/jobs/{job_id}`` and
    ``/v1/jobs`` are one resource, kept in one shard so that schemathesis's stateful phase
    can follow the links between them (create, then read or delete by name or id)."""
    return re.sub(r"/\{[^}/]+\}$", "", path)


def _shards(paths: list[str]) -> list[list[str]]:
    """The paths dealt into :data:`SCHEMATHESIS_SHARDS` shards of about equal cost, by
    resource (:func:`_resource`): the costliest first, each to the shard with the least so
    far (ties: by name, then the lower shard), so every xdist worker computes the same split."""
    groups: dict[str, list[str]] = {}
    for path in sorted(set(paths)):
        groups.setdefault(_resource(path), []).append(path)
    cost = {
        key: sum(PATH_COST_S.get(p, DEFAULT_PATH_COST_S) for p in group)
        for key, group in groups.items()
    }
    shards: list[list[str]] = [[] for _ in range(SCHEMATHESIS_SHARDS)]
    totals = [0.0] * SCHEMATHESIS_SHARDS
    for key in sorted(cost, key=lambda g: (-cost[g], g)):
        k = min(range(SCHEMATHESIS_SHARDS), key=lambda j: (totals[j], j))
        shards[k].extend(groups[key])
        totals[k] += cost[key]
    return shards


def _shard_regex(paths: list[str], shard: int) -> str:
    """The ``--include-path-regex`` of one shard (:func:`_shards`), matched exactly (the
    shards together are every path, once)."""
    mine = sorted(_shards(paths)[shard])
    return "^(?:" + "|".join(re.escape(p) for p in mine) + ")$"


def test_the_shards_cover_every_path_once():
    paths = ["/v1/plan", "/v1/plan/batch", "/v1/fk", "/v1/figures/{filename}", "/v1/ik"]
    hits = [
        [p for p in paths if re.fullmatch(_shard_regex(paths, k), p)]
        for k in range(SCHEMATHESIS_SHARDS)
    ]
    assert sorted(p for h in hits for p in h) == sorted(paths)  # each once, none twice
    assert all(hits), hits  # five paths over four shards: none left empty
    assert not any(  # exact, no prefix
        re.fullmatch(_shard_regex(paths, k), "/v1/plan/batch/x") for k in range(SCHEMATHESIS_SHARDS)
    )
    # a resource stays in one shard (its stateful links), and the shards are balanced by
    # cost: none holds more than the costliest resource over the even share
    every = sorted(PATH_COST_S)
    shards = _shards(every)
    (jobs,) = [k for k, shard in enumerate(shards) if "/v1/jobs" in shard]
    assert "/v1/jobs/{job_id}" in shards[jobs]
    cost = {key: 0.0 for key in map(_resource, every)}
    for p in every:
        cost[_resource(p)] += PATH_COST_S[p]
    totals = [sum(PATH_COST_S[p] for p in shard) for shard in shards]
    assert max(totals) - sum(totals) / SCHEMATHESIS_SHARDS <= max(cost.values())


@pytest.mark.parametrize("shard", range(SCHEMATHESIS_SHARDS))
def test_schemathesis_finds_no_failure_on_any_operation(live_server, tmp_path, shard):
    """Every check of schemathesis (status codes and content types documented, schemas of
    the answers, negative data rejected, no 5xx ...) over every operation (in
    :data:`SCHEMATHESIS_SHARDS` shards of the paths), with a bounded number of examples so
    that the suite stays fast (a long run belongs in benchmarks/).
    tests/schemathesis.toml says which answers count as accepted or rejected, and why, and
    narrows the coverage phase (every boundary case of a schema, no example bound) where it
    only repeated other cases: none for /v1/plan/batch (its items are /v1/plan's bodies, whose
    boundaries /v1/plan's coverage sends) and /v1/simulate(/bag) (plan, sequence and stop
    bodies one level down), negative
    only for the figures (every figure is drawn by test_api_workspace.py); all still get the
    fuzzing phase's examples (about 9,400 coverage cases over 34 operations)."""
    import httpx

    paths = list(httpx.get(f"{live_server}/openapi.json", timeout=60).json()["paths"])
    command = [
        sys.executable,
        "-m",
        "schemathesis.cli",
        "--config-file",
        str(ROOT / "tests" / "schemathesis.toml"),
        "run",
        f"{live_server}/openapi.json",
        "--include-path-regex",
        _shard_regex(paths, shard),
        # every check; the response-time check only as a hang guard, far above the request
        # budget (30 s): a speed bound would fail on a slow machine
        "--checks",
        "all",
        "--max-response-time",
        "300",
        "--max-examples",
        "12",
        "--seed",
        "1",
        # one worker: the shards run side by side under xdist instead (and CPython 3.11's
        # compiler race between threads, gh-106905, needs two)
        "--workers",
        "1",
        "--request-timeout",
        "60",
        "--generation-deterministic",
    ]
    out = subprocess.run(command, capture_output=True, text=True, timeout=900, cwd=tmp_path)
    report = out.stdout[-6000:] + out.stderr[-2000:]
    assert out.returncode == 0, report
    assert "No issues found" in out.stdout or " passed" in out.stdout, report
