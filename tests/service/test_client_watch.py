"""planner_api.deps.ClientWatch: a client that leaves resolves the request's CLIENT_GONE
future once the watch has started (WATCH_AFTER_S into the request), and a request that ends
before then never reads the connection (no watch task was made)."""

from __future__ import annotations

import asyncio

from planner_api.deps import WATCH_AFTER_S, ClientWatch
from planner_api.pool import CLIENT_GONE


class _Request:
    """What ClientWatch uses of a request: ``receive``, counted; its client has left."""

    def __init__(self) -> None:
        self.reads = 0

    async def receive(self) -> dict[str, str]:
        self.reads += 1
        return {"type": "http.disconnect"}


def test_a_short_request_never_reads_its_connection():
    request = _Request()

    async def scenario() -> None:
        async with ClientWatch(request):  # type: ignore[arg-type]
            gone = CLIENT_GONE.get()
            assert gone is not None and not gone.done()
            await asyncio.sleep(0)
        assert CLIENT_GONE.get() is None  # reset on the way out
        await asyncio.sleep(WATCH_AFTER_S * 2)  # the timer was cancelled: nothing starts
        assert not gone.done()

    asyncio.run(scenario())
    assert request.reads == 0


def test_a_client_gone_is_seen_once_the_watch_starts():
    request = _Request()

    async def scenario() -> float:
        loop = asyncio.get_running_loop()
        async with ClientWatch(request):  # type: ignore[arg-type]
            gone = CLIENT_GONE.get()
            assert gone is not None
            t0 = loop.time()
            await asyncio.wait_for(gone, timeout=5.0)
            return loop.time() - t0

    waited = asyncio.run(scenario())
    assert request.reads == 1
    assert waited >= WATCH_AFTER_S * 0.9  # a loop timer may fire a little early
