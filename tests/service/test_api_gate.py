"""What the service checks before it does any work, and in which order: size, API key,
content type, the body arriving in bounded time, JSON, schema; numbers that are numbers; and
answers bounded in samples and bytes, refused before the samples are computed."""

from __future__ import annotations

import socket
import time

import httpx
import pytest

from planner.endpoints import BYTES_PER_SAMPLE, answer_sample_limit

FK = {"q": [0.0, 1.0, 2.0]}
START = {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"}
GOAL = {"q": [0.6, 2.3, 0.8], "assembly_mode": "+"}
#: The 279-byte request of the operations review that answered 216 MB of JSON: TOPPRA at
#: 10 kHz under a velocity limit of 0.0082 rad/s (a 73 s motion, 732,522 samples).
HUGE = {
    "start": START,
    "goal": GOAL,
    "planner": {"seed": 1},
    "timing": {"method": "toppra", "sample_rate_hz": 10000},
    "limits": {"velocity": [0.0082, 0.0082, 0.0082], "acceleration": [1, 1, 1]},
}


@pytest.fixture(scope="module")
def keyed(client_factory):
    """An app with an API key whose worker is not warmed: every request here is answered by
    the gate or the validation before any job runs."""
    with client_factory(api_key="s3cret", warm=False) as c:
        yield c


def test_without_a_key_even_a_malformed_body_is_401(keyed):
    for content, ctype in [(b"{not json", "application/json"), (b"q=1", "text/plain")]:
        r = keyed.post("/v1/fk", content=content, headers={"content-type": ctype})
        assert r.status_code == 401, r.text
        assert r.headers["www-authenticate"] == "Bearer"
        assert r.json()["detail"][0]["type"] == "unauthorized"
    # with the key, the same bodies reach the next checks
    key = {"X-API-Key": "s3cret"}
    r = keyed.post("/v1/fk", content=b"q=1", headers={**key, "content-type": "text/plain"})
    assert r.status_code == 415
    r = keyed.post(
        "/v1/fk", content=b"{not json", headers={**key, "content-type": "application/json"}
    )
    assert r.status_code == 422 and r.json()["detail"][0]["type"] == "json_invalid"


def test_size_is_checked_before_the_key(client_factory):
    with client_factory(api_key="s3cret", max_body_bytes=1024, warm=False) as c:
        r = c.post("/v1/fk", content=b"x" * 2000, headers={"content-type": "application/json"})
        assert r.status_code == 413 and r.json()["detail"][0]["type"] == "body_too_large"


@pytest.mark.parametrize(
    "ctype", ["text/plain", "application/x-www-form-urlencoded", "multipart/form-data", None]
)
def test_a_body_that_is_not_json_is_415_naming_the_header(api, ctype):
    headers = {"content-type": ctype} if ctype else {}
    r = api.post("/v1/fk", content=b'{"q": [0, 1, 2]}', headers=headers)
    assert r.status_code == 415, r.text
    item = r.json()["detail"][0]
    assert item["loc"] == ["header", "content-type"] and item["type"] == "unsupported_media_type"
    assert "application/json" in item["msg"]
    # JSON with parameters, and structured +json types, are JSON
    for ok in ("application/json; charset=utf-8", "application/merge-patch+json"):
        r = api.post("/v1/fk", content=b'{"q": [0, 1, 2]}', headers={"content-type": ok})
        assert r.status_code == 200, (ok, r.text)


def test_a_boolean_or_a_string_is_not_a_number(api):
    for bad in (True, "1.0", None):
        r = api.post("/v1/fk", json={"q": [bad, 1.0, 2.0]})
        assert r.status_code == 422, (bad, r.text)
        assert r.json()["detail"][0]["loc"] == ["body", "q", 0]
    r = api.post("/v1/plan", json={"start": START, "goal": GOAL, "planner": {"seed": True}})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "planner", "seed"]
    assert api.post("/v1/fk", json={"q": [0, 1, 2]}).status_code == 200  # integers are numbers


def test_an_integer_of_5000_digits_is_named_not_called_invalid_json(api):
    body = b'{"q": [' + b"1" * 5000 + b", 1, 2]}"
    r = api.post("/v1/fk", content=body, headers={"content-type": "application/json"})
    assert r.status_code == 422
    item = r.json()["detail"][0]
    assert item["type"] == "number_too_long" and "5000 digits" in item["msg"], item


def test_the_216_mb_request_is_a_422_naming_the_rate_and_the_count(api):
    r = api.post("/v1/plan", json=HUGE)
    assert r.status_code == 422, r.status_code
    item = r.json()["detail"][0]
    assert item["loc"] == ["body", "timing", "sample_rate_hz"]
    # the count it would produce: duration x rate, the duration being that of a rest-to-rest
    # move of the largest joint step at 0.0082 rad/s (velocity-bound: it never reaches the
    # acceleration limit's share); independent of the library: trapezoid closed form
    step = max(abs(g - s) for g, s in zip(GOAL["q"], START["q"], strict=True))
    v, a = 0.0082, 1.0
    duration = step / v + v / a
    count = int(item["msg"].split(" would produce ")[1].split()[0])
    assert count == pytest.approx(duration * 10000, rel=0.02), item["msg"]
    assert "50000" in item["msg"]  # the limit, from the settings' default


def test_timing_endpoint_has_the_same_bound(api):
    body = {
        "waypoints": [START["q"], GOAL["q"]],
        "sample_rate_hz": 10000,
        "limits": HUGE["limits"],
    }
    r = api.post("/v1/timing", json=body)
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["loc"] == ["body", "sample_rate_hz"]


def test_a_batch_shares_the_response_bytes(api_with):
    """Two answers share max_response_bytes: each gets half the samples one answer gets (on
    the session's warm service: the routes read the limit per request)."""
    single = answer_sample_limit(50_000, 4_000_000)
    assert single == 4_000_000 // BYTES_PER_SAMPLE
    assert answer_sample_limit(50_000, 4_000_000, answers=2) == single // 2
    body = {**HUGE, "timing": {"method": "toppra", "sample_rate_hz": 100}}  # ~7,330 samples
    c = api_with(max_response_bytes=4_000_000)
    r = c.post("/v1/plan", json=body)
    assert r.status_code == 200 and r.json()["status"] == "solved"
    assert len(r.content) < 4_000_000
    r = c.post("/v1/plan/batch", json={"requests": [body, body]})
    assert r.status_code == 422, r.text[:300]
    item = r.json()["detail"][0]
    assert item["loc"][-1] == "sample_rate_hz" and str(single // 2) in item["msg"]


# ------------------------------------------------------------------ on a real server process
def _raw(url: str, request: bytes) -> socket.socket:
    host, port = url.removeprefix("http://").split(":")
    sock = socket.create_connection((host, int(port)), timeout=30)
    sock.sendall(request)
    return sock


def test_a_stalled_body_is_408_and_a_vanished_client_is_499_not_500(server_factory):
    _, url, _ = server_factory(workers="1", body_timeout_s="1", warm=False)
    head = b"POST /v1/fk HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
    # 15 of 30 declared bytes, then silence: 408 after the body timeout, connection closed
    sock = _raw(url, head + b"Content-Length: 30\r\n\r\n" + b'{"q": [0, 1, 2')
    t0 = time.monotonic()
    answer = b""
    while chunk := sock.recv(65536):
        answer += chunk
    waited = time.monotonic() - t0
    sock.close()
    assert answer.startswith(b"HTTP/1.1 408"), answer[:200]
    assert b"body_timeout" in answer
    assert waited < 20  # within the request budget (30 s), not held open
    # a client that sends half a body and goes away: recorded as 499
    sock = _raw(url, head + b"Content-Length: 30\r\n\r\n" + b'{"q": [0')
    sock.close()
    end = time.monotonic() + 30
    while True:
        metrics = httpx.get(f"{url}/metrics").text
        lines = [x for x in metrics.splitlines() if x.startswith("planner_http_requests_total{")]
        if any('status="499"' in x for x in lines):
            break
        assert time.monotonic() < end, lines
        time.sleep(0.1)
    assert not any('status="500"' in x for x in lines), lines
    # a cold worker pays its imports on this first job: minutes on a loaded machine, not 5 s
    assert httpx.post(f"{url}/v1/fk", json=FK, timeout=300).status_code == 200
