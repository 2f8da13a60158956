"""The scene stores behave alike: the embedded SQLite file and a real PostgreSQL server that
this module starts itself (Debian's ``postgresql`` package: initdb and pg_ctl in a temporary
folder, on a free port; skipped with the reason when the package or the psycopg driver is
missing, never faked). Put, get, list, delete; versions; last writer wins with no torn scene
under concurrent writers."""

from __future__ import annotations

import glob
import os
import shutil
import socket
import subprocess
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from planner_api.scene_store import PostgresSceneStore, SqliteSceneStore, open_store

T = "default"  # the tenant of these tests (tenants apart: test_scene_store_tenants.py)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _pg_bin() -> Path | None:
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"))
    return Path(found[-1]).parent if found else None


@pytest.fixture(scope="module")
def postgres_url():
    """A PostgreSQL server of this module's own (a few seconds to start), its URL."""
    bindir = _pg_bin()
    if bindir is None:
        pytest.skip("PostgreSQL is not installed (Debian package postgresql: initdb, pg_ctl)")
    try:
        import psycopg  # noqa: F401
    except ImportError:
        pytest.skip("the psycopg driver is not installed (pip install psycopg)")
    # a folder of its own under the system's temporary folder: pytest's is private to the
    # user running the tests, which the server's user (below) may not be
    root = Path(tempfile.mkdtemp(prefix="planner-pg-"))
    data, port = root / "data", _free_port()
    # initdb refuses to run as root: run the server as the package's postgres user then
    as_user: list[str] = []
    if os.geteuid() == 0:
        if shutil.which("runuser") is None:
            pytest.skip("running as root without runuser: cannot start PostgreSQL as postgres")
        as_user = ["runuser", "-u", "postgres", "--"]
        shutil.chown(root, "postgres")
    run = {"check": True, "capture_output": True, "timeout": 120}
    subprocess.run([*as_user, str(bindir / "initdb"), "-D", str(data), "-U", "planner",
                    "--auth=trust", "-E", "UTF8"], **run)  # fmt: skip
    options = f"-p {port} -k {root} -c listen_addresses=127.0.0.1 -c fsync=off"
    subprocess.run([*as_user, str(bindir / "pg_ctl"), "-D", str(data), "-o", options,
                    "-l", str(root / "log"), "-w", "start"], **run)  # fmt: skip
    url = f"postgresql://planner@127.0.0.1:{port}/postgres"
    try:
        yield url
    finally:
        subprocess.run([*as_user, str(bindir / "pg_ctl"), "-D", str(data), "-m", "immediate",
                        "stop"], capture_output=True, timeout=60)  # fmt: skip
        shutil.rmtree(root, ignore_errors=True)


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
        2, "h2", '{"obstacles": [1]}', 1, 5
    )  # fmt: skip
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
