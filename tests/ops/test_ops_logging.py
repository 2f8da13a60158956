"""Structured JSON logs with a request id: the id is taken from X-Request-ID when sane or
made, echoed in the answer, and carried by every log line of the request, including the
lines written by the job in its worker process."""

from __future__ import annotations

import io
import json
import logging
import os
import re

import pytest
from ops_jobs import sleep_pid

from planner_api.logging import (
    REQUEST_ID,
    JsonFormatter,
    RequestIdFilter,
    configure_logging,
    request_id_from,
    uvicorn_log_config,
)
from planner_api.routes.plan import get_plan_function

HEX32 = re.compile(r"[0-9a-f]{32}")


@pytest.fixture
def access_lines():
    """The api.access lines of the test, as parsed JSON objects."""
    stream = io.StringIO()
    handler = logging.StreamHandler(stream)
    handler.setFormatter(JsonFormatter())
    handler.addFilter(RequestIdFilter())
    lg = logging.getLogger("api.access")
    old_level = lg.level
    lg.addHandler(handler)
    lg.setLevel(logging.DEBUG)
    try:
        yield lambda: [json.loads(line) for line in stream.getvalue().splitlines()]
    finally:
        lg.removeHandler(handler)
        lg.setLevel(old_level)


def test_request_id_from_header_or_new():
    assert request_id_from("abc-123_x.y:z") == "abc-123_x.y:z"
    assert request_id_from(b"trace-7") == "trace-7"
    for bad in (None, "", "a b", "x" * 129, "id\r\nSet-Cookie: x", "é"):
        made = request_id_from(bad)
        assert HEX32.fullmatch(made), bad
    assert request_id_from(None) != request_id_from(None)


def test_json_formatter_fields_extras_and_exceptions():
    record = logging.LogRecord("api.test", logging.WARNING, __file__, 1, "x=%d", (3,), None)
    record.route = "/v1/plan"
    record.sizes = (1, 2)
    token = REQUEST_ID.set("rid-1")
    try:
        RequestIdFilter().filter(record)
    finally:
        REQUEST_ID.reset(token)
    line = json.loads(JsonFormatter().format(record))
    assert line["message"] == "x=3"
    assert line["level"] == "warning"
    assert line["logger"] == "api.test"
    assert line["request_id"] == "rid-1"
    assert line["route"] == "/v1/plan"
    assert line["sizes"] == [1, 2]
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z", line["ts"])
    try:
        raise ValueError("boom")
    except ValueError:
        import sys

        record = logging.LogRecord("a", logging.ERROR, __file__, 1, "failed", (), sys.exc_info())
    RequestIdFilter().filter(record)
    line = json.loads(JsonFormatter().format(record))
    assert line["request_id"] is None  # outside any request
    assert "ValueError: boom" in line["exc_info"]


def test_configure_logging_and_uvicorn_config_write_json(capsys):
    import logging.config

    root = logging.getLogger()
    saved = (list(root.handlers), root.level)
    try:
        configure_logging("info", "json")
        token = REQUEST_ID.set("r-9")
        logging.getLogger("uvicorn.error").info("hello %s", "there")
        logging.getLogger("some.lib").debug("hidden at info")
        REQUEST_ID.reset(token)
        err = capsys.readouterr().err.splitlines()
        assert len(err) == 1
        line = json.loads(err[0])
        assert (line["message"], line["request_id"], line["logger"]) == (
            "hello there",
            "r-9",
            "uvicorn.error",
        )
        logging.config.dictConfig(uvicorn_log_config("warning", "text"))
        logging.getLogger("uvicorn").warning("plain")
        err = capsys.readouterr().err
        assert err.rstrip().endswith("WARNING uvicorn [None] plain")
    finally:
        root.handlers[:] = saved[0]
        root.setLevel(saved[1])


def test_request_id_echoed_and_in_access_log(client_factory, access_lines):
    with client_factory(warm=False) as c:  # the observer's work: no warm worker needed
        given = c.post("/v1/fk", json={"q": [0.1, 1.0, 2.0]}, headers={"X-Request-ID": "req-42"})
        made = c.post("/v1/fk", json={"q": [0.1, 1.0]})
        refused = c.get("/v1/fk", headers={"X-Request-ID": "bad id"})
    assert given.status_code == 200 and given.headers["x-request-id"] == "req-42"
    assert made.status_code == 422 and HEX32.fullmatch(made.headers["x-request-id"])
    assert refused.status_code == 405 and HEX32.fullmatch(refused.headers["x-request-id"])
    lines = [x for x in access_lines() if x["path"] == "/v1/fk"]
    assert [(x["request_id"], x["status"], x["method"], x["route"]) for x in lines] == [
        ("req-42", 200, "POST", "/v1/fk"),
        (made.headers["x-request-id"], 422, "POST", "/v1/fk"),
        (refused.headers["x-request-id"], 405, "GET", "/v1/fk"),
    ]
    assert all(x["duration_ms"] > 0 for x in lines)


def test_worker_log_lines_carry_the_request_id(client_factory, capfd):
    # the worker processes inherit the test's stderr and log JSON (log_setup of the pool)
    with client_factory(log_format="json", log_level="warning", warm=False) as c:
        c.app.dependency_overrides[get_plan_function] = lambda: sleep_pid
        body = {"start": {"q": [0.0, 1.0, 2.0], "assembly_mode": "+"},
                "goal": {"p": [0.3, 0.1, 0.2]}, "planner": {"time_budget_s": 0.01}}  # fmt: skip
        r = c.post("/v1/plan", json=body, headers={"X-Request-ID": "plan-77"})
        assert r.status_code == 200
    worker_pid = int(r.json()["message"])
    lines = [json.loads(x) for x in capfd.readouterr().err.splitlines() if x.startswith("{")]
    mine = [x for x in lines if x["logger"] == "tests.ops_jobs"]
    assert len(mine) == 1
    assert mine[0]["request_id"] == "plan-77"
    assert mine[0]["message"] == "sleeping 0.01 s"
    assert mine[0]["pid"] == worker_pid != os.getpid()  # written in the worker process
