"""The scene stores behave alike: the embedded SQLite file and a real PostgreSQL server that
this module starts itself (Debian's ``postgresql`` package: initdb and pg_ctl in a temporary
folder, on a free port; skipped with the reason when the package or the psycopg driver is
missing, never faked). Put, get, list, delete; versions; last writer wins with no torn scene
under concurrent writers. (The server: ``postgres_factory`` of tests/conftest.py.)"""

from __future__ import annotations

import shutil
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

from planner_api.scene_store import PostgresSceneStore, SqliteSceneStore, open_store

T = "default"  # the tenant of these tests (tenants apart: test_scene_store_tenants.py)


@pytest.fixture(scope="module")
def postgres_url(postgres_factory):
    """A PostgreSQL server of this module's own (a few seconds to start), its URL."""
    with postgres_factory() as server:
        yield server.url


@pytest.fixture(params=["sqlite", "postgresql"])
def store(request, tmp_path):
    if request.param == "sqlite":
        s = open_store(str(tmp_path / "scenes.db"))
        assert isinstance(s, SqliteSceneStore)
    else:
        url = request.getfixturevalue("postgres_url")
        s = open_store(url)
        assert isinstance(s, PostgresSceneStore)
        with s._transaction() as con:  # a clean table for each test
            con.execute("DELETE FROM scenes")
    yield s
    s.close()


def test_put_get_list_delete(store):
    assert store.get(T, "a") is None and store.list(T) == [] and store.delete(T, "a") is None
    first = store.put(T, "a", '{"obstacles": []}', "h1", 0, 0)
    assert (first.name, first.version, first.hash, first.body) == ("a", 1, "h1", None)
    second = store.put(T, "a", '{"obstacles": [1]}', "h2", 1, 5)
    assert second.version == 2 and second.updated_at >= first.updated_at
    store.put(T, "b", "{}", "h3", 0, 0)
    got = store.get(T, "a")
    assert (got.version, got.hash, got.body, got.obstacles, got.points) == (
        2,
        "h2",
        '{"obstacles": [1]}',
        1,
        5,
    )
    assert store.get(T, "a", body=False).body is None
    assert [r.name for r in store.list(T)] == ["a", "b"]
    assert store.delete(T, "a").version == 2
    assert store.get(T, "a") is None and [r.name for r in store.list(T)] == ["b"]
    assert store.put(T, "a", "{}", "h4", 0, 0).version == 1  # a new scene after a delete


def test_concurrent_writers_last_wins_whole(store):
    """12 writers x 5 PUTs of one name, each body carrying its own hash: every PUT is a
    version, and the stored row is one PUT whole (its body and hash belong together)."""
    big = "x" * 200_000  # a body large enough that a torn write would show

    def write(k: int) -> list[int]:
        return [store.put(T, "race", f"{k}-{i}-{big}", f"{k}-{i}", k, i).version for i in range(5)]

    with ThreadPoolExecutor(12) as ex:
        versions = sorted(v for vs in ex.map(write, range(12)) for v in vs)
    assert versions == list(range(1, 61))
    got = store.get(T, "race")
    assert got.version == 60
    k, i, rest = got.body.split("-", 2)
    assert got.hash == f"{k}-{i}" and (got.obstacles, got.points) == (int(k), int(i))
    assert rest == big


def test_a_second_store_on_the_same_database_sees_the_scenes(store, tmp_path):
    """Another process's store (a restarted service, another replica) reads what this one
    wrote."""
    store.put(T, "shared", '{"obstacles": []}', "hh", 0, 0)
    other = open_store(str(store.path) if isinstance(store, SqliteSceneStore) else store.url)
    try:
        assert other.get(T, "shared").hash == "hh"
        other.put(T, "shared", "{}", "hh2", 0, 0)
        assert store.get(T, "shared").version == 2
    finally:
        other.close()


def test_the_default_store_is_a_file_in_the_user_data_folder(monkeypatch, tmp_path):
    from planner_api.scene_store import default_store_path

    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    assert default_store_path() == tmp_path / "data" / "planner" / "scenes.sqlite3"
    s = open_store(None)
    try:
        assert isinstance(s, SqliteSceneStore) and s.path.exists()
    finally:
        s.close()
    time.sleep(0)  # nothing stays open: the file can go
    shutil.rmtree(tmp_path / "data")
