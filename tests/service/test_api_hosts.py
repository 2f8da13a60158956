"""The Host check (``PLANNER_ALLOWED_HOSTS``) and relative redirects.

A keyless service answers only the loopback names by default, so that a web page whose name
resolves to 127.0.0.1 (DNS rebinding) cannot drive it from a browser; a keyed one answers any
host unless told; the probes answer any host (a load balancer probes by IP). Every redirect
is relative: its ``location`` never names the host the request sent.

The apps here never run a job: no warm pool is waited for."""

from __future__ import annotations

import asyncio
import json

import pytest
from pydantic import ValidationError

from planner_api.middleware import RequestGate, relative_location
from planner_api.settings import LOOPBACK_HOSTS, Settings, parse_allowed_hosts


@pytest.fixture(scope="module")
def keyless(client_factory):
    with client_factory(wait_ready=False, warm=False) as client:
        yield client


@pytest.fixture(scope="module")
def keyed(client_factory):
    with client_factory(wait_ready=False, warm=False, api_key="s3cret") as client:
        client.headers["x-api-key"] = "s3cret"
        yield client


@pytest.mark.parametrize(
    "host", ["localhost", "localhost:8000", "127.0.0.1:8000", "[::1]:8000", "LocalHost."]
)
def test_a_keyless_service_answers_the_loopback_names(keyless, host):
    assert keyless.get("/v1/version", headers={"host": host}).status_code == 200


@pytest.mark.parametrize(
    "host",
    ["evil.example", "evil.example:8000", "localhost.evil.example", "10.0.0.5:8000", "[::2]"],
)
def test_a_keyless_service_refuses_other_hosts_in_the_error_shape(keyless, host):
    for method, url in [
        ("GET", "/v1/version"),
        ("POST", "/v1/fk"),
        ("GET", "/"),
        ("GET", "/docs"),
        ("GET", "/metrics"),
    ]:
        r = keyless.request(method, url, headers={"host": host}, json={"q": [0, 1, 2]})
        assert r.status_code == 400, (url, r.status_code, r.text)
        (item,) = r.json()["detail"]
        assert item["loc"] == ["header", "host"] and item["type"] == "host_not_allowed"
        assert "PLANNER_ALLOWED_HOSTS" in item["msg"] and repr(host.lower())[1:4] in item["msg"]


@pytest.mark.parametrize("url", ["/v1/health", "/v1/ready"])
def test_the_probes_answer_any_host(keyless, url):
    """A load balancer or a kubelet probes a replica by its address (``Host: 10.0.0.5:8000``),
    which no deployment lists: the probes say nothing a page could use."""
    assert keyless.get(url, headers={"host": "10.0.0.5:8000"}).status_code in (200, 503)


def test_a_keyed_service_answers_any_host_by_default(keyed):
    assert keyed.get("/v1/version", headers={"host": "planner.example.com"}).status_code == 200
    assert Settings(api_key="k").keyed and Settings(api_key="k").host_names is None
    assert not Settings().keyed and Settings().host_names == LOOPBACK_HOSTS
    assert not Settings(api_key="").keyed  # an empty key is no key


def test_allowed_hosts_from_the_environment(monkeypatch, client_factory):
    monkeypatch.setenv("PLANNER_ALLOWED_HOSTS", " Planner.Example.com ,10.0.0.5,::1")
    assert Settings().host_names == {"planner.example.com", "10.0.0.5", "[::1]"}
    monkeypatch.setenv("PLANNER_ALLOWED_HOSTS", "*")
    assert Settings().host_names is None
    monkeypatch.setenv("PLANNER_ALLOWED_HOSTS", "planner.example.com")
    assert Settings(api_key="k").host_names == {"planner.example.com"}  # a key lists too
    with client_factory(wait_ready=False, warm=False) as client:
        ok = client.get("/v1/version", headers={"host": "planner.example.com:443"})
        assert ok.status_code == 200
        assert client.get("/v1/version").status_code == 400  # localhost is not listed


@pytest.mark.parametrize(
    "bad", ["", "a,,b", "planner.example.com:8000", "http://planner", "a/b", "[::1]:80", "*.x"]
)
def test_a_bad_allowed_hosts_is_refused_at_start_by_name(monkeypatch, bad):
    monkeypatch.setenv("PLANNER_ALLOWED_HOSTS", bad)
    with pytest.raises(ValidationError, match="allowed_hosts") as info:
        Settings()
    assert "PLANNER_ALLOWED_HOSTS" in str(info.value)
    with pytest.raises(ValueError, match="without port or scheme"):
        parse_allowed_hosts(bad)


def test_a_request_without_host_is_refused():
    """HTTP/1.0 may send no Host: nothing to compare, so not an allowed host (the probes
    still answer)."""

    async def app(scope, receive, send):  # pragma: no cover - never reached
        raise AssertionError("the gate let it through")

    gate = RequestGate(
        app, max_body_bytes=1024, timeout_s=1.0, body_timeout_s=1.0, allowed_hosts=LOOPBACK_HOSTS
    )
    sent: list[dict] = []

    async def send(message):
        sent.append(message)

    async def receive():  # pragma: no cover - never read
        return {"type": "http.request", "body": b""}

    scope = {"type": "http", "method": "GET", "path": "/v1/version", "headers": []}
    asyncio.run(gate(scope, receive, send))
    assert sent[0]["status"] == 400
    (item,) = json.loads(sent[1]["body"])["detail"]
    assert item["type"] == "host_not_allowed" and "none was given" in item["msg"]


@pytest.mark.parametrize(
    ("url", "location"),
    [
        ("/v1/version/", "/v1/version"),
        ("/v1/designs/?x=1", "/v1/designs?x=1"),
        ("/viewer", "/viewer/"),
    ],
)
def test_redirects_are_relative(keyless, keyed, url, location):
    """Starlette's trailing-slash redirect and the static files' directory redirect build an
    absolute location from the Host header; the answer's is relative, whatever the Host."""
    for client, host in [(keyless, "localhost:8000"), (keyed, "evil.example")]:
        r = client.get(url, headers={"host": host}, follow_redirects=False)
        assert r.status_code in (307, 308), (url, r.status_code, r.text)
        assert r.headers["location"] == location


def test_relative_location_keeps_foreign_and_relative_locations():
    assert relative_location(b"http://h:1/a?b=c", b"h:1") == b"/a?b=c"
    assert relative_location(b"https://H:1", b"h:1") == b"/"
    assert relative_location(b"http://h//evil.example/", b"h") == b"/evil.example/"
    assert relative_location(b"http://x/y", None) == b"/y"  # no Host: the server's own address
    assert relative_location(b"https://other.example/y", b"h") == b"https://other.example/y"
    assert relative_location(b"/already", b"h") == b"/already"


def test_the_openapi_document_lists_the_400(keyless):
    paths = keyless.get("/openapi.json").json()["paths"]
    assert "400" in paths["/v1/plan"]["post"]["responses"]
    assert "400" in paths["/v1/version"]["get"]["responses"]
    assert "400" not in paths["/v1/health"]["get"]["responses"]
