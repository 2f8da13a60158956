"""The store's calls (named scenes, and the ``jobs`` table of the long jobs:
:mod:`planner_api.job_table`), run in a thread pool of their own, each within a bounded time.

Why a pool of its own: the store's calls block (a file lock, a network round trip), and the
shared thread pool of the routes (anyio's, 40 threads) is what every ``def`` route and every
``run_in_threadpool`` needs. A held SQLite write lock once filled it with waiting PUTs, so an
unrelated ``GET /v1/jobs/{id}`` waited 29 s. Here the store has two lanes, one for reads and
one for writes, each of ``PLANNER_STORE_THREADS`` threads, and at most
:data:`QUEUE_PER_THREAD` calls per thread may wait for one; a call beyond that is answered 503
``store_unavailable`` at once, never queued. Why two lanes: only writes wait for SQLite's
write lock (reads are plain WAL reads), so PUTs piling up behind a held lock must not take
the threads the reads need (measured: with one lane, 45 PUTs behind a held lock made 45
concurrent GETs of a scene 503 as well).

Why every call has a budget: each call may take ``PLANNER_STORE_TIMEOUT_S`` from when it is
asked, its time waiting for a thread included; the store's own waits (SQLite's busy timeout,
PostgreSQL's connection and lock timeouts) get what is left
(:func:`planner_api.scene_store.waiting_at_most`). A call whose budget ran out before a
thread took it is dropped unrun (its 503 says nothing was changed), and the route stops
waiting for a call still running past its budget plus :data:`GRACE_S` (a driver that does not
honour its timeout), answering 503 all the same.

The store is opened on the first call (a SQLite file created, a table migrated, a
PostgreSQL connection made), in a store thread and within the budget too; a store that
cannot be opened is tried again at the next call. The ``jobs`` table is created in the same
database at the first job call (:meth:`StoreAccess.jobs`).
"""

from __future__ import annotations

import asyncio
import logging
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

from planner_api.exceptions import StoreUnavailableError
from planner_api.job_table import JobTable
from planner_api.scene_store import SceneStore, open_store, unavailable_errors, waiting_at_most

__all__ = ["GRACE_S", "QUEUE_PER_THREAD", "StoreAccess"]

logger = logging.getLogger(__name__)

#: Calls that may wait for each store thread; one more is a 503 at once.
QUEUE_PER_THREAD = 4
#: Seconds past its budget the route still waits for a running call before its 503.
GRACE_S = 1.0

T = TypeVar("T")


class _Expired(Exception):
    """A call's budget ran out before a store thread took it: it was not run."""


class _Lane:
    """Threads and an admission count of one kind of call (reads or writes)."""

    def __init__(self, name: str, threads: int) -> None:
        self.name = name
        self.threads = threads
        self.capacity = threads * (1 + QUEUE_PER_THREAD)
        self.executor = ThreadPoolExecutor(threads, thread_name_prefix=f"scene-store-{name}")
        self.lock = threading.Lock()
        self.in_flight = 0

    def admit(self) -> bool:
        with self.lock:
            if self.in_flight >= self.capacity:
                return False
            self.in_flight += 1
            return True

    def done(self, _: object = None) -> None:
        with self.lock:
            self.in_flight -= 1


class StoreAccess:
    """The service's way to its scene store (module docstring).

    Parameters
    ----------
    setting : str or None
        ``PLANNER_SCENE_STORE`` (:func:`planner_api.scene_store.open_store`).
    timeout_s : float
        Budget of one call from when it is asked, s (``PLANNER_STORE_TIMEOUT_S``).
    threads : int
        Store threads of each lane (``PLANNER_STORE_THREADS``).
    retry_after_s : int
        ``Retry-After`` of its 503s.
    job_ttl_s : float
        How long the ``jobs`` table keeps a finished job, s (``PLANNER_JOB_TTL_S``).
    """

    def __init__(
        self,
        setting: str | None,
        *,
        timeout_s: float,
        threads: int,
        retry_after_s: int,
        job_ttl_s: float = 3600.0,
        opener: Callable[[str | None], SceneStore] = open_store,
    ) -> None:
        self.setting = setting
        self.timeout_s = timeout_s
        self.retry_after_s = retry_after_s
        self.reads = _Lane("reads", threads)
        self.writes = _Lane("writes", threads)
        self._opener = opener
        self._lock = threading.Lock()
        self._store: SceneStore | None = None
        self.job_ttl_s = job_ttl_s
        self._jobs: JobTable | None = None
        self._errors = unavailable_errors()

    @property
    def kind(self) -> str:
        """What the store is, for messages: ``postgresql`` or ``sqlite``."""
        url = self.setting or ""
        return "postgresql" if url.startswith(("postgresql://", "postgres://")) else "sqlite"

    def _unavailable(self, why: str) -> StoreUnavailableError:
        return StoreUnavailableError(
            f"the store of scenes and jobs ({self.kind}) cannot answer now: {why}; nothing was changed, "
            f"retry after {self.retry_after_s} s",
            self.retry_after_s,
        )

    def _opened(self) -> SceneStore:
        store = self._store
        if store is None:
            with self._lock:
                store = self._store
                if store is None:
                    store = self._store = self._opener(self.setting)
        return store

    def _run(self, deadline: float, call: Callable[[SceneStore], T]) -> T:
        left = deadline - time.monotonic()
        if left <= 0:
            raise _Expired
        with waiting_at_most(left):
            return call(self._opened())

    async def call(self, call: Callable[[SceneStore], T], *, write: bool = False) -> T:
        """``call(store)`` in a store thread of its lane (``write``: a PUT or DELETE), within
        the budget; :class:`StoreUnavailableError` (503) when the lane's threads are busy and
        its queue full, when the budget runs out, or when the store cannot be reached. Its
        other errors (a quota) are raised as they are."""
        lane = self.writes if write else self.reads
        if not lane.admit():
            raise self._unavailable(
                f"its {lane.threads} {lane.name} threads (PLANNER_STORE_THREADS) are busy and "
                f"{lane.capacity - lane.threads} calls already wait for them"
            )
        deadline = time.monotonic() + self.timeout_s
        try:
            future = lane.executor.submit(self._run, deadline, call)
        except RuntimeError as exc:  # shut down: the application is stopping
            lane.done()
            raise self._unavailable("the service is stopping") from exc
        future.add_done_callback(lane.done)
        try:
            return await asyncio.wait_for(asyncio.wrap_future(future), self.timeout_s + GRACE_S)
        except (_Expired, TimeoutError) as exc:
            raise self._unavailable(
                f"it did not answer within {self.timeout_s:g} s (PLANNER_STORE_TIMEOUT_S)"
            ) from exc
        except self._errors as exc:
            logger.warning("scene store unavailable: %s: %s", type(exc).__name__, exc)
            raise self._unavailable(_why(exc, self.timeout_s)) from exc

    def _job_table(self, store: SceneStore) -> JobTable:
        table = self._jobs
        if table is None or table.store is not store:
            with self._lock:
                table = self._jobs
                if table is None or table.store is not store:
                    table = self._jobs = JobTable(store, ttl_s=self.job_ttl_s)
        return table

    async def jobs(self, call: Callable[[JobTable], T], *, write: bool = False) -> T:
        """``call(table)`` on the ``jobs`` table (:mod:`planner_api.job_table`), as
        :meth:`call` runs a scene call: the same lanes, budget and 503s."""
        return await self.call(lambda store: call(self._job_table(store)), write=write)

    async def ping(self) -> str | None:
        """None when the store answers a read within the budget, else why not (for
        ``/v1/ready``)."""
        try:
            await self.call(lambda store: store.ping())
        except StoreUnavailableError as exc:
            return str(exc)
        return None

    def close(self) -> None:
        """Stop the threads (a call still running ends on its own) and close the store."""
        for lane in (self.reads, self.writes):
            lane.executor.shutdown(wait=False, cancel_futures=True)
        with self._lock:
            store, self._store = self._store, None
        if store is not None:
            store.close()


def _why(exc: BaseException, timeout_s: float) -> str:
    """A driver error in words for the client, without the driver's details (host names,
    paths), which go to the log."""
    text = str(exc).lower()
    if "locked" in text or "busy" in text or "lock timeout" in text:
        return f"its write lock stayed held past {timeout_s:g} s (PLANNER_STORE_TIMEOUT_S)"
    return "its database cannot be reached or opened (details in the service log)"
