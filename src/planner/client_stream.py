"""The client of ``/v1/stream``: setpoints over a WebSocket (the ``websockets`` library; httpx
has no WebSocket), sync and async.

::

    with client.stream({"start": ..., "goal": ...}, rate_hz=1000) as session:
        for message in session:          # {"type": "setpoints" | "switched" | "done", ...}
            ...                          # session.ack(t), session.replace({...}), session.stop()

``auto_ack`` (default True) acknowledges every chunk as soon as it is read (a recorder: the
stream then runs as fast as the service computes it); a real-time consumer passes
``auto_ack=False`` and calls ``session.ack(t)`` with its own clock on the trajectory. An
``error`` message raises :class:`~planner.client_errors.InvalidRequestError` with its
``loc`` (the service then closes the socket with 1008).
"""

from __future__ import annotations

import json
from collections.abc import AsyncIterator, Iterator, Mapping
from typing import Any

from planner.client_errors import InvalidRequestError

__all__ = ["AsyncStreamSession", "StreamSession", "first_message", "stream_url"]


def stream_url(base_url: str) -> str:
    """The WebSocket URL of ``/v1/stream`` on the service at ``base_url`` (http -> ws)."""
    scheme, sep, rest = base_url.partition("://")
    ws = {"http": "ws", "https": "wss"}.get(scheme, scheme)
    return f"{ws}{sep}{rest.rstrip('/')}/v1/stream"


def _first(kind: str, request: Any, rate_hz: float, lookahead_s: float) -> str:
    body = request.model_dump(exclude_unset=True) if hasattr(request, "model_dump") else request
    return json.dumps(
        {"type": kind, "request": dict(body), "rate_hz": rate_hz, "lookahead_s": lookahead_s}
    )


def _checked(text: str | bytes) -> dict[str, Any]:
    message = json.loads(text)
    if message.get("type") == "error":
        detail = [{"loc": message.get("loc", []), "msg": message.get("msg", ""), "type": "stream"}]
        raise InvalidRequestError(f"stream: {message.get('msg')}", status_code=None, detail=detail)
    return message


def _chunk_end(message: dict[str, Any]) -> float:
    return message["t0"] + message["dt"] * (len(message["q"]) - 1)


class StreamSession:
    """A stream's messages (iterate), and what the client may send (see the module
    docstring). Made by :meth:`planner.client.PlannerClient.stream`."""

    def __init__(
        self,
        base_url: str,
        headers: Mapping[str, str],
        first: str,
        *,
        auto_ack: bool = True,
    ) -> None:
        from websockets.sync.client import connect

        self._connection = connect(stream_url(base_url), additional_headers=dict(headers))
        self._ws = self._connection.__enter__()
        self._ws.send(first)
        self.auto_ack = auto_ack

    def __enter__(self) -> StreamSession:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        self._connection.__exit__(None, None, None)

    def __iter__(self) -> Iterator[dict[str, Any]]:
        from websockets.exceptions import ConnectionClosedOK

        while True:
            try:
                message = _checked(self._ws.recv())
            except ConnectionClosedOK:
                return
            yield message
            if message["type"] == "done":
                return
            if message["type"] == "setpoints" and self.auto_ack:
                try:
                    self.ack(_chunk_end(message))
                except ConnectionClosedOK:  # the last chunk: the service closed; "done" follows
                    continue

    def receive(self, timeout: float | None = None) -> dict[str, Any] | None:
        """The next message, or None when none came within ``timeout`` s (a real-time
        consumer's loop: acknowledge its clock between messages); an ``error`` raises."""
        try:
            return _checked(self._ws.recv(timeout=timeout))
        except TimeoutError:
            return None

    def ack(self, t: float) -> None:
        """The client's clock on the trajectory reached ``t`` (s); nothing once the service
        has finished and closed the stream."""
        from websockets.exceptions import ConnectionClosedOK

        try:
            self._ws.send(json.dumps({"type": "ack", "t": float(t)}))
        except ConnectionClosedOK:
            return

    def replace(self, request: Any) -> None:
        """A new goal (a request of the stream's kind, ``start`` omitted), spliced at the next
        chunk boundary (a ``switched`` message says where)."""
        body = request.model_dump(exclude_unset=True) if hasattr(request, "model_dump") else request
        self._ws.send(json.dumps({"type": "replace", "request": dict(body)}))

    def stop(self) -> None:
        """Brake to rest from the next chunk boundary."""
        self._ws.send(json.dumps({"type": "stop"}))


class AsyncStreamSession:
    """:class:`StreamSession` for asyncio (``async with``, ``async for``, awaited sends)."""

    def __init__(
        self, base_url: str, headers: Mapping[str, str], first: str, *, auto_ack: bool = True
    ) -> None:
        self._url, self._headers, self._first = stream_url(base_url), dict(headers), first
        self.auto_ack = auto_ack
        self._ws: Any = None

    async def __aenter__(self) -> AsyncStreamSession:
        from websockets.asyncio.client import connect

        self._ws = await connect(self._url, additional_headers=self._headers)
        await self._ws.send(self._first)
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self._ws.close()

    async def __aiter__(self) -> AsyncIterator[dict[str, Any]]:
        from websockets.exceptions import ConnectionClosedOK

        while True:
            try:
                message = _checked(await self._ws.recv())
            except ConnectionClosedOK:
                return
            yield message
            if message["type"] == "done":
                return
            if message["type"] == "setpoints" and self.auto_ack:
                try:
                    await self.ack(_chunk_end(message))
                except ConnectionClosedOK:  # the last chunk: the service closed; "done" follows
                    continue

    async def ack(self, t: float) -> None:
        await self._ws.send(json.dumps({"type": "ack", "t": float(t)}))

    async def replace(self, request: Any) -> None:
        body = request.model_dump(exclude_unset=True) if hasattr(request, "model_dump") else request
        await self._ws.send(json.dumps({"type": "replace", "request": dict(body)}))

    async def stop(self) -> None:
        await self._ws.send(json.dumps({"type": "stop"}))


def first_message(
    kind: str | None, request: Any, rate_hz: float | None, lookahead_s: float | None
) -> str:
    """The opening message of a stream (``{"type", "request", "rate_hz", "lookahead_s"}``);
    None means absent, as everywhere in the client: the defaults ``"plan"``, 1000 Hz and
    0.05 s."""
    kind = "plan" if kind is None else kind
    rate_hz = 1000.0 if rate_hz is None else rate_hz
    lookahead_s = 0.05 if lookahead_s is None else lookahead_s
    if kind not in ("plan", "sequence"):
        raise InvalidRequestError(
            f"stream: kind must be 'plan' or 'sequence', got {kind!r}", status_code=None
        )
    return _first(kind, request, rate_hz, lookahead_s)
