"""Slow clients against a real service process (uvicorn with :mod:`planner_api.protocol`): a
thousand connections that never finish their headers are all closed after
``PLANNER_HEADER_TIMEOUT_S`` while normal requests are served meanwhile, and four clients that
never read a ~4.6 MB answer have their connections aborted after ``PLANNER_SEND_TIMEOUT_S``,
the server's sockets (and the answers buffered on them) given back.

The oracles are the sockets: what each client reads and when the server closes it, and the
server process's open sockets counted in ``/proc/<pid>/fd``."""

from __future__ import annotations

import json
import os
import selectors
import socket
import time
from pathlib import Path
from urllib.parse import urlsplit

import httpx
import pytest

pytestmark = pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="needs /proc")

#: Clients that send a request and never read its ~4.6 MB answer, at once (more than the one
#: worker: their jobs run in turn while the first answers wait unread).
NEVER_READ = 4
PARTIAL = b"POST /v1/plan HTTP/1.1\r\nHost: x\r\nContent-Ty"
#: A /v1/timing request whose answer is ~4.6 MB (about 11,500 samples at 7.5 kHz).
BIG_TIMING = {
    "waypoints": [[0, 1, 2], [1.0, 1.2, 2.1], [-1.0, 1.0, 2.0], [0, 1, 2]],
    "sample_rate_hz": 7500,
    "method": "toppra",
}


def _address(url: str) -> tuple[str, int]:
    parts = urlsplit(url)
    return parts.hostname or "127.0.0.1", parts.port or 80


def _open_sockets(pid: int) -> int:
    count = 0
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            count += os.readlink(fd).startswith("socket:")
        except OSError:  # closed meanwhile
            pass
    return count


def test_a_thousand_unfinished_headers_are_closed_and_others_are_served(server_factory):
    timeout_s = 2.0
    process, url, _ = server_factory(warm=False, workers="1", header_timeout_s=str(timeout_s))
    address = _address(url)
    sockets = []
    selector = selectors.DefaultSelector()
    try:
        for _ in range(1000):
            s = socket.create_connection(address, timeout=10)
            s.sendall(PARTIAL)
            s.setblocking(False)
            sockets.append(s)
            selector.register(s, selectors.EVENT_READ)
        opened = time.monotonic()
        with httpx.Client(base_url=url, timeout=30) as client:
            assert client.get("/v1/health").status_code == 200
            fk = client.post("/v1/fk", json={"q": [0.0, 1.0, 2.0]})
            assert fk.status_code == 200 and fk.json()["postures"], fk.text
        answers: dict[socket.socket, bytes] = {s: b"" for s in sockets}
        closed = 0
        end = opened + timeout_s + 60  # a generous bound: 1,000 closes on a loaded machine
        while closed < len(sockets):
            assert time.monotonic() < end, f"{len(sockets) - closed} connections still open"
            for key, _ in selector.select(timeout=1):
                s = key.fileobj
                try:
                    chunk = s.recv(4096)  # type: ignore[union-attr]
                except ConnectionResetError:
                    chunk = b""
                if chunk:
                    answers[s] += chunk  # type: ignore[index]
                else:
                    selector.unregister(s)
                    closed += 1
        assert time.monotonic() - opened >= 0.5 * timeout_s  # cut by the timer, not at once
        assert all(a.startswith(b"HTTP/1.1 408 ") for a in answers.values())
        assert b"header_timeout" in answers[sockets[0]]
    finally:
        for s in sockets:
            s.close()
    assert process.poll() is None


def test_clients_that_never_read_are_cut_and_their_answers_dropped(server_factory):
    send_timeout_s = 2.0
    process, url, _ = server_factory(
        warm=False,
        workers="1",
        queue_size="16",
        send_timeout_s=str(send_timeout_s),
        request_timeout_s="300",  # the ~4.6 MB answers in turn on a loaded machine
    )
    address = _address(url)
    with httpx.Client(base_url=url, timeout=60) as client:  # the worker's first timing job
        whole = client.post("/v1/timing", json=BIG_TIMING)  # (imports) and the answer's size
    assert whole.status_code == 200, whole.text
    size = len(whole.content)
    assert size > 4_000_000
    time.sleep(0.5)  # the client's connection closed on the server's side too
    before = _open_sockets(process.pid)
    body = json.dumps(BIG_TIMING).encode()
    request = (
        b"POST /v1/timing HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
        b"Content-Length: %d\r\n\r\n" % len(body) + body
    )
    clients = []
    try:
        for _ in range(NEVER_READ):
            s = socket.socket()
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            s.connect(address)
            s.sendall(request)
            clients.append(s)
        time.sleep(0.5)
        assert _open_sockets(process.pid) >= before + NEVER_READ
        end = time.monotonic() + send_timeout_s + 240  # the jobs in turn, then the timeout
        while _open_sockets(process.pid) > before:
            assert time.monotonic() < end, "the server still holds the unread answers"
            time.sleep(0.2)
        for s in clients:  # each got its kernel's share of the answer, then the close
            s.settimeout(10)
            got = b""
            try:
                while chunk := s.recv(1 << 20):
                    got += chunk
            except ConnectionResetError:
                pass
            assert got.startswith(b"HTTP/1.1 200 "), got[:200]
            assert len(got) < size
    finally:
        for s in clients:
            s.close()
    with httpx.Client(base_url=url, timeout=30) as client:
        assert client.get("/v1/health").status_code == 200
