"""WebSocket /v1/stream: a plan or sequence answer streamed as chunks of setpoints, paced by
the client's acknowledgements, with replacements and stops computed while the stream goes on
and spliced at a chunk boundary ahead of it (the rules: :mod:`planner.endpoints.stream`).

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
import math
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


async def _receive(websocket: WebSocket) -> Any:
    text = await websocket.receive_text()
    try:
        return json.loads(text)
    except ValueError as exc:
        raise StreamError([], f"a message must be JSON: {exc}") from exc


async def _timed(compute: Any) -> tuple[dict, float]:
    """The answer of ``compute`` (an awaitable) and its wall time, s."""
    began = time.monotonic()
    answer = await compute
    return answer, time.monotonic() - began


class _Splice:
    """A replacement or stop being computed while the stream goes on: its message, its
    splice time, the tries so far and the task computing it."""

    def __init__(
        self, websocket: WebSocket, session: StreamSession, incoming: Any, kind: str, request: dict
    ) -> None:
        self.websocket, self.session, self.incoming = websocket, session, incoming
        self.kind, self.request = kind, request  # the stream's kind, its current request
        self.tries = 0
        self.launch()

    def launch(self) -> None:
        """Plan from a splice time ahead of the horizon (see the endpoint's docstring); the
        last try holds the stream at it."""
        session, incoming = self.session, self.incoming
        self.tries += 1
        self.at = session.splice_time(session.margin(incoming.type))
        self.until = self.at if self.tries >= jobs.REPLANS else math.inf
        session.holding = True
        if incoming.type == "replace":
            body = session.replace_request(incoming.request, self.at)
            kind, loc = self.kind, ["request"]
        else:
            kind, body, loc = "stop", session.stop_request(self.request, self.at), []
        self.task = asyncio.ensure_future(_timed(_compute(self.websocket, kind, body, loc)))


async def _serve(websocket: WebSocket) -> None:
    idle = websocket.app.state.settings.request_timeout_s
    try:
        first = await asyncio.wait_for(_receive(websocket), idle)
    except TimeoutError as exc:
        raise StreamError([], f"no message for {idle:g} s: the stream is closed") from exc
    start = _validated(StreamStart, first, [])
    request = {**start.request}
    request["timing"] = {**request.get("timing", {}), "sample_rate_hz": start.rate_hz}
    answer, seconds = await _timed(_compute(websocket, start.type, request, ["request"]))
    session = StreamSession(answer["trajectory"], start.rate_hz, start.lookahead_s)
    session.plan_s = seconds
    reading = asyncio.ensure_future(_receive(websocket))
    splice: _Splice | None = None
    queued: list[Any] = []  # replaces and stops waiting for the one being computed
    try:
        while True:
            for message in session.pending(splice.until if splice else math.inf):
                await websocket.send_json(message)
            if session.finished:
                await websocket.close()
                return
            waits = {reading} if splice is None else {reading, splice.task}
            done, _ = await asyncio.wait(waits, timeout=idle, return_when=asyncio.FIRST_COMPLETED)
            if not done:
                raise StreamError([], f"no message for {idle:g} s: the stream is closed")
            if splice is not None and splice.task in done:
                got, seconds = splice.task.result()
                if splice.incoming.type == "stop":
                    session.stop_s = seconds
                else:
                    session.plan_s = seconds
                if session.too_late(splice.at):
                    splice.launch()  # its splice time was streamed: plan from a later one
                else:
                    if splice.incoming.type == "replace":
                        request = splice.incoming.request
                    await websocket.send_json(session.switch(got["trajectory"], splice.at))
                    splice = (
                        _Splice(websocket, session, queued.pop(0), start.type, request)
                        if queued
                        else None
                    )
            if reading in done:
                incoming = _validated(_MESSAGE, reading.result(), [])
                reading = asyncio.ensure_future(_receive(websocket))
                if incoming.type == "ack":
                    session.acknowledge(incoming.t)
                elif splice is None:
                    splice = _Splice(websocket, session, incoming, start.type, request)
                else:
                    queued.append(incoming)
    finally:
        reading.cancel()
        if splice is not None:  # let its job finish (cancelling would kill the worker)
            splice.task.add_done_callback(_discard)


def _discard(task: asyncio.Future) -> None:
    """Retrieve an abandoned computation's outcome (so asyncio does not log it)."""
    if not task.cancelled():
        task.exception()
