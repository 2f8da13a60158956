"""The scene stores' tenants, quotas, migration and availability, SQLite and a real
PostgreSQL server alike (``postgres_factory``, tests/conftest.py):

* two tenants each have their own ``table-1``; neither sees, lists or deletes the other's;
* the quotas refuse, naming the setting, and count a replaced scene once;
* a table of the first version (no tenant) is migrated: its rows become the tenant
  ``default``'s, with their bytes, and another tenant may then use the same names;
* SQLite under a write lock held by another connection (``BEGIN IMMEDIATE`` here): reads
  answer, a write gives up with the driver's "locked" error after the wait it was given;
* SQLite gives a deleted scene's space back to the file system;
* :class:`planner_api.store_access.StoreAccess`: a full pool refuses at once, a call whose
  budget ran out before a thread took it is not run.
"""

from __future__ import annotations

import asyncio
import sqlite3
import threading

import pytest

from planner_api.exceptions import QuotaExceededError, StoreUnavailableError
from planner_api.scene_store import (
    PostgresSceneStore,
    SqliteSceneStore,
    open_store,
    unavailable_errors,
    waiting_at_most,
)
from planner_api.store_access import QUEUE_PER_THREAD, StoreAccess

#: The table of the first version of the store, as it created it.
V1_SCHEMA = """
CREATE TABLE IF NOT EXISTS scenes (
    name TEXT PRIMARY KEY,
    version BIGINT NOT NULL,
    hash TEXT NOT NULL,
    body TEXT NOT NULL,
    updated_at DOUBLE PRECISION NOT NULL,
    obstacles BIGINT NOT NULL,
    points BIGINT NOT NULL
)
"""


@pytest.fixture(scope="module")
def postgres_url(postgres_factory):
    with postgres_factory() as server:
        yield server.url


def _clean_postgres(url: str) -> None:
    import psycopg

    with psycopg.connect(url, autocommit=True) as con:
        con.execute("DROP TABLE IF EXISTS scenes")


@pytest.fixture(params=["sqlite", "postgresql"])
def target(request, tmp_path):
    """Where a store goes: a SQLite path, or the PostgreSQL URL with no table yet."""
    if request.param == "sqlite":
        return str(tmp_path / "scenes.db")
    url = request.getfixturevalue("postgres_url")
    _clean_postgres(url)
    return url


@pytest.fixture
def store(target):
    s = open_store(target)
    yield s
    s.close()


def test_tenants_have_their_own_names(store):
    a = store.put("alice", "table-1", '{"obstacles": []}', "ha", 0, 0)
    b = store.put("bob", "table-1", '{"obstacles": [1]}', "hb", 1, 0)
    assert (a.version, b.version) == (1, 1)  # two scenes, not two versions of one
    assert store.get("alice", "table-1").hash == "ha"
    assert store.get("bob", "table-1").hash == "hb"
    store.put("alice", "only-alice", "{}", "hx", 0, 0)
    assert [r.name for r in store.list("alice")] == ["only-alice", "table-1"]
    assert [r.name for r in store.list("bob")] == ["table-1"]
    assert store.get("bob", "only-alice") is None
    assert store.delete("bob", "only-alice") is None
    assert store.get("alice", "only-alice") is not None  # untouched by bob's delete
    assert store.delete("bob", "table-1").hash == "hb"
    assert store.get("alice", "table-1").hash == "ha"


def test_the_count_quota_names_its_setting_and_a_replacement_counts_once(store):
    limits = {"max_scenes": 2, "max_bytes": 10_000}
    store.put("t", "a", "{}", "h", 0, 0, **limits)
    store.put("t", "b", "{}", "h", 0, 0, **limits)
    store.put("t", "a", '{"x": 1}', "h2", 0, 0, **limits)  # a new version of a: still 2
    with pytest.raises(QuotaExceededError) as caught:
        store.put("t", "c", "{}", "h", 0, 0, **limits)
    assert caught.value.status == 422 and caught.value.loc == ("path", "name")
    assert "PLANNER_SCENES_MAX" in str(caught.value) and "at most 2" in str(caught.value)
    assert store.get("t", "c") is None  # nothing stored
    store.put("other", "c", "{}", "h", 0, 0, **limits)  # the quota is per tenant
    store.delete("t", "b")
    store.put("t", "c", "{}", "h", 0, 0, **limits)  # room again after a delete


def test_the_byte_quota_sums_the_bodies_and_names_its_setting(store):
    limits = {"max_scenes": 100, "max_bytes": 1000}
    store.put("t", "a", "x" * 600, "h", 0, 0, **limits)
    store.put("t", "a", "é" * 300, "h", 0, 0, **limits)  # 600 bytes in UTF-8: replaces a
    with pytest.raises(QuotaExceededError) as caught:
        store.put("t", "b", "y" * 401, "h", 0, 0, **limits)
    assert caught.value.status == 413 and caught.value.loc == ("body",)
    message = str(caught.value)
    assert "PLANNER_SCENE_BYTES_MAX" in message and "1001 bytes" in message
    store.put("t", "b", "y" * 400, "h", 0, 0, **limits)  # exactly the limit
    assert store.get("t", "b") is not None


def _make_v1(target: str) -> None:
    """A store of the first version at ``target``, with two scenes."""
    rows = [("cell-1", 3, "h1", '{"obstacles": []}', 1.0, 0, 0),
            ("cell-2", 1, "h2", '{"obstacles": ["é"]}', 2.0, 1, 7)]  # fmt: skip
    if target.startswith("postgresql://"):
        import psycopg

        with psycopg.connect(target, autocommit=True) as con:
            con.execute(V1_SCHEMA)
            for row in rows:
                con.execute("INSERT INTO scenes VALUES (%s, %s, %s, %s, %s, %s, %s)", row)
    else:
        con = sqlite3.connect(target)
        con.execute(V1_SCHEMA)
        con.executemany("INSERT INTO scenes VALUES (?, ?, ?, ?, ?, ?, ?)", rows)
        con.commit()
        con.close()


def test_a_first_version_table_is_migrated_to_the_default_tenant(target):
    _make_v1(target)
    store = open_store(target)
    try:
        assert [r.name for r in store.list("default")] == ["cell-1", "cell-2"]
        got = store.get("default", "cell-2")
        assert (got.version, got.hash, got.body, got.points) == (1, "h2", '{"obstacles": ["é"]}', 7)
        assert store.list("alice") == []
        # the bytes were computed: the quota counts them (their UTF-8 lengths)
        stored = len(b'{"obstacles": []}') + len('{"obstacles": ["é"]}'.encode())
        with pytest.raises(QuotaExceededError):
            store.put("default", "new", "x" * (51 - stored), "h", 0, 0, max_bytes=50)
        store.put("default", "new", "x" * (50 - stored), "h", 0, 0, max_bytes=50)
        # names are per tenant now: another tenant's cell-1 is another scene
        assert store.put("alice", "cell-1", "{}", "ha", 0, 0).version == 1
        assert store.put("default", "cell-1", "{}", "hd", 0, 0).version == 4
    finally:
        store.close()
    again = open_store(target)  # a second opening finds it migrated: nothing changes
    try:
        assert [r.name for r in again.list("default")] == ["cell-1", "cell-2", "new"]
    finally:
        again.close()


def _hold_write_lock(path: str) -> sqlite3.Connection:
    con = sqlite3.connect(path, isolation_level=None)
    con.execute("BEGIN IMMEDIATE")
    return con


def test_sqlite_reads_answer_under_a_held_write_lock_and_writes_give_up(tmp_path):
    path = str(tmp_path / "scenes.db")
    store = SqliteSceneStore(path)
    store.put("t", "a", '{"obstacles": []}', "h", 0, 0)
    holder = _hold_write_lock(path)
    try:
        with waiting_at_most(0.2):
            assert store.get("t", "a").hash == "h"  # WAL: a plain read, no lock
            assert [r.name for r in store.list("t")] == ["a"]
            store.ping()
            with pytest.raises(unavailable_errors()) as caught:
                store.put("t", "b", "{}", "h", 0, 0)
            assert "locked" in str(caught.value)
            with pytest.raises(unavailable_errors()):
                store.delete("t", "a")
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    assert store.get("t", "b") is None and store.get("t", "a") is not None
    store.put("t", "b", "{}", "h", 0, 0)  # the lock released: writes go through


def _disk_bytes(path) -> int:
    return sum(p.stat().st_size for p in path.parent.glob(path.name + "*"))


def test_sqlite_gives_the_space_of_deleted_scenes_back(tmp_path):
    """20 scenes of 1 MB, then 19 deleted: the file (with its WAL) shrinks to a fraction;
    without incremental vacuum the file keeps its pages (SQLite's free list)."""
    path = tmp_path / "scenes.db"
    store = SqliteSceneStore(path)
    body = "x" * 1_000_000
    for i in range(20):
        store.put("t", f"s{i}", body, "h", 0, 0)
    full = _disk_bytes(path)
    assert full > 20_000_000
    for i in range(19):
        store.delete("t", f"s{i}")
    assert _disk_bytes(path) < full / 4, (full, _disk_bytes(path))
    assert store.get("t", "s19").body == body
    con = sqlite3.connect(path)
    assert con.execute("PRAGMA auto_vacuum").fetchone()[0] == 2  # incremental
    con.close()


def test_a_first_version_sqlite_file_is_converted_to_incremental_vacuum(tmp_path):
    path = str(tmp_path / "old.db")
    _make_v1(path)
    SqliteSceneStore(path).close()
    con = sqlite3.connect(path)
    assert con.execute("PRAGMA auto_vacuum").fetchone()[0] == 2
    assert con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    con.close()


class _Blocking:
    """A store whose calls wait for ``release`` (the one method the test calls)."""

    def __init__(self) -> None:
        self.release = threading.Event()
        self.ran: list[str] = []

    def get(self, what: str) -> str:  # the calls of the reads' lane
        self.ran.append(what)
        self.release.wait(30)
        return what

    def close(self) -> None:
        pass


def test_a_full_store_pool_refuses_at_once_and_expired_calls_do_not_run():
    blocking = _Blocking()
    access = StoreAccess(None, timeout_s=0.3, threads=1, retry_after_s=2, opener=lambda _: blocking)

    async def scenario() -> list[BaseException | str]:
        calls = [
            asyncio.create_task(access.call(lambda s, i=i: s.get(f"call-{i}")))
            for i in range(1 + QUEUE_PER_THREAD)
        ]
        await asyncio.sleep(0)  # every call admitted: one running, the others waiting
        with pytest.raises(StoreUnavailableError) as full:
            await access.call(lambda s: s.get("one too many"))
        assert "PLANNER_STORE_THREADS" in str(full.value) and full.value.retry_after_s == 2
        await access.call(lambda s: "a write", write=True)  # the other lane is free
        results = await asyncio.gather(*calls, return_exceptions=True)
        blocking.release.set()
        return results

    results = asyncio.run(scenario())
    access.close()
    # the running call outlived its budget (+ grace): 503; the waiting ones too
    assert all(isinstance(r, StoreUnavailableError) for r in results), results
    assert "PLANNER_STORE_TIMEOUT_S" in str(results[0])
    # the waiting calls' budgets ran out before the thread was free: none of them ran
    assert blocking.ran == ["call-0"]


def test_postgresql_unreachable_is_a_driver_error_of_the_unavailable_kind(postgres_factory):
    with postgres_factory() as server:
        store = PostgresSceneStore(server.url)
        store.put("t", "a", "{}", "h", 0, 0)
        server.stop()
        with waiting_at_most(1.0), pytest.raises(unavailable_errors()):
            store.get("t", "a")
        with waiting_at_most(1.0), pytest.raises(unavailable_errors()):
            store.get("t", "a")  # the reconnection is refused too
        server.start()
        assert store.get("t", "a").hash == "h"  # reconnects by itself
        store.close()
