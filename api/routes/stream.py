"""WebSocket /v1/stream: a plan or sequence answer streamed as chunks of setpoints, paced by
the client's acknowledgements, with replacements and stops spliced at chunk boundaries.

The rules live in :class:`planner.endpoints.stream.StreamSession`; this route does the I/O:
the API key and the service's limits as on the HTTP routes (the request gate of
:mod:`planner_api.middleware` sees only HTTP, so the key is checked here), every plan, sequence
or stop computed in the worker pool, errors sent as ``{"type": "error", "loc", "msg"}`` and the
socket closed with 1008 (policy violation). A client that stops acknowledging gets nothing
more and is closed after ``PLANNER_REQUEST_TIMEOUT_S`` without a message (1008 too), so a
slow reader never makes the service queue data.

A browser cannot set a WebSocket's headers, so the key may also come as a subprotocol (as
Kubernetes does for its bearer tokens): the client offers ``planner.stream`` and
``planner.key.<the key in base64url, unpadded>``; the route accepts ``planner.stream`` (it never
echoes the key). The key is not taken from the query string, which access logs record.
"""

from __future__ import annotations

import asyncio
import base64
import binascii
import json
import time
from functools import partial
from typing import Any

from fastapi import APIRouter, WebSocket, WebSocketDisconnect
from pydantic import TypeAdapter, ValidationError

from planner.endpoints import Job, JobBudget, answer_sample_limit
from planner.endpoints import stream as jobs
from planner.endpoints.stream import StreamSession
from planner.exceptions import PlannerError
from planner.wire import PlanRequest, SequenceRequest, StopRequest, StreamMessage, StreamStart
from planner_api.metrics import run_measured
from planner_api.routes._common import obstacles_within_limit, with_design_defaults
from planner_api.tenants import tenant_of

__all__ = ["StreamError", "router", "stream"]

router = APIRouter(tags=["execution"])

POLICY_VIOLATION = 1008
PROTOCOL = "planner.stream"
KEY_PROTOCOL = "planner.key."
_MESSAGE = TypeAdapter(StreamMessage)


class StreamError(Exception):
    """A message for the client: ``loc`` (the field) and ``msg``, then close 1008."""

    def __init__(self, loc: list[Any], msg: str) -> None:
        super().__init__(msg)
        self.loc, self.msg = loc, msg


def _validated(model: Any, data: Any, loc: list[Any]) -> Any:
    try:
        return (
            model.model_validate(data)
            if hasattr(model, "model_validate")
            else model.validate_python(data)
        )
    except ValidationError as exc:
        first = exc.errors()[0]
        raise StreamError([*loc, *first["loc"]], first["msg"]) from exc


async def _compute(websocket: WebSocket, kind: str, body: dict[str, Any], loc: list[Any]) -> dict:
    """The answer of a plan, sequence or stop ``body`` computed in the worker pool, as JSON
    data; a library error or a non-solved status is a :class:`StreamError`."""
    app = websocket.app
    settings = app.state.settings
    kinds: dict[str, tuple[Any, Job]] = {
        "plan": (PlanRequest, jobs.plan),
        "sequence": (SequenceRequest, jobs.sequence),
        "stop": (StopRequest, jobs.stop),
    }
    model, job = kinds[kind]
    request = obstacles_within_limit(_validated(model, body, loc), settings)
    request = with_design_defaults(request, settings.design_defaults)
    deadline = time.monotonic() + settings.request_timeout_s
    samples = answer_sample_limit(settings.max_trajectory_samples, settings.max_response_bytes)
    try:
        content, _ = await app.state.pool.run(
            partial(run_measured, job, budget=JobBudget(deadline, samples)),
            request,
            deadline=deadline,
        )
    except PlannerError as exc:
        where = list(getattr(exc, "loc", ("body", *exc.field_path)))
        raise StreamError([*loc, *where[1:]], str(exc)) from exc
    answer = json.loads(content)
    if answer.get("status") != "solved" or answer.get("trajectory") is None:
        raise StreamError(loc, f"{kind} answered {answer.get('status')}: {answer.get('message')}")
    return answer


def _authorised(websocket: WebSocket) -> bool:
    keys = websocket.app.state.settings.tenant_keys
    if keys is None:
        return True
    headers = {k.lower(): v for k, v in websocket.headers.items()}
    if "x-api-key" not in headers:
        for offered in websocket.scope.get("subprotocols", []):
            if offered.startswith(KEY_PROTOCOL):
                encoded = offered[len(KEY_PROTOCOL) :]
                try:
                    key = base64.urlsafe_b64decode(encoded + "=" * (-len(encoded) % 4))
                    headers["x-api-key"] = key.decode()
                except (binascii.Error, UnicodeDecodeError):
                    pass  # not a key: refused below like a missing one
    return tenant_of(headers, keys) is not None


@router.websocket("/v1/stream")
async def stream(websocket: WebSocket) -> None:
    """Stream setpoints (see the module docstring and docs/execution.md)."""
    chosen = PROTOCOL if PROTOCOL in websocket.scope.get("subprotocols", []) else None
    await websocket.accept(subprotocol=chosen)
    try:
        if not _authorised(websocket):
            raise StreamError(["header", "x-api-key"], "a valid API key is required")
        await _serve(websocket)
    except StreamError as exc:
        await websocket.send_json({"type": "error", "loc": exc.loc, "msg": exc.msg})
        await websocket.close(POLICY_VIOLATION)
    except WebSocketDisconnect:
        return


async def _receive(websocket: WebSocket, timeout: float) -> Any:
    try:
        text = await asyncio.wait_for(websocket.receive_text(), timeout)
    except TimeoutError as exc:
        raise StreamError([], f"no message for {timeout:g} s: the stream is closed") from exc
    try:
        return json.loads(text)
    except ValueError as exc:
        raise StreamError([], f"a message must be JSON: {exc}") from exc


async def _serve(websocket: WebSocket) -> None:
    idle = websocket.app.state.settings.request_timeout_s
    start = _validated(StreamStart, await _receive(websocket, idle), [])
    request = {**start.request}
    request["timing"] = {**request.get("timing", {}), "sample_rate_hz": start.rate_hz}
    answer = await _compute(websocket, start.type, request, ["request"])
    session = StreamSession(answer["trajectory"], start.rate_hz, start.lookahead_s)
    while True:
        for message in session.pending():
            await websocket.send_json(message)
        if session.finished:
            await websocket.close()
            return
        incoming = _validated(_MESSAGE, await _receive(websocket, idle), [])
        if incoming.type == "ack":
            session.acknowledge(incoming.t)
            continue
        at = session.splice_time()
        if incoming.type == "replace":
            body = session.replace_request(incoming.request, at)
            got = await _compute(websocket, start.type, body, ["request"])
            request = incoming.request
        else:
            body = session.stop_request(request, at)
            got = await _compute(websocket, "stop", body, [])
        await websocket.send_json(session.switch(got["trajectory"], at))
