"""Where named scenes persist: an embedded SQLite file by default, PostgreSQL for a
deployment of several replicas (``PLANNER_SCENE_STORE``, :mod:`planner_api.settings`).

One table, one row per scene: ``name`` (the key), ``version`` (1 at the first PUT, +1 at
each), ``hash`` (SHA-256 of ``body``), ``body`` (the scene's canonical JSON, as the wire
writes it), ``updated_at`` and the counts a listing shows. Why one row: a PUT is one
``INSERT ... ON CONFLICT (name) DO UPDATE`` statement, atomic in both databases, so two
concurrent PUTs of one name leave one of them whole (the last to commit wins) and a reader
sees a whole scene or the one before, never a mix. A plan resolves its scene once, at the
start (the route reads the row and hands the scene's obstacles to the job): a PUT during the
plan changes the next plans, not this one.

Both stores speak the same SQL (``ON CONFLICT`` upserts exist in SQLite >= 3.24 and
PostgreSQL >= 9.5); only the parameter style and the connection differ. The calls block:
the routes run them in a thread (``run_in_threadpool``), never on the event loop.
"""

from __future__ import annotations

import os
import sqlite3
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

__all__ = [
    "PostgresSceneStore",
    "SceneRow",
    "SceneStore",
    "SqliteSceneStore",
    "default_store_path",
    "open_store",
]

_SCHEMA = """
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
_UPSERT = """
INSERT INTO scenes (name, version, hash, body, updated_at, obstacles, points)
VALUES ({p}, 1, {p}, {p}, {p}, {p}, {p})
ON CONFLICT (name) DO UPDATE SET
    version = scenes.version + 1, hash = excluded.hash, body = excluded.body,
    updated_at = excluded.updated_at, obstacles = excluded.obstacles, points = excluded.points
RETURNING name, version, hash, updated_at, obstacles, points
"""
_INFO = "name, version, hash, updated_at, obstacles, points"


@dataclass(frozen=True, slots=True)
class SceneRow:
    """A stored scene: its metadata, and its ``body`` (JSON text) when it was asked for."""

    name: str
    version: int
    hash: str
    updated_at: float
    obstacles: int
    points: int
    body: str | None = None

    def info(self) -> dict[str, Any]:
        """The fields of :class:`planner.wire.SceneInfo`."""
        return {
            "name": self.name, "version": self.version, "hash": self.hash,
            "updated_at": self.updated_at, "obstacles": self.obstacles, "points": self.points,
        }  # fmt: skip


class SceneStore(Protocol):
    """What the routes need of a store (each call one transaction)."""

    def put(self, name: str, body: str, digest: str, obstacles: int, points: int) -> SceneRow:
        """Store ``body`` under ``name`` (a new version; last writer wins)."""
        ...

    def get(self, name: str, *, body: bool = True) -> SceneRow | None:
        """The scene (with its body unless ``body`` is False), or None."""
        ...

    def list(self) -> list[SceneRow]:
        """Every scene's metadata, by name."""
        ...

    def delete(self, name: str) -> SceneRow | None:
        """Forget the scene; its metadata, or None when there was none."""
        ...

    def close(self) -> None: ...


class _SqlStore:
    """The SQL shared by both stores; ``_connect()`` yields a connection in a transaction
    that commits on exit, ``_P`` is the driver's parameter marker."""

    _P = "?"

    @contextmanager
    def _connect(self) -> Iterator[Any]:  # pragma: no cover - overridden
        raise NotImplementedError
        yield

    def _row(self, values: Any, body: str | None = None) -> SceneRow:
        name, version, digest, updated, obstacles, points = values
        return SceneRow(
            str(name), int(version), str(digest), float(updated), int(obstacles), int(points), body
        )

    def put(self, name: str, body: str, digest: str, obstacles: int, points: int) -> SceneRow:
        with self._connect() as con:
            cur = con.execute(
                _UPSERT.format(p=self._P), (name, digest, body, time.time(), obstacles, points)
            )
            return self._row(cur.fetchone())

    def get(self, name: str, *, body: bool = True) -> SceneRow | None:
        columns = f"{_INFO}, body" if body else _INFO
        with self._connect() as con:
            found = con.execute(
                f"SELECT {columns} FROM scenes WHERE name = {self._P}", (name,)
            ).fetchone()
        if found is None:
            return None
        return self._row(found[:6], str(found[6]) if body else None)

    def list(self) -> list[SceneRow]:
        with self._connect() as con:
            rows = con.execute(f"SELECT {_INFO} FROM scenes ORDER BY name").fetchall()
        return [self._row(r) for r in rows]

    def delete(self, name: str) -> SceneRow | None:
        with self._connect() as con:
            found = con.execute(
                f"DELETE FROM scenes WHERE name = {self._P} RETURNING {_INFO}", (name,)
            ).fetchone()
        return None if found is None else self._row(found)


class SqliteSceneStore(_SqlStore):
    """Scenes in one SQLite file (created with its folder on first use), in WAL mode so that
    readers never wait for a writer. A connection per call: sqlite3 connections belong to
    one thread, and opening a file costs microseconds."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        con = sqlite3.connect(self.path, timeout=30.0, isolation_level=None)
        try:  # outside a transaction: SQLite refuses to change the journal mode inside one
            con.execute("PRAGMA journal_mode=WAL")
        finally:
            con.close()
        with self._connect() as con:
            con.execute(_SCHEMA)

    @contextmanager
    def _connect(self) -> Iterator[sqlite3.Connection]:
        con = sqlite3.connect(self.path, timeout=30.0, isolation_level=None)
        try:
            con.execute("BEGIN IMMEDIATE")
            try:
                yield con
            except BaseException:
                con.execute("ROLLBACK")
                raise
            con.execute("COMMIT")
        finally:
            con.close()

    def close(self) -> None:
        """Nothing stays open between calls."""


class PostgresSceneStore(_SqlStore):
    """Scenes in a PostgreSQL database (``postgresql://`` URL; the driver is psycopg 3,
    imported only here). One connection, used by one call at a time, re-opened when lost."""

    _P = "%s"

    def __init__(self, url: str) -> None:
        self.url = url
        self._lock = threading.Lock()
        self._con: Any = None
        with self._connect() as con:
            con.execute(_SCHEMA)

    @contextmanager
    def _connect(self) -> Iterator[Any]:
        import psycopg

        with self._lock:
            if self._con is None or self._con.closed:
                self._con = psycopg.connect(self.url)
            try:
                with self._con.transaction():
                    yield self._con
            except psycopg.OperationalError:
                self._con.close()
                self._con = None
                raise

    def close(self) -> None:
        with self._lock:
            if self._con is not None:
                self._con.close()
                self._con = None


def default_store_path() -> Path:
    """Where scenes live without ``PLANNER_SCENE_STORE``: ``$XDG_DATA_HOME/planner/
    scenes.sqlite3`` (``~/.local/share`` when XDG_DATA_HOME is unset)."""
    base = os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share"
    return Path(base) / "planner" / "scenes.sqlite3"


def open_store(setting: str | None) -> SceneStore:
    """The store a ``PLANNER_SCENE_STORE`` value names: a ``postgresql://`` (or
    ``postgres://``) URL, else a SQLite file path (None or empty: :func:`default_store_path`)."""
    if setting and setting.startswith(("postgresql://", "postgres://")):
        return PostgresSceneStore(setting)
    return SqliteSceneStore(setting or default_store_path())
