"""An answer's head goes out with its body in one write (:class:`planner_api.protocol.
_HeadWithBody`): one ``send()`` and one client wake-up per plain answer instead of two, the
head of a streamed answer whose first chunk is late still sent at once, the 100 Continue never
held. The oracle is what reaches the transport (a recording one), and on a real socket, what
the client reads and when."""

from __future__ import annotations

import asyncio
import socket
import threading
import time

import uvicorn
from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

from planner_api.protocol import _CONTINUE, _HeadWithBody, guarded_protocol

HEAD = b"HTTP/1.1 200 OK\r\ncontent-length: 2\r\n\r\n"


class _Recorder:
    """A transport that keeps what is written to it."""

    def __init__(self) -> None:
        self.writes: list[bytes] = []
        self.closed = False

    def write(self, data: bytes) -> None:
        self.writes.append(data)

    def close(self) -> None:
        self.closed = True

    def is_closing(self) -> bool:
        return self.closed

    def get_extra_info(self, name: str) -> str:
        return f"info {name}"


def _turn(loop: asyncio.AbstractEventLoop) -> None:
    loop.run_until_complete(asyncio.sleep(0))


def test_the_head_goes_with_the_body_in_one_write() -> None:
    loop = asyncio.new_event_loop()
    try:
        t = _Recorder()
        w = _HeadWithBody(t, loop)  # type: ignore[arg-type]
        w.write(HEAD)
        assert t.writes == []
        w.write(b"ok")
        _turn(loop)
        assert t.writes == [HEAD + b"ok"]
        w.write(b"more")  # after the head, every write is the transport's
        assert t.writes == [HEAD + b"ok", b"more"]
        assert w.get_extra_info("peername") == "info peername"
    finally:
        loop.close()


def test_a_head_whose_body_is_late_goes_on_the_next_turn_and_a_large_body_after_it() -> None:
    loop = asyncio.new_event_loop()
    try:
        t = _Recorder()
        w = _HeadWithBody(t, loop)  # type: ignore[arg-type]
        w.write(HEAD)
        _turn(loop)
        assert t.writes == [HEAD]
        w.write(b"chunk")
        assert t.writes == [HEAD, b"chunk"]
        t2 = _Recorder()
        w2 = _HeadWithBody(t2, loop)  # type: ignore[arg-type]
        big = b"x" * (1 << 20)
        w2.write(HEAD)
        w2.write(big)
        assert t2.writes == [HEAD, big]
    finally:
        loop.close()


def test_the_100_continue_is_never_held_and_close_sends_a_held_head() -> None:
    loop = asyncio.new_event_loop()
    try:
        t = _Recorder()
        w = _HeadWithBody(t, loop)  # type: ignore[arg-type]
        w.write(_CONTINUE)
        assert t.writes == [_CONTINUE]
        w.write(HEAD)
        w.close()
        assert t.writes == [_CONTINUE, HEAD]
        assert t.closed and w.is_closing()
        _turn(loop)  # the scheduled flush finds nothing held
        assert t.writes == [_CONTINUE, HEAD]
    finally:
        loop.close()


async def _late_body(scope, receive, send) -> None:  # type: ignore[no-untyped-def]
    if scope["type"] != "http":
        return
    await send({"type": "http.response.start", "status": 200, "headers": []})  # chunked
    if scope["path"] == "/late":
        await asyncio.sleep(0.5)
    await send({"type": "http.response.body", "body": b"done"})


def test_on_a_real_socket_a_late_body_does_not_hold_its_head() -> None:
    protocol = guarded_protocol(5.0, 5.0, HttpToolsProtocol)
    config = uvicorn.Config(
        _late_body, host="127.0.0.1", port=0, http=protocol, lifespan="off", log_config=None
    )
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        end = time.monotonic() + 20
        while not server.started:
            assert time.monotonic() < end and thread.is_alive(), "uvicorn did not start"
            time.sleep(0.01)
        port = server.servers[0].sockets[0].getsockname()[1]
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            s.sendall(b"GET /late HTTP/1.1\r\nHost: x\r\n\r\n")
            start = time.monotonic()
            first = s.recv(65536)
            assert first.startswith(b"HTTP/1.1 200 OK")
            assert time.monotonic() - start < 0.4, "the head waited for the late body"
            rest = b""
            while not rest.endswith(b"0\r\n\r\n"):
                rest += s.recv(65536)
            assert b"done" in first + rest
            s.sendall(b"GET /now HTTP/1.1\r\nHost: x\r\n\r\n")  # keep-alive: the next answer
            answer = b""
            while not answer.endswith(b"0\r\n\r\n"):
                answer += s.recv(65536)
            assert answer.startswith(b"HTTP/1.1 200 OK") and b"done" in answer
    finally:
        server.should_exit = True
        thread.join(10)
