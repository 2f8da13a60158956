"""``planner serve`` while its workers warm up: a progress line every
:data:`planner_api.pool.pool.WARMING_REPORT_S` seconds, so that the tens of seconds between
"Uvicorn running" and the first warm worker on a first start (numba compiling) are not
silent; none once every worker is warm."""

from __future__ import annotations

import asyncio
import functools
import logging
import re
import time

from planner_api.pool import WorkerPool
from planner_api.pool import pool as pool_module

PROGRESS = re.compile(r"(\d+) of (\d+) workers warm after (\d+\.\d) s")


def test_the_pool_says_how_far_warm_up_is_until_every_worker_is_warm(monkeypatch, caplog):
    monkeypatch.setattr(pool_module, "WARMING_REPORT_S", 0.2)
    caplog.set_level(logging.INFO, logger="planner_api.pool")

    async def scenario() -> None:
        pool = WorkerPool(1, 0, warm_up=functools.partial(time.sleep, 1.5))  # picklable
        await pool.start()
        try:
            deadline = time.monotonic() + 120
            while pool.warm_workers < 1:
                assert time.monotonic() < deadline, "the worker never warmed up"
                await asyncio.sleep(0.05)
            await asyncio.sleep(0.6)  # three more report periods with the worker warm: none
        finally:
            pool.shutdown()

    asyncio.run(scenario())
    messages = [r.getMessage() for r in caplog.records if r.name == "planner_api.pool"]
    ready = next(i for i, m in enumerate(messages) if re.fullmatch(r"worker \d+ warm in .*", m))
    progress = [PROGRESS.fullmatch(m) for m in messages]
    before = [m for m in progress[:ready] if m]
    assert len(before) >= 3, messages  # a 1.5 s warm-up, one line per 0.2 s
    assert all(m[1] == "0" and m[2] == "1" for m in before)
    seconds = [float(m[3]) for m in before]
    assert seconds == sorted(seconds) and seconds[-1] >= 1.0  # since the worker was started
    assert not any(progress[ready:]), messages[ready:]
