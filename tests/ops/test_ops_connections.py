"""The connection timeouts of :mod:`planner_api.protocol` on real sockets: a client that sends
its headers slowly (or not at all) is answered 408 and closed after the header timeout, one
whose headers arrived is never cut by it, and a client that does not read its answer has its
connection aborted after the send timeout, its buffered bytes dropped.

Each protocol class (httptools, the default, and h11) is served by uvicorn in a thread with a
small ASGI app, so the timeouts can be a fraction of a second; the service itself, with its
settings, is tested in ``tests/ops/test_ops_slow_clients.py``. The oracle is the socket: what the
client reads, and when the server closes it."""

from __future__ import annotations

import asyncio
import socket
import threading
import time
from collections.abc import Iterator

import pytest
import uvicorn
from uvicorn.protocols.http.h11_impl import H11Protocol
from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

from planner_api.protocol import guarded_protocol

HEADER_TIMEOUT_S = 0.6
SEND_TIMEOUT_S = 0.8
BIG = 8 * 1024 * 1024  # far beyond what the kernel's socket buffers hold
PARTIAL = b"POST /slow HTTP/1.1\r\nHost: x\r\nContent-Ty"


async def _app(scope, receive, send) -> None:  # type: ignore[no-untyped-def]
    """``/big``: BIG bytes in one write; ``/slow``: answers after 2 header timeouts; else 'ok'."""
    if scope["type"] != "http":
        return
    while (await receive()).get("more_body"):
        pass
    if scope["path"] == "/slow":
        await asyncio.sleep(2 * HEADER_TIMEOUT_S)
    body = b"x" * BIG if scope["path"] == "/big" else b"ok"
    await send(
        {
            "type": "http.response.start",
            "status": 200,
            "headers": [(b"content-length", str(len(body)).encode())],
        }
    )
    await send({"type": "http.response.body", "body": body})


class _Served:
    def __init__(self, base: type) -> None:
        protocol = guarded_protocol(HEADER_TIMEOUT_S, SEND_TIMEOUT_S, base)
        # log_config=None: uvicorn leaves the process's logging as it is (other tests' state)
        config = uvicorn.Config(
            _app, host="127.0.0.1", port=0, http=protocol, lifespan="off", log_config=None
        )
        self.server = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.server.run, daemon=True)
        self.thread.start()
        end = time.monotonic() + 20
        while not self.server.started:
            assert time.monotonic() < end and self.thread.is_alive(), "uvicorn did not start"
            time.sleep(0.01)
        self.port = self.server.servers[0].sockets[0].getsockname()[1]

    def connect(self, rcvbuf: int | None = None) -> socket.socket:
        s = socket.socket()
        if rcvbuf is not None:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        s.connect(("127.0.0.1", self.port))
        return s

    def connections(self) -> int:
        return len(self.server.server_state.connections)

    def stop(self) -> None:
        self.server.should_exit = True
        self.thread.join(10)


@pytest.fixture(params=[HttpToolsProtocol, H11Protocol], ids=["httptools", "h11"])
def served(request: pytest.FixtureRequest) -> Iterator[_Served]:
    s = _Served(request.param)
    try:
        yield s
    finally:
        s.stop()


def _read_until_closed(s: socket.socket, bound_s: float) -> tuple[bytes, float, bool]:
    """What the client reads until the server closes the connection (EOF or reset), the
    seconds it took, and whether it was a reset; fails after ``bound_s``."""
    start = time.monotonic()
    s.settimeout(bound_s)
    data, reset = b"", False
    try:
        while chunk := s.recv(65536):
            data += chunk
    except ConnectionResetError:
        reset = True
    except TimeoutError:
        pytest.fail(f"the server had not closed the connection after {bound_s} s")
    return data, time.monotonic() - start, reset


def test_unfinished_headers_get_408_and_the_connection_closed(served):
    with served.connect() as s:
        s.sendall(PARTIAL)
        data, seconds, _ = _read_until_closed(s, 10 * HEADER_TIMEOUT_S + 5)
    assert data.startswith(b"HTTP/1.1 408 "), data
    assert b'"type": "header_timeout"' in data and b"connection: close" in data.lower()
    assert seconds >= 0.5 * HEADER_TIMEOUT_S  # cut by the timer, not at once


def test_a_silent_connection_and_a_trickle_are_closed_too(served):
    with served.connect() as silent, served.connect() as trickle:
        start = time.monotonic()
        for byte in PARTIAL:  # one byte every tenth of the timeout: each resets uvicorn's
            try:  # keep-alive timer, not this one
                trickle.send(bytes([byte]))
            except (BrokenPipeError, ConnectionResetError):
                break
            if time.monotonic() - start > 4 * HEADER_TIMEOUT_S:
                break
            time.sleep(HEADER_TIMEOUT_S / 10)
        for s in (silent, trickle):
            data, _, _ = _read_until_closed(s, 10 * HEADER_TIMEOUT_S + 5)
            assert data.startswith(b"HTTP/1.1 408 "), data


def test_the_next_request_of_a_keep_alive_connection_has_the_same_bound(served):
    with served.connect() as s:
        s.sendall(b"GET /fast HTTP/1.1\r\nHost: x\r\n\r\n")
        first = b""
        while not first.endswith(b"ok"):
            first += s.recv(4096)
        assert first.startswith(b"HTTP/1.1 200 ")
        s.sendall(PARTIAL)
        data, _, _ = _read_until_closed(s, 10 * HEADER_TIMEOUT_S + 5)
    assert data.startswith(b"HTTP/1.1 408 "), data


def test_a_request_whose_headers_arrived_is_not_cut(served):
    """``/slow`` answers after twice the header timeout: served whole, on a connection that
    then takes a second request."""
    with served.connect() as s:
        for _ in range(2):
            s.sendall(b"POST /slow HTTP/1.1\r\nHost: x\r\nContent-Length: 2\r\n\r\n{}")
            answer = b""
            s.settimeout(10 * HEADER_TIMEOUT_S + 5)
            while not answer.endswith(b"ok"):
                chunk = s.recv(4096)
                assert chunk, f"closed after {answer!r}"
                answer += chunk
            assert answer.startswith(b"HTTP/1.1 200 "), answer


def test_a_client_that_does_not_read_is_aborted_and_its_answer_dropped(served):
    """An 8 MB answer to a client with a small receive buffer that never reads: the server
    aborts the connection after the send timeout, and the connection, with its buffered
    bytes, is gone: the client then reads what its kernel held, far less than the answer,
    and the end is a TCP reset (not a clean close that a client reading a chunked answer, or
    ignoring Content-Length, takes for a complete one): the kernel's buffer on the server's
    side is dropped too."""
    with served.connect(rcvbuf=4096) as s:
        s.sendall(b"GET /big HTTP/1.1\r\nHost: x\r\n\r\n")
        time.sleep(0.2)
        assert served.connections() == 1
        end = time.monotonic() + 10 * SEND_TIMEOUT_S + 5
        while served.connections() and time.monotonic() < end:
            time.sleep(0.05)
        assert served.connections() == 0, "the connection outlived the send timeout"
        data, _, reset = _read_until_closed(s, 5)
    assert data.startswith(b"HTTP/1.1 200 ") and len(data) < BIG // 2
    assert reset, f"a clean end of stream after {len(data)} bytes: the cut looks complete"


def test_a_client_that_reads_gets_the_whole_answer(served):
    """A reading client is not cut by the send timeout: the whole 8 MB answer arrives."""
    with served.connect(rcvbuf=65536) as s:
        s.sendall(b"GET /big HTTP/1.1\r\nHost: x\r\n\r\n")
        s.settimeout(10)
        got = 0
        while got < BIG:
            chunk = s.recv(1 << 20)
            assert chunk, f"closed after {got} bytes"
            got += len(chunk)
    assert got > BIG
