"""ASGI middleware: request size limit and the request's deadline; request id, metrics and
the access log (:class:`RequestObserver`).

Pure ASGI (no ``BaseHTTPMiddleware``): it reads the body up to ``max_body_bytes`` before the
application sees it, answering 413 beyond (whether the client sent ``Content-Length`` or
streamed the body in chunks), and stamps ``scope["state"]["deadline"]`` (a
:func:`time.monotonic` value) when the request arrives, which the worker pool honours.

Why not ``FastAPI(max_body_size=...)``: it answers an oversized ``Content-Length`` with a
plain-text 413, outside the exception handlers, so not in the service's ``detail`` format.
"""

from __future__ import annotations

import json
import logging
import time

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from api.logging import REQUEST_ID, REQUEST_ID_HEADER, request_id_from
from api.metrics import CURRENT, UNMATCHED, Metrics

__all__ = ["RequestLimitsMiddleware", "RequestObserver"]

access_logger = logging.getLogger("api.access")


class RequestLimitsMiddleware:
    """Enforce ``max_body_bytes`` and stamp the deadline ``timeout_s`` after arrival."""

    def __init__(self, app: ASGIApp, *, max_body_bytes: int, timeout_s: float) -> None:
        self.app = app
        self.max_body_bytes = max_body_bytes
        self.timeout_s = timeout_s

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        scope.setdefault("state", {})["deadline"] = time.monotonic() + self.timeout_s
        for name, value in scope.get("headers", ()):
            if name == b"content-length":
                try:
                    too_large = int(value) > self.max_body_bytes
                except ValueError:
                    too_large = False
                if too_large:
                    await self._too_large(send)
                    return
        chunks: list[bytes] = []
        size = 0
        while True:
            message = await receive()
            if message["type"] == "http.disconnect":
                return
            body = message.get("body", b"")
            size += len(body)
            if size > self.max_body_bytes:
                await self._too_large(send)
                return
            chunks.append(body)
            if not message.get("more_body", False):
                break
        buffered: Message | None = {
            "type": "http.request",
            "body": b"".join(chunks),
            "more_body": False,
        }

        async def replay() -> Message:
            nonlocal buffered
            if buffered is not None:
                message, buffered = buffered, None
                return message
            return await receive()

        await self.app(scope, replay, send)

    async def _too_large(self, send: Send) -> None:
        body = json.dumps(
            {
                "detail": [
                    {
                        "loc": ["body"],
                        "msg": f"the request body exceeds {self.max_body_bytes} bytes",
                        "type": "body_too_large",
                    }
                ]
            }
        ).encode()
        await send(
            {
                "type": "http.response.start",
                "status": 413,
                "headers": [
                    (b"content-type", b"application/json"),
                    (b"content-length", str(len(body)).encode()),
                    (b"connection", b"close"),
                ],
            }
        )
        await send({"type": "http.response.body", "body": body})


#: Paths whose access-log line is written at DEBUG (probes and scrapes every few seconds).
_QUIET_PATHS = frozenset({"/v1/health", "/v1/ready", "/metrics"})


def _route_label(scope: Scope) -> str:
    """The matched route's path template, else the path if it is one of the app's documented
    paths (a 413 answered before routing), else :data:`api.metrics.UNMATCHED`."""
    route = scope.get("route")
    path = getattr(route, "path", None)
    if isinstance(path, str):
        return path
    app = scope.get("app")
    raw = scope.get("path", "")
    openapi = getattr(app, "openapi", None)
    if callable(openapi):
        try:
            if raw in openapi().get("paths", {}):  # cached by FastAPI after the first call
                return raw
        except Exception:  # pragma: no cover - a broken schema must not break the answer
            logging.getLogger(__name__).exception("could not read the OpenAPI paths")
    return UNMATCHED


class RequestObserver:
    """The outermost middleware: gives the request its id (the client's ``X-Request-ID`` when
    sane, else a new one; echoed in the answer and set in :data:`api.logging.REQUEST_ID` for
    every log line), records it in ``metrics`` and writes one access-log line."""

    def __init__(self, app: ASGIApp, *, metrics: Metrics) -> None:
        self.app = app
        self.metrics = metrics
        self._header = REQUEST_ID_HEADER.lower().encode()

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        given = next((v for k, v in scope.get("headers", ()) if k == self._header), None)
        request_id = request_id_from(given)
        id_token = REQUEST_ID.set(request_id)
        metrics_token = CURRENT.set(self.metrics)
        start = time.perf_counter()
        status = 500  # if the app raises before answering
        self.metrics.in_progress.inc()

        async def send_with_id(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
                headers = [(k, v) for k, v in message.get("headers", ()) if k != self._header]
                headers.append((self._header, request_id.encode()))
                message = {**message, "headers": headers}
            await send(message)

        try:
            await self.app(scope, receive, send_with_id)
        finally:
            seconds = time.perf_counter() - start
            self.metrics.in_progress.dec()
            route = _route_label(scope)
            method = scope.get("method", "")
            self.metrics.record_request(method, route, status, seconds)
            path = scope.get("path", "")
            access_logger.log(
                logging.DEBUG if path in _QUIET_PATHS and status < 400 else logging.INFO,
                "%s %s %d",
                method,
                path,
                status,
                extra={
                    "method": method,
                    "path": path,
                    "route": route,
                    "status": status,
                    "duration_ms": round(seconds * 1000.0, 3),
                    "client": (scope.get("client") or ("", 0))[0],
                },
            )
            CURRENT.reset(metrics_token)
            REQUEST_ID.reset(id_token)
