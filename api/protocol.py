"""uvicorn's HTTP/1.1 protocol with the two timeouts it lacks: a header timeout and a send
timeout, so that neither a client that sends its headers slowly nor one that never reads its
answer holds a connection (and the answer's bytes) for longer than a setting says.

uvicorn bounds the idle time between two requests of a keep-alive connection
(``timeout_keep_alive``) but cancels that timer on the first byte of the next request, and it
has no bound on the time the request line and headers take (uvicorn issue #157,
"--timeout-request-start"). ASGI middleware cannot help: an application is only called once
the headers are complete. So the bound lives in the protocol:

- **Header timeout.** A timer is armed when a connection opens and again each time an answer
  is complete (the connection waits for the next request). When it fires while no request is
  being served (no request yet, or the last one answered), the request line and headers have
  not arrived in time: the connection is answered 408 ``header_timeout`` and closed. A request
  whose headers arrived is never cut by it (its body has ``PLANNER_BODY_TIMEOUT_S``, checked
  by :class:`planner_api.middleware.RequestGate`; its work has the request's budget).
- **Send timeout.** When the transport's write buffer passes its high-water mark (the client
  reads more slowly than the service writes), a timer is armed; the transport resuming
  writing (the buffer drained below its low-water mark) cancels it. When it fires, the client
  has not taken the answer in time: the connection is aborted with a TCP reset, which drops
  the buffered bytes at once, the transport's and the kernel's (``SO_LINGER`` 0, then
  ``transport.abort()``; ``close()`` would keep them until they are sent, and ``abort()``
  alone still lets the kernel send its buffer and a clean FIN), so the client sees a reset,
  never what looks like the end of an answer.

:func:`guarded_protocol` makes the class uvicorn is given: the timers of :class:`_Guard` mixed
into uvicorn's httptools protocol (the default of ``uvicorn[standard]``) or its h11 one; on
the httptools one, an answer's head is also written with its body in one write
(:class:`_HeadWithBody`).
"""

from __future__ import annotations

import asyncio
import importlib.util
import json
import logging
import socket
import struct
from typing import Any

from uvicorn.protocols.http.h11_impl import H11Protocol

__all__ = ["guarded_protocol"]

logger = logging.getLogger(__name__)

_HEADER_TIMEOUT_BODY = json.dumps(
    {
        "detail": [
            {
                "loc": ["header"],
                "msg": "the request line and headers did not arrive in time",
                "type": "header_timeout",
            }
        ]
    }
).encode()
_HEADER_TIMEOUT_ANSWER = (
    b"HTTP/1.1 408 Request Timeout\r\n"
    b"content-type: application/json\r\n"
    b"content-length: " + str(len(_HEADER_TIMEOUT_BODY)).encode() + b"\r\n"
    b"connection: close\r\n\r\n" + _HEADER_TIMEOUT_BODY
)


class _Guard:
    """The two timers, mixed into a uvicorn HTTP protocol class (which provides ``loop``,
    ``transport``, ``cycle``, ``client`` and the methods overridden here)."""

    header_timeout_s: float = 10.0
    send_timeout_s: float = 30.0
    loop: asyncio.AbstractEventLoop
    transport: asyncio.Transport
    cycle: Any
    client: Any
    _header_timer: asyncio.TimerHandle | None = None
    _send_timer: asyncio.TimerHandle | None = None

    def _arm_header_timer(self) -> None:
        if self._header_timer is not None:
            self._header_timer.cancel()
        self._header_timer = self.loop.call_later(self.header_timeout_s, self._header_timeout)

    def _header_timeout(self) -> None:
        self._header_timer = None
        transport = self.transport
        if transport is None or transport.is_closing():
            return
        if self.cycle is not None and not self.cycle.response_complete:
            return  # a request is being served: its headers arrived
        logger.info(
            "closing a connection whose request headers did not arrive within %g s (%s)",
            self.header_timeout_s,
            _peer(self.client),
        )
        transport.write(_HEADER_TIMEOUT_ANSWER)
        transport.close()
        # a client that sends nothing may read nothing either: the send timer bounds the close
        self._arm_send_timer()

    def _arm_send_timer(self) -> None:
        if self._send_timer is None:
            self._send_timer = self.loop.call_later(self.send_timeout_s, self._send_timeout)

    def _disarm_send_timer(self) -> None:
        if self._send_timer is not None:
            self._send_timer.cancel()
            self._send_timer = None

    def _send_timeout(self) -> None:
        self._send_timer = None
        transport = self.transport
        if transport is None:
            return
        logger.warning(
            "aborting a connection whose client did not take %d buffered bytes within %g s (%s)",
            transport.get_write_buffer_size(),
            self.send_timeout_s,
            _peer(self.client),
        )
        _reset(transport)

    # the protocol's hooks
    def connection_made(self, transport: asyncio.Transport) -> None:
        super().connection_made(transport)  # type: ignore[misc]
        self._arm_header_timer()

    def connection_lost(self, exc: Exception | None) -> None:
        for timer in (self._header_timer, self._send_timer):
            if timer is not None:
                timer.cancel()
        self._header_timer = self._send_timer = None
        super().connection_lost(exc)  # type: ignore[misc]

    def on_response_complete(self) -> None:
        self._arm_header_timer()  # the connection now waits for its next request's headers
        super().on_response_complete()  # type: ignore[misc]

    def pause_writing(self) -> None:
        self._arm_send_timer()
        super().pause_writing()  # type: ignore[misc]

    def resume_writing(self) -> None:
        self._disarm_send_timer()
        super().resume_writing()  # type: ignore[misc]


#: The bytes uvicorn writes to ask for a body (``Expect: 100-continue``): never held.
_CONTINUE = b"HTTP/1.1 100 Continue\r\n\r\n"
#: A body up to this size is joined to its held head (one copy); a larger one follows it.
_JOIN_MAX = 1 << 16


class _HeadWithBody:
    """A request cycle's transport that holds the answer's status line and headers until
    its first body bytes and writes both at once.

    uvicorn writes an answer's head and its body with one ``transport.write`` each, and each
    is a ``send()`` to the client, which on loopback or a LAN wakes the client twice for one
    answer (it reads the head, then waits for the body): two system calls and two wake-ups
    where one does. The head is held only while the task that wrote it runs: the body of a
    plain answer follows in the same step, and a streamed answer whose first chunk is late
    gets its head sent on the loop's next turn (``call_soon``). Everything else (the 100
    Continue, ``close``, ``is_closing``) is the transport's own."""

    __slots__ = ("_done", "_held", "_loop", "_transport")

    def __init__(self, transport: asyncio.Transport, loop: asyncio.AbstractEventLoop) -> None:
        self._transport = transport
        self._loop = loop
        self._held: bytes | None = None
        self._done = False  # the head is out: every write is the transport's

    def write(self, data: bytes) -> None:
        if self._done or data == _CONTINUE:
            self._transport.write(data)
        elif self._held is None:
            self._held = data
            self._loop.call_soon(self._flush)
        else:
            held, self._held, self._done = self._held, None, True
            if len(data) <= _JOIN_MAX:
                self._transport.write(held + data)
            else:
                self._transport.write(held)
                self._transport.write(data)

    def _flush(self) -> None:
        if self._held is not None:
            held, self._held, self._done = self._held, None, True
            if not self._transport.is_closing():
                self._transport.write(held)

    def close(self) -> None:
        self._flush()
        self._transport.close()

    def is_closing(self) -> bool:
        return self._transport.is_closing()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._transport, name)


class _OneWrite:
    """Mixed into uvicorn's httptools protocol: each request's cycle writes through a
    :class:`_HeadWithBody`."""

    transport: asyncio.Transport
    loop: asyncio.AbstractEventLoop
    cycle: Any

    def on_headers_complete(self) -> None:
        super().on_headers_complete()  # type: ignore[misc]
        cycle = self.cycle
        if cycle is not None and cycle.transport is self.transport:
            cycle.transport = _HeadWithBody(self.transport, self.loop)


def _reset(transport: asyncio.Transport) -> None:
    """Abort ``transport`` with a TCP reset: ``abort()`` drops the bytes the transport still
    buffers, but the kernel would send the ones already in its socket buffer (megabytes)
    and then a clean FIN, which a client reading a chunked answer, or one that ignores
    Content-Length, takes for a complete answer. ``SO_LINGER`` with a zero timeout makes
    the close discard them and send RST: the client learns that the answer was cut."""
    sock = transport.get_extra_info("socket")
    if sock is not None:
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        except OSError:  # pragma: no cover - the socket closed meanwhile
            pass
    transport.abort()


def _peer(client: Any) -> str:
    return f"{client[0]}:{client[1]}" if client else "unknown client"


if importlib.util.find_spec("httptools") is not None:
    from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

    _DEFAULT: type[asyncio.Protocol] = HttpToolsProtocol
else:  # pragma: no cover - uvicorn without its [standard] extra
    _DEFAULT = H11Protocol


def guarded_protocol(
    header_timeout_s: float,
    send_timeout_s: float,
    base: type[asyncio.Protocol] | None = None,
) -> type[asyncio.Protocol]:
    """The protocol class to give uvicorn (``uvicorn.Config(http=...)``): uvicorn's protocol
    ``base`` (default: its httptools one when httptools is installed, as uvicorn's ``auto``
    picks, else its h11 one) with the two timers and these timeouts, s."""
    base = base or _DEFAULT
    # the head written with the body where the protocol makes a cycle per request's headers
    # (httptools'; h11's writes through its own connection object)
    mixins = (_Guard, _OneWrite) if hasattr(base, "on_headers_complete") else (_Guard,)
    return type(
        f"Guarded{base.__name__}",
        (*mixins, base),
        {"header_timeout_s": header_timeout_s, "send_timeout_s": send_timeout_s},
    )
