"""WebSocket /v1/stream: setpoints at the asked rate, paced by acknowledgements, a
replacement spliced at a chunk boundary with the setpoints continuous, a stop to rest, and
bad input as an error message naming the field, then close 1008.

Checked by finite differences of the streamed setpoints (the grid is t0 + i dt without gaps,
q moves by at most velocity x dt, qd by at most acceleration x dt) and by the end state.
"""

from __future__ import annotations

import base64
import time

import numpy as np
import pytest
from starlette.websockets import WebSocketDisconnect

START = {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"}
GOAL = {"q": [0.3, 2.1, 1.1], "assembly_mode": "+"}
TIMING = {"method": "ruckig"}


def _collect(ws, action_after: float | None = None, action: dict | None = None, hold: bool = False):
    """Receive until done, acknowledging each chunk's end less 40 ms (a client behind the
    stream) once its clock, which runs in real time from the first chunk, gets there;
    ``action`` sent once the stream passes ``action_after``. With ``hold`` the client's clock
    stands still from the action until the service's ``switched`` (a controller that holds
    its clock while it waits): the send horizon cannot pass the splice time however slow the
    machine, so where the splice lands does not depend on the machine's speed."""
    messages, sent, w0, waiting = [], False, None, False
    while True:
        m = ws.receive_json()
        messages.append(m)
        if m["type"] == "setpoints":
            end = m["t0"] + m["dt"] * (len(m["q"]) - 1)
            if action is not None and not sent and end > action_after:
                ws.send_json(action)
                sent, waiting = True, hold
            if waiting:
                continue
            w0 = time.monotonic() - m["t0"] if w0 is None else w0
            time.sleep(max(0.0, end - 0.04 - (time.monotonic() - w0)))
            ws.send_json({"type": "ack", "t": end - 0.04})
        elif m["type"] == "switched" and waiting:
            waiting, w0 = False, time.monotonic() - m["at"]  # the clock goes on from there
            ws.send_json({"type": "ack", "t": m["at"]})
        elif m["type"] in ("done", "error"):
            return messages


def _grid(messages):
    chunks = [m for m in messages if m["type"] == "setpoints"]
    t = np.concatenate([m["t0"] + m["dt"] * np.arange(len(m["q"])) for m in chunks])
    q, qd = (np.concatenate([np.asarray(m[k]) for m in chunks]) for k in ("q", "qd"))
    return t, q, qd


def _continuous(t, q, qd, dt):
    np.testing.assert_allclose(np.diff(t), dt, atol=1e-9)
    assert np.all(np.abs(np.diff(q, axis=0)) <= 2.0 * dt * (1 + 1e-6) + 1e-12)
    assert np.all(np.abs(np.diff(qd, axis=0)) <= 8.0 * dt * (1 + 1e-6) + 1e-12)


def test_a_stream_with_a_replacement_is_continuous_and_ends_at_the_new_goal(api):
    new_goal = {"q": [0.0, 1.9, 1.0], "assembly_mode": "+"}
    with api.websocket_connect("/v1/stream") as ws:
        request = {"start": START, "goal": GOAL, "timing": TIMING}
        ws.send_json({"type": "plan", "request": request, "rate_hz": 500, "lookahead_s": 0.05})
        replace = {"type": "replace", "request": {"goal": new_goal, "timing": TIMING}}
        messages = _collect(ws, 0.2, replace)
    switched = [m for m in messages if m["type"] == "switched"]
    assert len(switched) == 1 and messages[-1]["type"] == "done"
    t, q, qd = _grid(messages)
    at = switched[0]["at"]
    assert np.any(np.isclose(t, at, atol=1e-9))  # a chunk boundary on the grid
    _continuous(t, q, qd, 1 / 500)
    np.testing.assert_allclose(q[-1], new_goal["q"], atol=1e-9)
    assert not np.any(qd[-1])
    i = messages.index(switched[0])  # the new trajectory's setpoints come after the switch
    assert all(m["t0"] < at - 1e-9 for m in messages[:i] if m["type"] == "setpoints")
    later = [m["t0"] for m in messages[i + 1 :] if m["type"] == "setpoints"]
    assert any(abs(t0 - at) < 1e-9 for t0 in later)


def test_the_stream_goes_on_while_a_replacement_is_planned(api):
    # the client keeps acknowledging its clock after the replace; the service must keep
    # sending the running trajectory while the replacement is planned (a stream that waits
    # for the plan sends nothing between the replace and its `switched`), then splice at a
    # chunk boundary at or after the client's clock when it sent the replace
    new_goal = {"q": [0.0, 1.9, 1.0], "assembly_mode": "+"}
    replace = {"type": "replace", "request": {"goal": new_goal, "timing": TIMING}}
    with api.websocket_connect("/v1/stream") as ws:
        request = {"start": START, "goal": GOAL, "timing": TIMING}
        ws.send_json({"type": "plan", "request": request, "rate_hz": 1000, "lookahead_s": 0.05})
        messages, clock, sent_at, during, switched = [], 0.0, None, 0, None
        while True:
            m = ws.receive_json()
            messages.append(m)
            if m["type"] == "setpoints":
                during += sent_at is not None and switched is None
                if sent_at is None and m["t0"] > 0.1:
                    ws.send_json(replace)
                    sent_at = clock
                clock = m["t0"] + m["dt"] * (len(m["q"]) - 1) - 0.04
                ws.send_json({"type": "ack", "t": clock})
            elif m["type"] == "switched":
                switched = m
            else:
                assert m["type"] == "done", m
                break
    assert switched is not None and during >= 1  # chunks kept coming while it was planned
    t, q, qd = _grid(messages)
    _continuous(t, q, qd, 1 / 1000)  # no gap in setpoint time, continuous at the splice
    at = switched["at"]
    t0s = [m["t0"] for m in messages if m["type"] == "setpoints"]
    assert at >= sent_at and np.any(np.isclose(t0s, at, atol=1e-9))  # a chunk boundary
    i = messages.index(switched)
    assert all(m["t0"] < at - 1e-9 for m in messages[:i] if m["type"] == "setpoints")
    np.testing.assert_allclose(q[-1], new_goal["q"], atol=1e-9)


def test_a_stop_brings_the_stream_to_rest(api):
    with api.websocket_connect("/v1/stream") as ws:
        request = {"start": START, "goal": GOAL, "timing": TIMING}
        ws.send_json({"type": "plan", "request": request, "rate_hz": 1000})
        messages = _collect(ws, 0.05, {"type": "stop"}, hold=True)
    t, q, qd = _grid(messages)
    _continuous(t, q, qd, 1 / 1000)
    switched = [m for m in messages if m["type"] == "switched"]
    assert len(switched) == 1 and switched[0]["at"] < 0.3  # the 0.43 s motion stopped early
    assert not np.any(qd[-1]) and np.max(np.abs(q[-1] - GOAL["q"])) > 1e-3  # stopped short


@pytest.mark.parametrize(
    ("first", "loc"),
    [
        ({"type": "plan", "request": {"start": {"q": [0, 2], "assembly_mode": "+"}, "goal": GOAL}},
         ["request", "start", "q"]),
        ({"type": "plan", "request": {"start": START, "goal": GOAL}, "rate_hz": 0}, ["rate_hz"]),
        ({"type": "walk", "request": {}}, ["type"]),
    ],
)  # fmt: skip
def test_bad_input_is_an_error_message_then_close_1008(api, first, loc):
    with api.websocket_connect("/v1/stream") as ws:
        ws.send_json(first)
        error = ws.receive_json()
        assert error["type"] == "error" and error["loc"][: len(loc)] == loc, error
        with pytest.raises(WebSocketDisconnect) as closed:
            ws.receive_json()
        assert closed.value.code == 1008


def test_a_keyed_service_refuses_a_stream_without_its_key(api):
    # the route reads the keys per connection (the HTTP gate does not see WebSockets)
    from planner_api.settings import Settings

    saved = api.app.state.settings
    api.app.state.settings = Settings(**{**dict(saved), "api_keys": "alpha:k1"})
    try:
        with api.websocket_connect("/v1/stream") as ws:
            error = ws.receive_json()
            assert error["type"] == "error" and error["loc"] == ["header", "x-api-key"]
            with pytest.raises(WebSocketDisconnect) as closed:
                ws.receive_json()
            assert closed.value.code == 1008
        with api.websocket_connect("/v1/stream", headers={"x-api-key": "k1"}) as ws:
            body = {"start": START, "goal": GOAL}
            ws.send_json({"type": "plan", "request": body, "rate_hz": 100})
            assert ws.receive_json()["type"] == "setpoints"
        # a browser's way (it cannot set headers): the key as a subprotocol, base64url
        for key, first in [("k1", "setpoints"), ("k2", "error")]:
            encoded = base64.urlsafe_b64encode(key.encode()).decode().rstrip("=")
            offered = ["planner.stream", f"planner.key.{encoded}"]
            with api.websocket_connect("/v1/stream", subprotocols=offered) as ws:
                assert ws.accepted_subprotocol == "planner.stream"
                if first == "setpoints":
                    ws.send_json({"type": "plan", "request": body, "rate_hz": 100})
                assert ws.receive_json()["type"] == first
    finally:
        api.app.state.settings = saved


def test_the_clients_and_the_cli_stream_from_a_live_service(live_server, tmp_path):
    import asyncio
    import json

    from typer.testing import CliRunner

    from planner.client import AsyncPlannerClient, InvalidRequestError, PlannerClient
    from planner_cli import app

    request = {"start": START, "goal": GOAL, "timing": TIMING}
    with PlannerClient(live_server, timeout=30) as client:
        with client.stream(request, rate_hz=200) as session:
            messages = list(session)
        with pytest.raises(InvalidRequestError) as err, client.stream({"goal": GOAL}) as bad:
            list(bad)
        assert err.value.detail[0]["loc"][:2] == ["request", "start"]
    assert messages[-1]["type"] == "done"
    t, q, qd = _grid(messages)
    _continuous(t, q, qd, 1 / 200)
    np.testing.assert_allclose(q[-1], GOAL["q"], atol=1e-9)

    async def stream_async() -> list[dict]:
        async with AsyncPlannerClient(live_server, timeout=30) as client:
            async with client.stream(request, rate_hz=200) as session:
                return [m async for m in session]

    again = asyncio.run(stream_async())
    assert _grid(again)[1].tolist() == q.tolist()  # the same answer, the same setpoints
    path = tmp_path / "request.json"
    path.write_text(json.dumps(request))
    out = tmp_path / "stream.jsonl"
    args = ["stream", str(path), "--url", live_server, "--rate", "200", "--out", str(out)]
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 0, r.output
    assert r.stdout.splitlines()[-1].startswith("done at")
    assert [json.loads(x) for x in out.read_text().splitlines()] == messages
