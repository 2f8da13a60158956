"""Where long jobs (``POST /v1/jobs``) live: a ``jobs`` table in the scene store's database
(``PLANNER_SCENE_STORE``: the SQLite file of one replica, or the PostgreSQL database every
replica shares), so that a job outlives the process that accepted it and any replica answers
for it.

One row per job: ``id``, ``tenant``, ``kind``, ``status`` (``queued``, ``running``, ``done``,
``failed``, ``cancelled``), the times (``submitted_at``, ``started_at``, ``finished_at``,
``expires_at``, Unix s), ``owner`` (the id of the replica that runs it, random at each start),
``heartbeat_at`` (the owner's last sign of life, Unix s), ``error`` (the
:class:`planner.wire.JobError` JSON of a failed job), ``result`` (the endpoint's answer, its
JSON bytes) and ``bytes`` (the result's length, summed for the bound of all results).

Why an owner and a heartbeat: a replica that dies leaves its unfinished rows behind. Each
replica refreshes ``heartbeat_at`` of its unfinished rows every :data:`HEARTBEAT_S`; a
``queued`` or ``running`` row whose heartbeat is older than :data:`STALE_S` is answered
``failed`` with the error type ``lost_on_restart`` (503 in its ``error``), and marked so at
the next submit (which counts the unfinished jobs). A replica that stops on its own (SIGTERM,
a deploy) marks its unfinished rows so at once (:meth:`JobTable.lose_owned`). The times are
the replicas' wall clocks: they must agree within a second or so (NTP).

Each method is one transaction, run in a store thread (:mod:`planner_api.store_access`);
the writes that count or evict (a submit, a finish) hold a lock of their own (SQLite's write
lock; in PostgreSQL a transaction-scoped advisory lock on :data:`_LOCK_KEY`), so two replicas
submitting at once cannot both take the last place.
"""

from __future__ import annotations

import builtins
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import Any

from planner.wire import ErrorItem, JobError
from planner_api.exceptions import TenantJobsError, TooManyJobsError

__all__ = [
    "HEARTBEAT_S",
    "STALE_S",
    "JobRow",
    "JobTable",
    "lost_error",
]

#: Seconds between two heartbeats of a replica's unfinished jobs.
HEARTBEAT_S = 2.0
#: A queued or running job whose owner's heartbeat is older than this is lost, s.
STALE_S = 3 * HEARTBEAT_S
#: The advisory lock of the counting writes (PostgreSQL); ``:`` is in no tenant's name.
_LOCK_KEY = "jobs:"
_UNFINISHED = "('queued', 'running')"
_META = "id, tenant, kind, status, submitted_at, started_at, finished_at, expires_at, error"


def _schema(blob: str) -> list[str]:
    return [
        f"""CREATE TABLE IF NOT EXISTS jobs (
            id TEXT PRIMARY KEY,
            tenant TEXT NOT NULL,
            kind TEXT NOT NULL,
            status TEXT NOT NULL,
            submitted_at DOUBLE PRECISION NOT NULL,
            started_at DOUBLE PRECISION,
            finished_at DOUBLE PRECISION,
            expires_at DOUBLE PRECISION,
            owner TEXT,
            heartbeat_at DOUBLE PRECISION,
            error TEXT,
            result {blob},
            bytes BIGINT NOT NULL DEFAULT 0
        )""",
        "CREATE INDEX IF NOT EXISTS jobs_by_tenant ON jobs (tenant, submitted_at)",
        "CREATE INDEX IF NOT EXISTS jobs_by_owner ON jobs (owner, status)",
    ]


def lost_error(why: str) -> JobError:
    """The error of a job whose replica stopped before it finished (503 ``lost_on_restart``)."""
    return JobError(
        status_code=503,
        detail=[ErrorItem(loc=[], type="lost_on_restart", msg=f"{why}; submit it again")],
    )


#: Why a row whose owner stopped heartbeating is failed.
_STALE_WHY = (
    f"the service replica that held this job stopped (a crash or a restart) before it "
    f"finished: no heartbeat for more than {STALE_S:g} s"
)
#: Why a row is failed when its own replica stops.
STOPPED_WHY = "the service restarted (or stopped) while this job was queued or running"


@dataclass(frozen=True, slots=True)
class JobRow:
    """A job as stored (``result`` only when it was asked for)."""

    id: str
    tenant: str
    kind: str
    status: str
    submitted_at: float
    started_at: float | None = None
    finished_at: float | None = None
    expires_at: float | None = None
    error: JobError | None = None
    result: bytes | None = None

    @property
    def finished(self) -> bool:
        return self.status not in ("queued", "running")


class JobTable:
    """The ``jobs`` table of an opened scene store (:mod:`planner_api.scene_store`): its
    ``_write(key)`` and ``_read()`` connections and its parameter marker ``_P``.

    Parameters
    ----------
    store : SqliteSceneStore or PostgresSceneStore
        The opened store; the table is created in it if missing.
    ttl_s : float
        How long a finished job is kept, s (``PLANNER_JOB_TTL_S``).
    """

    def __init__(self, store: Any, *, ttl_s: float) -> None:
        self.store = store
        self.ttl_s = ttl_s
        self._p = store._P
        self._sqlite = self._p == "?"
        #: Whether the table is known to exist (created by the first write otherwise).
        self._created = False

    @contextmanager
    def _write(self, key: str) -> Iterator[Any]:
        """A write transaction (``key``: PostgreSQL's advisory lock), the table created in it
        first if it may be missing. Why at the first write and not at the store's opening: a
        read must not need the write lock (a held SQLite lock leaves job reads answering)."""
        created = self._created
        with self.store._write(key if created else _LOCK_KEY) as con:
            if not created:
                for statement in _schema("BLOB" if self._sqlite else "BYTEA"):
                    con.execute(statement)
            yield con
        self._created = True

    @contextmanager
    def _read(self) -> Iterator[Any | None]:
        """A connection for plain reads, or None when the table does not exist yet (no job
        was ever submitted to this database: every read answers nothing)."""
        with self.store._read() as con:
            if not self._created:
                sql = (
                    "SELECT name FROM sqlite_master WHERE type = 'table' AND name = 'jobs'"
                    if self._sqlite
                    else "SELECT to_regclass('jobs')"
                )
                found = con.execute(sql).fetchone()
                if found is None or found[0] is None:
                    yield None
                    return
                self._created = True
            yield con

    def _row(self, values: Any, *, now: float, result: Any = None) -> JobRow:
        jid, tenant, kind, status, submitted, started, finished, expires, error = values[:9]
        row = JobRow(
            id=str(jid),
            tenant=str(tenant),
            kind=str(kind),
            status=str(status),
            submitted_at=float(submitted),
            started_at=started,
            finished_at=finished,
            expires_at=expires,
            error=None if error is None else JobError.model_validate_json(error),
            result=None if result is None else bytes(result),
        )
        heartbeat = values[9]
        if not row.finished and heartbeat is not None and heartbeat < now - STALE_S:
            row = replace(
                row,
                status="failed",
                finished_at=float(heartbeat),
                expires_at=float(heartbeat) + self.ttl_s,
                error=lost_error(_STALE_WHY),
            )
        return row

    def _housekeeping(self, con: Any, now: float) -> None:
        """Forget the expired jobs, fail the lost ones (in a write transaction)."""
        p = self._p
        con.execute(f"DELETE FROM jobs WHERE expires_at <= {p}", (now,))
        con.execute(
            f"UPDATE jobs SET status = 'failed', error = {p}, finished_at = heartbeat_at, "
            f"expires_at = heartbeat_at + {p} WHERE status IN {_UNFINISHED} "
            f"AND heartbeat_at < {p}",
            (lost_error(_STALE_WHY).model_dump_json(), self.ttl_s, now - STALE_S),
        )

    def insert(
        self, row: JobRow, owner: str, *, max_jobs: int, per_tenant: int, retry_after_s: int
    ) -> None:
        """Store a new ``queued`` job of ``owner``, unless the table holds ``max_jobs`` and
        none of them is finished (:class:`TooManyJobsError`, 503) or its tenant has
        ``per_tenant`` unfinished jobs (:class:`TenantJobsError`, 429); the oldest finished
        jobs are evicted to make room (not when it is refused: one transaction)."""
        p, now = self._p, time.time()
        with self._write(_LOCK_KEY) as con:
            self._housekeeping(con, now)
            (kept,) = con.execute("SELECT COUNT(*) FROM jobs").fetchone()
            if int(kept) >= max_jobs:
                excess = int(kept) - max_jobs + 1
                old = con.execute(
                    f"SELECT id FROM jobs WHERE status NOT IN {_UNFINISHED} "
                    f"ORDER BY submitted_at, id LIMIT {p}",
                    (excess,),
                ).fetchall()
                if len(old) < excess:
                    raise TooManyJobsError(
                        f"{kept} long jobs are kept and none of them has finished (at most "
                        f"{max_jobs}, PLANNER_MAX_JOBS, over every replica); retry when one "
                        "has finished",
                        retry_after_s=retry_after_s,
                    )
                for (jid,) in old:
                    con.execute(f"DELETE FROM jobs WHERE id = {p}", (jid,))
            (mine,) = con.execute(
                f"SELECT COUNT(*) FROM jobs WHERE tenant = {p} AND status IN {_UNFINISHED}",
                (row.tenant,),
            ).fetchone()
            if int(mine) >= per_tenant:
                raise TenantJobsError(
                    f"this tenant has {mine} long jobs queued or running, at most "
                    f"{per_tenant} (PLANNER_JOBS_PER_TENANT); retry when one has finished",
                    retry_after_s=retry_after_s,
                )
            con.execute(
                f"INSERT INTO jobs (id, tenant, kind, status, submitted_at, owner, heartbeat_at)"
                f" VALUES ({p}, {p}, {p}, 'queued', {p}, {p}, {p})",
                (row.id, row.tenant, row.kind, row.submitted_at, owner, now),
            )

    def get(self, tenant: str, job_id: str) -> JobRow | None:
        """The job with its result, or None (no such job of ``tenant``, or expired)."""
        p, now = self._p, time.time()
        with self._read() as con:
            if con is None:
                return None
            found = con.execute(
                f"SELECT {_META}, heartbeat_at, result FROM jobs WHERE id = {p} AND "
                f"tenant = {p} AND (expires_at IS NULL OR expires_at > {p})",
                (job_id, tenant, now),
            ).fetchone()
        if found is None:
            return None
        return self._row(found, now=now, result=found[10] if found[3] == "done" else None)

    def list(self, tenant: str) -> list[JobRow]:
        """The tenant's jobs still kept, in submission order (no results)."""
        p, now = self._p, time.time()
        with self._read() as con:
            if con is None:
                return []
            rows = con.execute(
                f"SELECT {_META}, heartbeat_at FROM jobs WHERE tenant = {p} AND "
                f"(expires_at IS NULL OR expires_at > {p}) ORDER BY submitted_at, id",
                (tenant, now),
            ).fetchall()
        return [self._row(r, now=now) for r in rows]

    def start(self, job_id: str) -> bool:
        """Mark the job ``running`` now; False when it is no longer queued (cancelled, lost)."""
        p, now = self._p, time.time()
        with self._write(job_id) as con:
            found = con.execute(
                f"UPDATE jobs SET status = 'running', started_at = {p}, heartbeat_at = {p} "
                f"WHERE id = {p} AND status IN {_UNFINISHED} RETURNING id",
                (now, now, job_id),
            ).fetchone()
        return found is not None

    def finish(
        self,
        job_id: str,
        status: str,
        *,
        result: bytes | None = None,
        error: JobError | None = None,
        max_total_bytes: int,
    ) -> None:
        """End the job (unless it ended already: a cancel wins). A result evicts the oldest
        finished jobs with results until all the results fit ``max_total_bytes``."""
        p, now = self._p, time.time()
        size = 0 if result is None else len(result)
        with self._write(_LOCK_KEY) as con:
            self._housekeeping(con, now)
            if size:
                (held,) = con.execute("SELECT COALESCE(SUM(bytes), 0) FROM jobs").fetchone()
                held = int(held)
                if held + size > max_total_bytes:
                    rows = con.execute(
                        f"SELECT id, bytes FROM jobs WHERE bytes > 0 AND status NOT IN "
                        f"{_UNFINISHED} ORDER BY submitted_at, id"
                    ).fetchall()
                    for jid, nbytes in rows:
                        if held + size <= max_total_bytes:
                            break
                        con.execute(f"DELETE FROM jobs WHERE id = {p}", (jid,))
                        held -= int(nbytes)
            con.execute(
                f"UPDATE jobs SET status = {p}, result = {p}, bytes = {p}, error = {p}, "
                f"finished_at = {p}, expires_at = {p} WHERE id = {p} AND status IN {_UNFINISHED}",
                (
                    status,
                    result,
                    size,
                    None if error is None else error.model_dump_json(),
                    now,
                    now + self.ttl_s,
                    job_id,
                ),
            )

    def cancel(self, tenant: str, job_id: str) -> JobRow | None:
        """Mark a queued or running job of ``tenant`` ``cancelled`` (its owner's poll stops
        it); the job as it is then, or None when there is none. A finished job is left."""
        p, now = self._p, time.time()
        with self._write(job_id) as con:
            con.execute(
                f"UPDATE jobs SET status = 'cancelled', finished_at = {p}, expires_at = {p} "
                f"WHERE id = {p} AND tenant = {p} AND status IN {_UNFINISHED} "
                f"AND heartbeat_at >= {p}",
                (now, now + self.ttl_s, job_id, tenant, now - STALE_S),
            )
        return self.get(tenant, job_id)

    # ``builtins.list``: in the class body, ``list`` is the method :meth:`list`
    def ended(self, job_ids: builtins.list[str]) -> builtins.list[str]:
        """Which of ``job_ids`` are no longer queued or running in the table (cancelled by
        another replica, failed as lost, or gone)."""
        p, still = self._p, set[str]()
        with self._read() as con:
            if con is None:
                return list(job_ids)
            for start in range(0, len(job_ids), 500):
                chunk = job_ids[start : start + 500]
                marks = ", ".join([p] * len(chunk))
                still.update(
                    r[0]
                    for r in con.execute(
                        f"SELECT id FROM jobs WHERE id IN ({marks}) AND status IN {_UNFINISHED}",
                        chunk,
                    ).fetchall()
                )
        return [j for j in job_ids if j not in still]

    def heartbeat(self, owner: str) -> None:
        """Refresh the heartbeat of ``owner``'s unfinished jobs."""
        p = self._p
        with self._write(f"jobs-heartbeat:{owner}") as con:
            con.execute(
                f"UPDATE jobs SET heartbeat_at = {p} WHERE owner = {p} AND status IN {_UNFINISHED}",
                (time.time(), owner),
            )

    def lose_owned(self, owner: str) -> None:
        """Fail ``owner``'s unfinished jobs as lost (its replica is stopping)."""
        p, now = self._p, time.time()
        with self._write(f"jobs-heartbeat:{owner}") as con:
            con.execute(
                f"UPDATE jobs SET status = 'failed', error = {p}, finished_at = {p}, "
                f"expires_at = {p} WHERE owner = {p} AND status IN {_UNFINISHED}",
                (lost_error(STOPPED_WHY).model_dump_json(), now, now + self.ttl_s, owner),
            )

    def sweep(self) -> None:
        """Forget the expired jobs and fail the lost ones now (at a replica's start)."""
        with self._write(_LOCK_KEY) as con:
            self._housekeeping(con, time.time())
