"""The light HTTP client of the service benchmarks: one keep-alive ``http.client``
connection, the lightest client the standard library has (httpx spends ~2 ms of its own per
request, which hid the server's cost). Shared by ``service.py`` and ``soak.py``."""

from __future__ import annotations

import http.client
import json
import time
from urllib.parse import urlsplit

__all__ = ["LightClient"]


class LightClient:
    """One keep-alive connection to ``url``; reconnects after a connection error (the
    server closed it, e.g. after a 408 or 413), which the caller sees as that error."""

    def __init__(self, url: str, timeout_s: float = 60.0) -> None:
        parts = urlsplit(url)
        self.host, self.port, self.timeout_s = parts.hostname, parts.port, timeout_s
        self.conn = self._connect()

    def _connect(self) -> http.client.HTTPConnection:
        return http.client.HTTPConnection(self.host, self.port, timeout=self.timeout_s)

    def request(
        self, method: str, path: str, body: bytes | dict | None = None
    ) -> tuple[int, bytes, float]:
        """One request, its answer read whole: (status, body, seconds client side). A
        ``dict`` body is sent as JSON. Raises the connection's error (``OSError``,
        ``http.client.HTTPException``) after reconnecting for the next request."""
        if isinstance(body, dict):
            body = json.dumps(body).encode()
        headers = {"Content-Type": "application/json"} if body is not None else {}
        t0 = time.perf_counter()
        try:
            self.conn.request(method, path, body=body, headers=headers)
            r = self.conn.getresponse()
            data = r.read()
        except (OSError, http.client.HTTPException):
            self.conn.close()
            self.conn = self._connect()
            raise
        seconds = time.perf_counter() - t0
        if r.getheader("connection", "").lower() == "close":
            self.conn.close()
            self.conn = self._connect()
        return r.status, data, seconds

    def call(self, method: str, path: str, body: bytes | None = None) -> float:
        """One request that must answer 200; seconds, client side."""
        status, data, seconds = self.request(method, path, body)
        if status != 200:
            raise RuntimeError(f"{method} {path}: {status} {data[:300]!r}")
        return seconds

    def close(self) -> None:
        self.conn.close()
