"""ASGI middleware: the request gate (size, API key, content type, body reading in bounded
time, the request's deadline) and the observer (request id, metrics, the access log).

Pure ASGI (no ``BaseHTTPMiddleware``). :class:`RequestGate` checks, in this order, before the
application parses anything:

0. **host**: a ``Host`` header (its port stripped) that names no allowed host
   (``PLANNER_ALLOWED_HOSTS``) is 400 ``host_not_allowed``, whatever the path but the probes
   ``/v1/health`` and ``/v1/ready`` (a load balancer or a kubelet probes a replica by its IP
   address, which no deployment lists); a set lookup;
1. **size**: a ``Content-Length`` over ``max_body_bytes`` is 413 at once; a streamed body is
   cut off (413) as soon as it passes the limit;
2. **auth**: without an accepted key (when keys are configured: ``PLANNER_API_KEY``, or a
   tenant's of ``PLANNER_API_KEYS``, :mod:`planner_api.tenants`), every ``/v1`` route but
   the probes ``/v1/health`` and ``/v1/ready`` is 401, whatever the body holds;
3. **content type**: a POST to a ``/v1`` route whose ``Content-Type`` is not JSON is 415
   (a method the route does not take is left to routing: 405);
4. **body in bounded time**: the whole body must arrive within ``body_timeout_s`` (at most the
   request's budget), else 408 and the connection is closed, so a client that stalls cannot
   hold a connection;
5. then FastAPI parses the JSON and validates the schema (422); or, for a hot route whose
   path the route table already knows, the route's direct answer, called here with the body
   read (:func:`planner_api.routes.direct.index_routes`, "The front door's direct answer"),
   which declines what is not the plain case back to the application's own path.

Without the host check, a keyless service on a user's machine answers any web page that makes
its own name resolve to 127.0.0.1 (DNS rebinding): the browser sends that page's name as the
Host. :class:`RequestObserver` also makes every redirect relative (Starlette's trailing-slash
redirect and the static files' directory redirect build an absolute ``location`` from the
Host header): a redirect never sends a client to a host the request named.

It also stamps ``scope["state"]["deadline"]`` (a :func:`time.monotonic` value) when the
request arrives, which the worker pool honours.

Why not ``FastAPI(max_body_size=...)``: it answers an oversized ``Content-Length`` with a
plain-text 413, outside the exception handlers, so not in the service's ``detail`` format.
"""

from __future__ import annotations

import asyncio
import json
import logging
import time
from collections.abc import Callable, Mapping
from typing import Any

from starlette.routing import Match
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from planner_api.logging import REQUEST_ID, REQUEST_ID_HEADER, request_id_from
from planner_api.metrics import CURRENT, UNMATCHED, Metrics
from planner_api.tenants import tenant_of

__all__ = [
    "API_KEY_REQUIRED",
    "CLIENT_CLOSED_REQUEST",
    "HOST_NOT_ALLOWED",
    "RequestGate",
    "RequestObserver",
    "host_name",
    "relative_location",
]

access_logger = logging.getLogger("api.access")

#: Status recorded (never sent) when the client went away before the answer: nginx's 499.
CLIENT_CLOSED_REQUEST = 499
#: Paths that never need the API key (liveness and readiness, for probes).
_OPEN_PATHS = frozenset({"/v1/health", "/v1/ready"})
_BODY_METHODS = frozenset({"POST", "PUT", "PATCH"})


#: The 401's message, the gate's and the routes' alike.
API_KEY_REQUIRED = "a valid API key is required (X-API-Key or Authorization: Bearer)"


#: The 400's message when the Host names no allowed host (followed by the name).
HOST_NOT_ALLOWED = "the Host header names no host this service answers (PLANNER_ALLOWED_HOSTS)"


def host_name(value: str) -> str:
    """A ``Host`` header's host name as :func:`planner_api.settings.parse_allowed_hosts`
    writes the allowed ones: lower case, its port stripped (an IPv6 address kept in its
    brackets), without a final dot."""
    value = value.strip().lower()
    if value.startswith("["):
        return value[: value.find("]") + 1] if "]" in value else value
    return value.partition(":")[0].rstrip(".")


#: How many (method, path) answers of :func:`_route_takes` are remembered per application.
_ROUTE_CACHE_SIZE = 1024


def _route_takes(scope: Scope) -> bool:
    """Whether a route of the app takes this path with this method (else routing answers
    404 or 405, which the content type must not pre-empt). Remembered per application for
    the last :data:`_ROUTE_CACHE_SIZE` (method, path) pairs: matching every route's pattern
    is a tenth of the cheapest request's cost."""
    app = scope.get("app")
    router = getattr(app, "router", None)
    cache = getattr(router, "_planner_takes", None)
    if cache is None:
        cache = {}
        if router is not None:
            router._planner_takes = cache
    key = (scope.get("method"), scope.get("path"))
    found = cache.get(key)
    if found is None:
        found = any(
            route.matches(scope)[0] is Match.FULL for route in getattr(router, "routes", ())
        )
        if len(cache) >= _ROUTE_CACHE_SIZE:
            cache.pop(next(iter(cache)))
        cache[key] = found
    return found


def _direct_answer_of(scope: Scope) -> Callable[[Scope, Receive, Send, bytes], Any] | None:
    """The route's direct answer of this (method, path), if the application keeps one
    (``app.state.direct_answers``: :func:`planner_api.routes.direct.index_routes`), which
    answers the request without the layers between this gate and the route."""
    answers = getattr(getattr(scope.get("app"), "state", None), "direct_answers", None)
    if not answers:
        return None
    return answers.get((scope.get("method"), scope.get("path")))


def _is_json(content_type: str) -> bool:
    media = content_type.split(";", 1)[0].strip().lower()
    return media == "application/json" or (
        media.startswith("application/") and media.endswith("+json")
    )


class RequestGate:
    """The checks before the application (see the module docstring), in their order."""

    def __init__(
        self,
        app: ASGIApp,
        *,
        max_body_bytes: int,
        timeout_s: float,
        body_timeout_s: float,
        api_key: str | None = None,
        api_keys: Mapping[str, str] | None = None,
        allowed_hosts: frozenset[str] | None = None,
    ) -> None:
        self.app = app
        self.max_body_bytes = max_body_bytes
        self.timeout_s = timeout_s
        self.body_timeout_s = min(body_timeout_s, timeout_s)
        # every accepted key -> its tenant (planner_api.tenants); None: no key asked
        if api_keys is None and api_key is not None:
            api_keys = {api_key: "default"}
        self.api_keys = dict(api_keys) if api_keys is not None else None
        #: None: any host (``PLANNER_ALLOWED_HOSTS=*``, or the default of a keyed service)
        self.allowed_hosts = allowed_hosts

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        arrival = time.monotonic()
        scope.setdefault("state", {})["deadline"] = arrival + self.timeout_s
        headers = {k.decode("latin-1"): v.decode("latin-1") for k, v in scope.get("headers", ())}
        path = scope.get("path", "")
        if self.allowed_hosts is not None and path not in _OPEN_PATHS:
            host = host_name(headers.get("host", ""))
            if host not in self.allowed_hosts:
                shown = repr(host[:100]) if host else "none was given"
                await _answer(
                    send,
                    400,
                    f"{HOST_NOT_ALLOWED}: {shown}",
                    "host_not_allowed",
                    ["header", "host"],
                )
                return
        try:
            too_large = int(headers.get("content-length", "0")) > self.max_body_bytes
        except ValueError:
            too_large = False
        if too_large:
            await self._too_large(send)
            return
        guarded = path.startswith("/v1/") and path not in _OPEN_PATHS
        if guarded and self.api_keys is not None:
            if tenant_of(headers, self.api_keys) is None:
                await _answer(
                    send,
                    401,
                    API_KEY_REQUIRED,
                    "unauthorized",
                    [],
                    [(b"www-authenticate", b"Bearer")],
                )
                return
        if guarded and scope.get("method") in _BODY_METHODS and _route_takes(scope):
            content_type = headers.get("content-type", "")
            if not _is_json(content_type):
                got = f"got {content_type!r}" if content_type else "none was given"
                await _answer(
                    send,
                    415,
                    f"the body must be JSON: send Content-Type: application/json ({got})",
                    "unsupported_media_type",
                    ["header", "content-type"],
                )
                return
        chunks: list[bytes] = []
        outcome = ""  # why the body is not there: "timeout", "too_large" or "disconnect"
        try:
            # one timer for the whole body (not a task per chunk, as asyncio.wait_for makes)
            async with asyncio.timeout(arrival + self.body_timeout_s - time.monotonic()):
                size = 0
                while True:
                    message = await receive()
                    if message["type"] == "http.disconnect":
                        outcome = "disconnect"
                        break
                    body = message.get("body", b"")
                    size += len(body)
                    if size > self.max_body_bytes:
                        outcome = "too_large"
                        break
                    chunks.append(body)
                    if not message.get("more_body", False):
                        break
        except TimeoutError:
            outcome = "timeout"
        if outcome == "timeout":
            await _answer(
                send,
                408,
                f"the request body did not arrive within {self.body_timeout_s:g} s",
                "body_timeout",
                ["body"],
                [(b"connection", b"close")],
            )
            return
        if outcome == "too_large":
            await self._too_large(send)
            return
        if outcome == "disconnect":
            return  # the observer records 499: nobody is left to answer
        body = chunks[0] if len(chunks) == 1 else b"".join(chunks)
        direct = _direct_answer_of(scope)
        if direct is not None and await direct(scope, receive, send, body):
            return
        buffered: Message | None = {"type": "http.request", "body": body, "more_body": False}

        async def replay() -> Message:
            nonlocal buffered
            if buffered is not None:
                message, buffered = buffered, None
                return message
            return await receive()

        await self.app(scope, replay, send)

    async def _too_large(self, send: Send) -> None:
        await _answer(
            send,
            413,
            f"the request body exceeds {self.max_body_bytes} bytes",
            "body_too_large",
            ["body"],
            [(b"connection", b"close")],
        )


async def _answer(
    send: Send,
    status: int,
    msg: str,
    type_: str,
    loc: list[str],
    headers: list[tuple[bytes, bytes]] = (),  # type: ignore[assignment]
) -> None:
    """An error answer in the service's ``detail`` format, sent before the application."""
    body = json.dumps({"detail": [{"loc": loc, "msg": msg, "type": type_}]}).encode()
    await send(
        {
            "type": "http.response.start",
            "status": status,
            "headers": [
                (b"content-type", b"application/json"),
                (b"content-length", str(len(body)).encode()),
                *headers,
            ],
        }
    )
    await send({"type": "http.response.body", "body": body})


#: Paths whose access-log line is written at DEBUG (probes and scrapes every few seconds).
_QUIET_PATHS = frozenset({"/v1/health", "/v1/ready", "/metrics"})


def _route_label(scope: Scope) -> str:
    """The matched route's path template, else the path if it is one of the app's documented
    paths (a 413 answered before routing), else :data:`planner_api.metrics.UNMATCHED`."""
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


#: Headers every answer carries unless its route set its own (the viewer's page and the API
#: documentation pages set a Content-Security-Policy for what they load): no MIME sniffing,
#: no referrer, and a policy that loads nothing and may be framed by no one (a JSON answer,
#: a script or a style sheet needs no more). ``X-Frame-Options: DENY`` says "framed by no one"
#: to the browsers and proxies that do not read the policy's ``frame-ancestors``, also on the
#: pages with their own policy (which keep ``frame-ancestors 'none'``).
SECURITY_HEADERS: tuple[tuple[bytes, bytes], ...] = (
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"no-referrer"),
    (b"x-frame-options", b"DENY"),
    (b"content-security-policy", b"default-src 'none'; frame-ancestors 'none'"),
)


_CONNECTION_CLOSE = (b"connection", b"close")


def relative_location(location: bytes, host: bytes | None) -> bytes:
    """A redirect's ``location`` without the scheme and host the application built from the
    request's ``Host`` header (``http://<host>/v1/plan`` -> ``/v1/plan``; without a Host
    header, from the server's address: any absolute one), another location unchanged. A path
    starting ``//`` (a host to a browser) keeps one slash."""
    scheme, sep, rest = location.partition(b"://")
    if not sep or scheme.lower() not in (b"http", b"https"):
        return location
    netloc, _, tail = rest.partition(b"/")
    if host is not None and netloc.lower() != host.strip().lower():
        return location
    return b"/" + tail.lstrip(b"/")


def _access_line(
    level: int, method: str, path: str, route: str, status: int, seconds: float, scope: Scope
) -> None:
    """One access-log line (the caller checked that ``level`` is logged). The record is made
    and handled directly: ``Logger.log`` would also look up the calling frame (a stack walk
    per request) for a file name and line number that neither log format writes."""
    extra = {
        "method": method,
        "path": path,
        "route": route,
        "status": status,
        "duration_ms": round(seconds * 1000.0, 3),
        "client": (scope.get("client") or ("", 0))[0],
    }
    record = access_logger.makeRecord(
        access_logger.name, level, "", 0, "%s %s %d", (method, path, status), None, extra=extra
    )
    access_logger.handle(record)


class RequestObserver:
    """The outermost middleware: gives the request its id (the client's ``X-Request-ID`` when
    sane, else a new one; echoed in the answer and set in :data:`planner_api.logging.REQUEST_ID` for
    every log line), adds :data:`SECURITY_HEADERS` where the route set none, records it in
    ``metrics`` and writes one access-log line. While ``stopping()`` (the drain after a
    SIGTERM, :mod:`planner_api.server`) every answer carries ``Connection: close``, so that
    keep-alive clients reconnect, through their load balancer, to another replica."""

    def __init__(
        self, app: ASGIApp, *, metrics: Metrics, stopping: Callable[[], bool] = lambda: False
    ) -> None:
        self.app = app
        self.metrics = metrics
        self.stopping = stopping
        self._header = REQUEST_ID_HEADER.lower().encode()

    @staticmethod
    def _relative(scope: Scope, headers: list[tuple[bytes, bytes]]) -> list[tuple[bytes, bytes]]:
        host = next((v for k, v in scope.get("headers", ()) if k == b"host"), None)
        return [
            (k, relative_location(v, host) if k.lower() == b"location" else v) for k, v in headers
        ]

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        given = next((v for k, v in scope.get("headers", ()) if k == self._header), None)
        request_id = request_id_from(given)
        id_token = REQUEST_ID.set(request_id)
        metrics_token = CURRENT.set(self.metrics)
        start = time.perf_counter()
        status: int | None = None
        self.metrics.in_progress.inc()

        async def send_with_id(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
                headers = [(k, v) for k, v in message.get("headers", ()) if k != self._header]
                headers.append((self._header, request_id.encode()))
                present = {k.lower() for k, _ in headers}
                headers += [(k, v) for k, v in SECURITY_HEADERS if k not in present]
                if 300 <= status < 400:
                    headers = self._relative(scope, headers)
                if self.stopping():
                    headers.append(_CONNECTION_CLOSE)
                message = {**message, "headers": headers}
            await send(message)

        try:
            await self.app(scope, receive, send_with_id)
        except BaseException:
            status = status or 500
            raise
        finally:
            # no answer started and no error: the client went away first (499, not a 5xx)
            status = CLIENT_CLOSED_REQUEST if status is None else status
            seconds = time.perf_counter() - start
            self.metrics.in_progress.dec()
            route = _route_label(scope)
            method = scope.get("method", "")
            self.metrics.record_request(method, route, status, seconds)
            path = scope.get("path", "")
            # probes every few seconds, also their 503s while the workers warm up
            quiet = path in _QUIET_PATHS and (status < 400 or status == 503)
            level = logging.DEBUG if quiet else logging.INFO
            if access_logger.isEnabledFor(level):
                _access_line(level, method, path, route, status, seconds, scope)
            CURRENT.reset(metrics_token)
            REQUEST_ID.reset(id_token)
