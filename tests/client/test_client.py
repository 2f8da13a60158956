"""The client's own behaviour against scripted answers (httpx.MockTransport): request
building, error translation, 503 retries honouring Retry-After, local validation, parity of
the sync and async clients."""

from __future__ import annotations

import asyncio
import inspect
import json
import threading
import time

import httpx
import pytest

import planner.client as client_module
import planner.client_errors as client_errors
from planner.client import (
    APIError,
    AsyncPlannerClient,
    AuthenticationError,
    DeadlineExceededError,
    InvalidRequestError,
    PlannerClient,
    PlannerClientError,
    ProtocolError,
    RequestTimeoutError,
    ServerError,
    ServiceUnavailableError,
    TransportError,
)
from planner.exceptions import PlannerError
from planner.wire import FKResponse, PlanRequest

START = {"q": [0.0, 1.0, 2.0], "assembly_mode": "+"}
EMPTY_FK = {"postures": []}


class Script:
    """A MockTransport handler answering from a list and recording the requests."""

    def __init__(self, *answers: httpx.Response) -> None:
        self.answers = list(answers)
        self.requests: list[httpx.Request] = []

    def __call__(self, request: httpx.Request) -> httpx.Response:
        self.requests.append(request)
        return self.answers.pop(0)


def _error(status: int, msg: str, loc=(), type_="x", headers=None) -> httpx.Response:
    return httpx.Response(
        status, json={"detail": [{"loc": list(loc), "msg": msg, "type": type_}]}, headers=headers
    )


def _sync(script: Script, **options) -> PlannerClient:
    return PlannerClient("http://planner.test", transport=httpx.MockTransport(script), **options)


def _async(script: Script, **options) -> AsyncPlannerClient:
    return AsyncPlannerClient(
        "http://planner.test", transport=httpx.MockTransport(script), **options
    )


@pytest.fixture
def sleeps(monkeypatch):
    """Record the client's sleeps instead of sleeping (sync and async). Only this thread's:
    ``time.sleep`` and ``asyncio.sleep`` are the modules' own, and a thread an earlier test
    of the same worker left running (a server's loop polling every 0.25 s) sleeps for real
    (faked, it once spun and filled the record)."""
    waited: list[float] = []
    here = threading.current_thread()
    real_sleep, real_async_sleep = time.sleep, asyncio.sleep

    def fake_sleep(s: float) -> None:
        if threading.current_thread() is here:
            waited.append(s)
        else:
            real_sleep(s)

    async def fake_async_sleep(s: float, *args: object) -> None:
        if threading.current_thread() is here:
            waited.append(s)
        else:
            await real_async_sleep(s, *args)

    monkeypatch.setattr(client_module.time, "sleep", fake_sleep)
    monkeypatch.setattr(client_module.asyncio, "sleep", fake_async_sleep)
    return waited


def test_the_sleeps_of_other_threads_are_real_and_not_recorded(sleeps):
    """The fixture records this thread's sleeps only: another thread's (a server left
    running by an earlier test of the worker) sleep for real and stay out of the record."""
    slept = []

    def other() -> None:
        async def poll() -> None:
            for _ in range(3):
                t0 = time.monotonic()
                await asyncio.sleep(0.01)
                slept.append(time.monotonic() - t0)

        asyncio.run(poll())
        t0 = time.monotonic()
        time.sleep(0.01)
        slept.append(time.monotonic() - t0)

    thread = threading.Thread(target=other)
    thread.start()
    thread.join(10)
    assert len(slept) == 4 and min(slept) >= 0.009 and sleeps == []


def test_request_body_headers_and_parsed_model():
    script = Script(httpx.Response(200, json=EMPTY_FK))
    with _sync(script, api_key="k") as c:
        answer = c.fk([0, 1, 2], "-", design={"L0": 0.3})
    assert isinstance(answer, FKResponse) and answer.postures == []
    (req,) = script.requests
    assert (req.method, req.url.path) == ("POST", "/v1/fk")
    assert req.headers["x-api-key"] == "k"
    assert req.headers["user-agent"].startswith("hybrid-planner-client/")
    assert json.loads(req.content) == {
        "q": [0.0, 1.0, 2.0],
        "assembly_mode": "-",
        "design": {"L0": 0.3},
    }


def test_numpy_arrays_and_library_designs_are_accepted():
    import numpy as np

    from planner import Design

    script = Script(httpx.Response(200, json={"postures": []}))
    with _sync(script) as c:
        c.ik(np.array([0.3, 0.1, 0.2]), "+-+", design=Design.paper_optimum())
    body = json.loads(script.requests[0].content)
    assert body["p"] == [0.3, 0.1, 0.2] and body["working_mode"] == "+-+"
    assert body["design"]["L0"] == 0 and body["design"]["L1"] == body["design"]["L2"] == 0.4


def test_plan_accepts_a_model_a_dict_or_keywords():
    ok = {"status": "no_path", "message": "budget ran out"}
    script = Script(*(httpx.Response(200, json=ok) for _ in range(3)))
    with _sync(script) as c:
        r1 = c.plan(PlanRequest(start=START, goal=START))
        r2 = c.plan({"start": START}, goal={"p": [0.3, 0.1, 0.2]})
        r3 = c.plan(start=START, goal=START, planner={"seed": 5})
    assert r1.status == r2.status == r3.status == "no_path"
    bodies = [json.loads(r.content) for r in script.requests]
    assert all(r.url.path == "/v1/plan" for r in script.requests)
    assert bodies[1] == {"start": START, "goal": {"p": [0.3, 0.1, 0.2]}}
    assert bodies[2]["planner"] == {"seed": 5}


def test_plan_batch_wraps_requests_and_returns_results():
    answer = {"results": [{"status": "solved"}, {"status": "unreachable"}]}
    script = Script(httpx.Response(200, json=answer))
    with _sync(script) as c:
        out = c.plan_batch(
            [{"start": START, "goal": START}, PlanRequest(start=START, goal={"p": [1, 1, 1]})]
        )
    assert [r.status for r in out.results] == ["solved", "unreachable"]
    body = json.loads(script.requests[0].content)
    assert script.requests[0].url.path == "/v1/plan/batch" and len(body["requests"]) == 2


def test_local_validation_fails_before_sending():
    script = Script()
    with _sync(script) as c:
        with pytest.raises(InvalidRequestError) as info:
            c.fk([0, 1, float("nan")])
        assert info.value.status_code is None
        assert info.value.detail[0]["loc"] == ["q", 2]
        with pytest.raises(InvalidRequestError, match="goal"):
            c.plan(start=START)
    assert script.requests == []


@pytest.mark.parametrize(
    ("status", "cls"),
    [
        (422, InvalidRequestError),
        (401, AuthenticationError),
        (504, DeadlineExceededError),
        (500, ServerError),
        (502, ServerError),
        (501, ServerError),
        (409, APIError),
    ],
)
def test_error_statuses_become_typed_exceptions_with_the_server_message(status, cls):
    script = Script(_error(status, "L1 must be positive", ("body", "design", "L1")))
    with _sync(script) as c, pytest.raises(cls) as info:
        c.fk([0, 1, 2])
    err = info.value
    assert type(err) is cls
    assert isinstance(err, PlannerClientError) and isinstance(err, PlannerError)
    assert err.status_code == status
    assert err.message == "body.design.L1: L1 must be positive"
    assert err.detail[0]["loc"] == ["body", "design", "L1"]


def test_non_json_error_body_still_carries_a_message():
    script = Script(httpx.Response(502, text="Bad gateway from the proxy"))
    with _sync(script) as c, pytest.raises(ServerError, match="Bad gateway from the proxy"):
        c.health()


def test_answer_not_matching_the_model_is_a_protocol_error():
    script = Script(
        httpx.Response(200, json={"postures": "many"}), httpx.Response(200, text="<html>")
    )
    with _sync(script) as c:
        with pytest.raises(ProtocolError, match="FKResponse"):
            c.fk([0, 1, 2])
        with pytest.raises(ProtocolError):
            c.fk([0, 1, 2])


def test_503_is_retried_honouring_retry_after(sleeps):
    script = Script(
        _error(503, "busy", headers={"Retry-After": "2"}),
        _error(503, "busy"),
        httpx.Response(200, json=EMPTY_FK),
    )
    with _sync(script, backoff_s=0.5) as c:
        assert c.fk([0, 1, 2]).postures == []
    assert len(script.requests) == 3
    assert sleeps == [2.0, 1.0]  # the server's advice, then backoff 0.5 * 2**1


def test_503_gives_up_after_max_retries_with_the_servers_advice(sleeps):
    script = Script(
        *(_error(503, "all workers busy", headers={"Retry-After": "30"}) for _ in range(3))
    )
    with _sync(script, max_retries=2, max_backoff_s=5) as c:
        with pytest.raises(ServiceUnavailableError, match="all workers busy") as info:
            c.fk([0, 1, 2])
    assert info.value.retry_after == 30.0 and info.value.status_code == 503
    assert sleeps == [5, 5]  # capped at max_backoff_s
    assert len(script.requests) == 3


def test_no_retry_on_other_errors(sleeps):
    script = Script(_error(500, "boom"))
    with _sync(script) as c, pytest.raises(ServerError):
        c.fk([0, 1, 2])
    assert sleeps == [] and len(script.requests) == 1


def test_ready_returns_the_503_answer_instead_of_raising(sleeps):
    script = Script(
        httpx.Response(503, json={"status": "starting", "workers": 2}, headers={"Retry-After": "1"})
    )
    with _sync(script) as c:
        assert c.ready().status == "starting"
    assert sleeps == []


def test_async_client_retries_and_translates_errors_the_same_way(sleeps):
    async def scenario():
        script = Script(
            _error(503, "busy", headers={"Retry-After": "1"}),
            httpx.Response(200, json=EMPTY_FK),
            _error(422, "bad q", ("body", "q")),
        )
        async with _async(script) as c:
            assert (await c.fk([0, 1, 2])).postures == []
            with pytest.raises(InvalidRequestError, match=r"body\.q: bad q"):
                await c.fk([0, 1, 2])
        return script

    script = asyncio.run(scenario())
    assert sleeps == [1.0] and len(script.requests) == 3


def test_transport_failures_are_translated():
    def refuse(request):
        raise httpx.ConnectError("connection refused", request=request)

    def slow(request):
        raise httpx.ReadTimeout("timed out", request=request)

    with PlannerClient("http://x", transport=httpx.MockTransport(refuse)) as c:
        with pytest.raises(TransportError, match="connection refused") as info:
            c.health()
        assert not isinstance(info.value, RequestTimeoutError)
    with PlannerClient("http://x", transport=httpx.MockTransport(slow)) as c:
        with pytest.raises(RequestTimeoutError):
            c.health()


def test_real_refused_connection(unused_port):
    with PlannerClient(f"http://127.0.0.1:{unused_port}", timeout=2) as c:
        with pytest.raises(TransportError):
            c.health()


def test_sync_and_async_clients_have_the_same_endpoint_methods():
    public = {n for n in dir(PlannerClient) if not n.startswith("_")} - {"close"}
    public_async = {n for n in dir(AsyncPlannerClient) if not n.startswith("_")} - {"aclose"}
    assert public == public_async
    assert {
        "fk",
        "ik",
        "analyze",
        "designs",
        "health",
        "version",
        "ready",
        "plan",
        "plan_batch",
        "check_design",
    } <= public
    # ``stream`` opens a session (``with`` / ``async with``), not one call: both have it
    assert (
        {"stream"} <= public and PlannerClient.stream.__doc__ and AsyncPlannerClient.stream.__doc__
    )
    calls = public - {"base_url", "timeout", "max_retries", "backoff_s", "max_backoff_s", "stream"}
    for name in calls:
        sync_m, async_m = getattr(PlannerClient, name), getattr(AsyncPlannerClient, name)
        assert inspect.signature(sync_m) == inspect.signature(async_m), name
        assert inspect.iscoroutinefunction(async_m) and not inspect.iscoroutinefunction(sync_m)
        assert sync_m.__doc__ and sync_m.__name__ == name
    assert str(inspect.signature(PlannerClient.fk).return_annotation) == "FKResponse"


def test_all_lists_exactly_the_public_names():
    """``__all__`` is, in sorted order, exactly the client's public classes and functions,
    its constants and the whole error tree of :mod:`planner.client_errors`: nothing missing,
    nothing else (not a wire model or a helper the module merely imports)."""
    names = client_module.__all__
    assert names == sorted(names, key=lambda n: (not n.isupper(), n))
    defined = {
        n
        for n, v in vars(client_module).items()
        if not n.startswith("_")
        and getattr(v, "__module__", None) == client_module.__name__
        and (inspect.isclass(v) or inspect.isfunction(v))
    }
    constants = {
        n
        for n, v in vars(client_module).items()
        if n.isupper() and isinstance(v, int | float | str) and not isinstance(v, bool)
    }
    errors = set(client_errors.__all__)
    assert errors == {
        n
        for n, v in vars(client_errors).items()
        if inspect.isclass(v) and issubclass(v, PlannerClientError)
    }
    assert [n for n in errors if getattr(client_module, n) is not getattr(client_errors, n)] == []
    assert sorted(names) == sorted(defined | constants | errors)
    # the sets are read from the module, not empty by a mistake of the rules above
    assert {"PlannerClient", "write_csv"} <= defined and "DEFAULT_BASE_URL" in constants


def test_bad_options_are_rejected():
    for options in ({"timeout": 0}, {"max_retries": -1}, {"backoff_s": -1.0}):
        with pytest.raises(ValueError):
            PlannerClient("http://x", **options)


def test_check_design_sends_only_the_options_given():
    answer = {
        "design": {},
        "volume": 1.0,
        "parallel_singularities": [],
        "singularity_free": True,
        "reasons": {},
        "operative_working_modes": [],
        "kappa_max": 10.0,
        "sampled_volume": {"value": 1, "standard_error": 0, "n_samples": 1},
        "well_conditioned_fraction": {"value": 1, "standard_error": 0, "n_samples": 1},
        "gci": {"value": 1, "standard_error": 0, "n_samples": 1},
    }
    script = Script(httpx.Response(200, json=answer))
    with _sync(script) as c:
        assert c.check_design({"L0": 0.4}, seed=3).singularity_free is True
    (req,) = script.requests
    assert req.url.path == "/v1/design/check"
    assert json.loads(req.content) == {"design": {"L0": 0.4}, "seed": 3}
