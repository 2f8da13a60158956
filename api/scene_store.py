"""Where named scenes persist: an embedded SQLite file by default, PostgreSQL for a
deployment of several replicas (``PLANNER_SCENE_STORE``, :mod:`planner_api.settings`).

One table, one row per scene of a tenant: ``tenant`` and ``name`` (the key: names are per
tenant, :mod:`planner_api.tenants`), ``version`` (1 at the first PUT, +1 at each), ``hash``
(SHA-256 of ``body``), ``body`` (the scene's canonical JSON, as the wire writes it),
``bytes`` (the body's UTF-8 length, summed for the tenant's quota), ``updated_at`` and the
counts a listing shows. Why one row: a PUT is one ``INSERT ... ON CONFLICT (tenant, name) DO
UPDATE`` statement, atomic in both databases, so two concurrent PUTs of one name leave one
of them whole (the last to commit wins) and a reader sees a whole scene or the one before,
never a mix. A plan resolves its scene once, at the start (the route reads the row and hands
the scene's obstacles to the job): a PUT during the plan changes the next plans, not this one.

Both stores speak the same SQL (``ON CONFLICT`` upserts exist in SQLite >= 3.24 and
PostgreSQL >= 9.5); only the parameter style, the connection and the locking differ.

Waiting is bounded: every call waits at most the seconds :func:`waiting_at_most` gives its
thread (``PLANNER_STORE_TIMEOUT_S`` less the time the call already queued), for SQLite's
write lock (its busy timeout), for PostgreSQL's connection (``connect_timeout``) and its
locks (``lock_timeout``). A wait that runs out raises one of :func:`unavailable_errors`,
which the service answers 503 ``store_unavailable`` (:mod:`planner_api.store_access`, which
also runs these blocking calls in a thread pool of their own).

**SQLite**: WAL mode, so a read is a plain ``SELECT`` that never waits for a writer; only a
write takes the write lock (``BEGIN IMMEDIATE``), and the quota check and the upsert happen
under it. ``auto_vacuum=INCREMENTAL``: a delete gives its pages back to the file system
(``PRAGMA incremental_vacuum`` after it, then a truncating checkpoint that empties the WAL;
``journal_size_limit`` keeps the WAL file from staying at its largest after the writes). A file made before that mode is converted
once, when it is opened (a ``VACUUM``: it rewrites the file, seconds for hundreds of MB).

**Migration**: a table of the first version (no tenant, ``name`` its key) is rebuilt in
place when a store opens it: every row goes to the tenant ``default``
(:data:`planner_api.tenants.DEFAULT_TENANT`), ``bytes`` computed from the body. In SQLite by
copying into a new table in one transaction (SQLite cannot change a primary key); in
PostgreSQL with ``ALTER TABLE`` under an exclusive lock (the replicas opening it at once
migrate it once).
"""

from __future__ import annotations

import logging
import math
import os
import sqlite3
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from planner_api.exceptions import QuotaExceededError
from planner_api.tenants import DEFAULT_TENANT

__all__ = [
    "PostgresSceneStore",
    "SceneRow",
    "SceneStore",
    "SqliteSceneStore",
    "default_store_path",
    "open_store",
    "unavailable_errors",
    "waiting_at_most",
]

logger = logging.getLogger(__name__)

_COLUMNS = f"""
    tenant TEXT NOT NULL DEFAULT '{DEFAULT_TENANT}',
    name TEXT NOT NULL,
    version BIGINT NOT NULL,
    hash TEXT NOT NULL,
    body TEXT NOT NULL,
    updated_at DOUBLE PRECISION NOT NULL,
    obstacles BIGINT NOT NULL,
    points BIGINT NOT NULL,
    bytes BIGINT NOT NULL DEFAULT 0,
    PRIMARY KEY (tenant, name)
"""
_SCHEMA = f"CREATE TABLE IF NOT EXISTS scenes ({_COLUMNS})"
_UPSERT = """
INSERT INTO scenes (tenant, name, version, hash, body, updated_at, obstacles, points, bytes)
VALUES ({p}, {p}, 1, {p}, {p}, {p}, {p}, {p}, {p})
ON CONFLICT (tenant, name) DO UPDATE SET
    version = scenes.version + 1, hash = excluded.hash, body = excluded.body,
    updated_at = excluded.updated_at, obstacles = excluded.obstacles, points = excluded.points,
    bytes = excluded.bytes
RETURNING name, version, hash, updated_at, obstacles, points
"""
_INFO = "name, version, hash, updated_at, obstacles, points"
#: The tenant's other scenes: their count and bytes (the quota of a PUT).
_USAGE = "SELECT COUNT(*), COALESCE(SUM(bytes), 0) FROM scenes WHERE tenant = {p} AND name <> {p}"
#: The wait of a call when no :func:`waiting_at_most` says otherwise, s.
_DEFAULT_WAIT_S = 3.0
_WAIT = threading.local()
#: Largest WAL file kept after a checkpoint, bytes (SQLite's journal_size_limit).
_WAL_LIMIT_BYTES = 16 * 1024 * 1024
#: The wait of the space reclaim after a delete (best effort), s.
_RECLAIM_WAIT_S = 0.05


@contextmanager
def waiting_at_most(seconds: float) -> Iterator[None]:
    """Within the block, this thread's store calls wait at most ``seconds`` for a lock or a
    connection (module docstring)."""
    saved = getattr(_WAIT, "seconds", None)
    _WAIT.seconds = max(seconds, 0.001)
    try:
        yield
    finally:
        _WAIT.seconds = saved


def _wait_s() -> float:
    seconds = getattr(_WAIT, "seconds", None)
    return _DEFAULT_WAIT_S if seconds is None else seconds


def unavailable_errors() -> tuple[type[BaseException], ...]:
    """The driver errors that mean "the store cannot answer now" (a lock held past the wait,
    a database unreachable or gone, a file that cannot be opened): a 503, never a 500."""
    errors: list[type[BaseException]] = [sqlite3.OperationalError, OSError]
    try:
        import psycopg
    except ImportError:  # pragma: no cover - the postgres extra not installed
        pass
    else:
        errors += [psycopg.OperationalError, psycopg.InterfaceError]
    return tuple(errors)


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
            "name": self.name,
            "version": self.version,
            "hash": self.hash,
            "updated_at": self.updated_at,
            "obstacles": self.obstacles,
            "points": self.points,
        }


class SceneStore(Protocol):
    """What the routes need of a store (each call one transaction, every one of a tenant)."""

    def put(
        self,
        tenant: str,
        name: str,
        body: str,
        digest: str,
        obstacles: int,
        points: int,
        *,
        max_scenes: int | None = None,
        max_bytes: int | None = None,
    ) -> SceneRow:
        """Store ``body`` under ``name`` (a new version; last writer wins), unless the
        tenant's scenes would then pass ``max_scenes`` or their bodies ``max_bytes``
        (:class:`QuotaExceededError`)."""
        ...

    def get(self, tenant: str, name: str, *, body: bool = True) -> SceneRow | None:
        """The scene (with its body unless ``body`` is False), or None."""
        ...

    def list(self, tenant: str) -> list[SceneRow]:
        """Every scene's metadata, by name."""
        ...

    def delete(self, tenant: str, name: str) -> SceneRow | None:
        """Forget the scene; its metadata, or None when there was none."""
        ...

    def ping(self) -> None:
        """A read that answers when the store can (raises when it cannot)."""
        ...

    def close(self) -> None: ...


def _check_quota(
    name: str,
    usage: tuple[Any, Any],
    size: int,
    max_scenes: int | None,
    max_bytes: int | None,
) -> None:
    """:class:`QuotaExceededError` when a PUT of ``size`` bytes under ``name`` takes the
    tenant, whose other scenes are ``usage`` (count, bytes), past a limit."""
    count, stored = int(usage[0]), int(usage[1])
    if max_scenes is not None and count + 1 > max_scenes:
        raise QuotaExceededError(
            f"this tenant stores {count} other scenes, at most {max_scenes} "
            f"(PLANNER_SCENES_MAX): delete one before storing {name!r}",
            422,
            ("path", "name"),
        )
    if max_bytes is not None and stored + size > max_bytes:
        raise QuotaExceededError(
            f"the scene's {size} bytes would bring this tenant's stored scenes to "
            f"{stored + size} bytes, more than {max_bytes} (PLANNER_SCENE_BYTES_MAX)",
            413,
            ("body",),
        )


class _SqlStore:
    """The SQL shared by both stores; ``_write()`` yields a connection in a write
    transaction that commits on exit, ``_read()`` one for plain reads, ``_P`` is the
    driver's parameter marker."""

    _P = "?"

    @contextmanager
    def _write(self, tenant: str) -> Iterator[Any]:  # pragma: no cover - overridden
        raise NotImplementedError
        yield

    @contextmanager
    def _read(self) -> Iterator[Any]:  # pragma: no cover - overridden
        raise NotImplementedError
        yield

    def _row(self, values: Any, body: str | None = None) -> SceneRow:
        name, version, digest, updated, obstacles, points = values
        return SceneRow(
            str(name), int(version), str(digest), float(updated), int(obstacles), int(points), body
        )

    def put(
        self,
        tenant: str,
        name: str,
        body: str,
        digest: str,
        obstacles: int,
        points: int,
        *,
        max_scenes: int | None = None,
        max_bytes: int | None = None,
    ) -> SceneRow:
        size = len(body.encode())
        values = (tenant, name, digest, body, time.time(), obstacles, points, size)
        with self._write(tenant) as con:
            if max_scenes is not None or max_bytes is not None:
                usage = con.execute(_USAGE.format(p=self._P), (tenant, name)).fetchone()
                _check_quota(name, usage, size, max_scenes, max_bytes)
            cur = con.execute(_UPSERT.format(p=self._P), values)
            return self._row(cur.fetchone())

    def get(self, tenant: str, name: str, *, body: bool = True) -> SceneRow | None:
        columns = f"{_INFO}, body" if body else _INFO
        with self._read() as con:
            found = con.execute(
                f"SELECT {columns} FROM scenes WHERE tenant = {self._P} AND name = {self._P}",
                (tenant, name),
            ).fetchone()
        if found is None:
            return None
        return self._row(found[:6], str(found[6]) if body else None)

    def list(self, tenant: str) -> list[SceneRow]:
        with self._read() as con:
            rows = con.execute(
                f"SELECT {_INFO} FROM scenes WHERE tenant = {self._P} ORDER BY name", (tenant,)
            ).fetchall()
        return [self._row(r) for r in rows]

    def delete(self, tenant: str, name: str) -> SceneRow | None:
        with self._write(tenant) as con:
            found = con.execute(
                f"DELETE FROM scenes WHERE tenant = {self._P} AND name = {self._P} "
                f"RETURNING {_INFO}",
                (tenant, name),
            ).fetchone()
        return None if found is None else self._row(found)

    def ping(self) -> None:
        with self._read() as con:
            con.execute("SELECT 1").fetchone()


class SqliteSceneStore(_SqlStore):
    """Scenes in one SQLite file (created with its folder on first use), in WAL mode so that
    readers never wait for a writer (module docstring). A connection per call: sqlite3
    connections belong to one thread, and opening a file costs microseconds."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        con = self._open()
        try:  # outside a transaction: SQLite refuses to change these inside one
            if con.execute("PRAGMA auto_vacuum").fetchone()[0] != 2:
                con.execute("PRAGMA auto_vacuum=INCREMENTAL")  # a new file: from its start
            con.execute("PRAGMA journal_mode=WAL")
            self._migrate(con)
            if con.execute("PRAGMA auto_vacuum").fetchone()[0] != 2:
                # a file made before: the mode takes effect with a VACUUM (rewrites the file)
                logger.info("converting the scene store %s to auto_vacuum=INCREMENTAL", path)
                try:
                    con.execute("VACUUM")
                except sqlite3.OperationalError as exc:  # busy: converted at a later start
                    logger.warning("scene store %s not converted now: %s", path, exc)
        finally:
            con.close()

    def _open(self) -> sqlite3.Connection:
        con = sqlite3.connect(self.path, timeout=_wait_s(), isolation_level=None)
        con.execute(f"PRAGMA journal_size_limit={_WAL_LIMIT_BYTES}")
        return con

    def _migrate(self, con: sqlite3.Connection) -> None:
        """Create the table, or rebuild one of the first version (module docstring)."""
        con.execute("BEGIN IMMEDIATE")
        try:
            columns = {row[1] for row in con.execute("PRAGMA table_info(scenes)")}
            if not columns:
                con.execute(_SCHEMA)
            elif "tenant" not in columns:
                logger.info(
                    "migrating the scene store %s: scenes of tenant %r", self.path, DEFAULT_TENANT
                )
                con.execute(f"CREATE TABLE scenes_v2 ({_COLUMNS})")
                con.execute(
                    "INSERT INTO scenes_v2 (tenant, name, version, hash, body, updated_at, "
                    "obstacles, points, bytes) SELECT ?, name, version, hash, body, updated_at, "
                    "obstacles, points, length(CAST(body AS BLOB)) FROM scenes",
                    (DEFAULT_TENANT,),
                )
                con.execute("DROP TABLE scenes")
                con.execute("ALTER TABLE scenes_v2 RENAME TO scenes")
        except BaseException:
            con.execute("ROLLBACK")
            raise
        con.execute("COMMIT")

    @contextmanager
    def _write(self, tenant: str) -> Iterator[sqlite3.Connection]:
        con = self._open()
        try:
            con.execute("BEGIN IMMEDIATE")  # waits for the write lock at most _wait_s()
            try:
                yield con
            except BaseException:
                con.execute("ROLLBACK")
                raise
            con.execute("COMMIT")
        finally:
            con.close()

    @contextmanager
    def _read(self) -> Iterator[sqlite3.Connection]:
        con = self._open()  # autocommit: each SELECT reads the last commit, takes no lock
        try:
            yield con
        finally:
            con.close()

    def delete(self, tenant: str, name: str) -> SceneRow | None:
        found = super().delete(tenant, name)
        if found is not None:
            self._reclaim()
        return found

    def _reclaim(self) -> None:
        """Give the deleted scene's pages back: the free pages are cut off the file (an
        incremental vacuum), and a checkpoint moves that into the file and empties the WAL.
        Best effort, with a short wait of its own: a busy store reclaims at a later delete.
        (Through ``executescript``: a plain ``execute`` steps the pragma once, which frees
        one page.)"""
        con = sqlite3.connect(self.path, timeout=_RECLAIM_WAIT_S, isolation_level=None)
        try:
            con.executescript("PRAGMA incremental_vacuum;")
            con.execute("PRAGMA wal_checkpoint(TRUNCATE)").fetchall()
        except sqlite3.OperationalError as exc:
            logger.info("scene store space not reclaimed now: %s", exc)
        finally:
            con.close()

    def close(self) -> None:
        """Nothing stays open between calls."""


class PostgresSceneStore(_SqlStore):
    """Scenes in a PostgreSQL database (``postgresql://`` URL; the driver is psycopg 3,
    imported only here). A connection per thread (the store's threads are few and fixed,
    :mod:`planner_api.store_access`), re-opened when lost; every wait bounded (module
    docstring). A write first takes a transaction-scoped advisory lock on its tenant, so
    that two PUTs of one tenant check the quota one after the other."""

    _P = "%s"

    def __init__(self, url: str) -> None:
        self.url = url
        self._local = threading.local()
        self._lock = threading.Lock()
        self._all: list[Any] = []
        with self._transaction() as con:
            con.execute(_SCHEMA)
        self._migrate()

    def _connection(self) -> Any:
        import psycopg

        con = getattr(self._local, "con", None)
        if con is None or con.closed or con.broken:
            # libpq's connect_timeout is whole seconds, at least 2
            con = psycopg.connect(
                self.url, connect_timeout=max(2, math.ceil(_wait_s())), autocommit=True
            )
            self._local.con = con
            with self._lock:
                self._all = [c for c in self._all if not c.closed]
                self._all.append(con)
        return con

    @contextmanager
    def _transaction(self) -> Iterator[Any]:
        import psycopg

        con = self._connection()
        try:
            with con.transaction():
                con.execute(f"SET LOCAL lock_timeout = {max(1, round(_wait_s() * 1000))}")
                yield con
        except psycopg.OperationalError:
            if con.broken or con.closed:
                con.close()
                self._local.con = None
            raise

    @contextmanager
    def _write(self, tenant: str) -> Iterator[Any]:
        with self._transaction() as con:
            con.execute("SELECT pg_advisory_xact_lock(hashtext(%s))", (tenant,))
            yield con

    _read = _transaction

    def _migrate(self) -> None:
        """Move a table of the first version to tenants (module docstring)."""
        columns_sql = (
            "SELECT column_name FROM information_schema.columns "
            "WHERE table_name = 'scenes' AND table_schema = current_schema()"
        )
        with self._transaction() as con:
            if "tenant" in {r[0] for r in con.execute(columns_sql)}:
                return
            con.execute("LOCK TABLE scenes IN ACCESS EXCLUSIVE MODE")
            if "tenant" in {r[0] for r in con.execute(columns_sql)}:
                return  # another replica migrated it while this one waited
            logger.info("migrating the scene store: scenes of tenant %r", DEFAULT_TENANT)
            key = con.execute(
                "SELECT constraint_name FROM information_schema.table_constraints WHERE "
                "table_name = 'scenes' AND table_schema = current_schema() AND "
                "constraint_type = 'PRIMARY KEY'"
            ).fetchone()
            con.execute(
                f"ALTER TABLE scenes ADD COLUMN tenant TEXT NOT NULL DEFAULT '{DEFAULT_TENANT}',"
                " ADD COLUMN bytes BIGINT NOT NULL DEFAULT 0"
            )
            con.execute("UPDATE scenes SET bytes = octet_length(body)")
            if key is not None:
                con.execute(f'ALTER TABLE scenes DROP CONSTRAINT "{key[0]}"')
            con.execute("ALTER TABLE scenes ADD PRIMARY KEY (tenant, name)")

    def close(self) -> None:
        with self._lock:
            for con in self._all:
                con.close()
            self._all = []


def default_store_path() -> Path:
    """Where scenes live without ``PLANNER_SCENE_STORE``: ``$XDG_DATA_HOME/planner/
    scenes.sqlite3`` (``~/.local/share`` when XDG_DATA_HOME is unset)."""
    base = os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share"
    return Path(base) / "planner" / "scenes.sqlite3"


def open_store(setting: str | None) -> SceneStore:
    """The store a ``PLANNER_SCENE_STORE`` value names: a ``postgresql://`` (or
    ``postgres://``) URL, else a SQLite file path (None or empty: :func:`default_store_path`).
    Opening it waits as a call does (:func:`waiting_at_most`)."""
    if setting and setting.startswith(("postgresql://", "postgres://")):
        return PostgresSceneStore(setting)
    return SqliteSceneStore(setting or default_store_path())
