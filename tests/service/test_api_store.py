"""The scene store's availability over HTTP: a SQLite write lock held by another connection
(``BEGIN IMMEDIATE`` in the test) leaves the scene reads answering 200 (WAL), makes a PUT
or DELETE a 503 ``store_unavailable`` with ``Retry-After`` naming the bound, and leaves the
other routes answering while PUTs wait; PostgreSQL stopped (a server of the test's own):
the scene routes and a plan naming a scene are 503 ``store_unavailable``, ``/v1/ready`` is a
503 naming the store, and all of it recovers when the server is back.

The oracle of "the other routes answer meanwhile" is an order, not a time: once the store's
pool is full of PUTs waiting on the lock, ``GET /v1/jobs/<x>`` and ``/v1/health`` are asked
and answered while those PUTs are still unanswered (they wait PLANNER_STORE_TIMEOUT_S).
"""

from __future__ import annotations

import sqlite3
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

START = {"q": [0.3, 2.0, 1.0], "assembly_mode": "+"}
GOAL = {"q": [-0.6, 1.4, 0.7], "assembly_mode": "+"}
SPHERE = {"type": "sphere", "center": [5, 5, 5], "radius": 0.1}


def _unavailable(r) -> str:
    """The message of a 503 store_unavailable answer (asserting that it is one)."""
    assert r.status_code == 503, r.text
    assert int(r.headers["retry-after"]) >= 1
    (item,) = r.json()["detail"]
    assert item["type"] == "store_unavailable" and item["loc"] == []
    return item["msg"]


@pytest.fixture
def locked_store(client_factory, tmp_path, request):
    """A service with a SQLite store holding one scene, and a function that holds the
    file's write lock from another connection (released at the end). Its store timeout is
    the test's indirect parameter, s (1 s when none: each write refused costs that)."""
    timeout = getattr(request, "param", 1)
    path = str(tmp_path / "scenes.db")
    holders: list[sqlite3.Connection] = []

    def hold() -> None:
        con = sqlite3.connect(path, isolation_level=None)
        con.execute("BEGIN IMMEDIATE")
        holders.append(con)

    with client_factory(
        scene_store=path, store_timeout_s=timeout, store_threads=2, warm=False
    ) as c:
        assert c.put("/v1/scenes/kept", json={"obstacles": [SPHERE]}).status_code == 200
        try:
            yield c, hold
        finally:
            for con in holders:
                con.execute("ROLLBACK")
                con.close()


def test_a_held_write_lock_leaves_reads_and_fails_writes_with_503(locked_store):
    c, hold = locked_store
    hold()
    got = c.get("/v1/scenes/kept")
    assert got.status_code == 200 and got.json()["scene"]["obstacles"] == [SPHERE]
    assert [s["name"] for s in c.get("/v1/scenes").json()["scenes"]] == ["kept"]
    # a plan naming the scene reads it: it is served (the worker answers or not, no 503)
    plan = c.post(
        "/v1/plan",
        json={"start": START, "goal": GOAL, "scene": "kept", "timing": {"method": "none"}},
    )
    assert plan.status_code == 200, plan.text
    msg = _unavailable(c.put("/v1/scenes/new", json={"obstacles": []}))
    assert "1 s (PLANNER_STORE_TIMEOUT_S)" in msg and "nothing was changed" in msg
    _unavailable(c.delete("/v1/scenes/kept"))
    assert c.get("/v1/ready").json()["store"] == "ok"  # reads answer: the store is up


# a 3 s store timeout: the PUTs still wait while the other routes answer
@pytest.mark.parametrize("locked_store", [3], indirect=True)
def test_other_routes_answer_while_puts_wait_on_the_lock(locked_store):
    """12 PUTs wait on the held lock (2 write threads + 8 waiting, the rest refused at
    once): meanwhile a job poll, the health and readiness probes and a scene's GET answer;
    then every PUT is a 503, some of them refused at once because the write lane was full."""
    c, hold = locked_store
    access = c.app.state.scene_access.writes
    hold()
    with ThreadPoolExecutor(12) as ex:
        puts = [ex.submit(c.put, f"/v1/scenes/w{i}", json={"obstacles": []}) for i in range(12)]
        while access.in_flight < access.capacity and not all(f.done() for f in puts):
            time.sleep(0.01)  # until the store's pool is full of waiting PUTs
        job = c.get("/v1/jobs/0123456789abcdef")
        health = c.get("/v1/health")
        scene = c.get("/v1/scenes/kept")  # reads have a lane of their own
        ready = c.get("/v1/ready")
        waiting = sum(not f.done() for f in puts)
        answers = [f.result() for f in puts]
    assert job.status_code == 404 and job.json()["detail"][0]["type"] == "job_not_found"
    assert health.status_code == 200 and scene.status_code == 200
    assert ready.status_code == 200 and ready.json()["store"] == "ok"
    assert waiting > 0  # the two answers came while PUTs still waited on the lock
    messages = [_unavailable(r) for r in answers]
    assert any("PLANNER_STORE_THREADS" in m for m in messages)  # the pool refused at once
    assert any("PLANNER_STORE_TIMEOUT_S" in m for m in messages)  # the others waited
    assert [s["name"] for s in c.get("/v1/scenes").json()["scenes"]] == ["kept"]


def test_postgresql_stopped_is_503_and_ready_names_the_store(client_factory, postgres_factory):
    body = {"start": START, "goal": GOAL, "scene": "cell", "timing": {"method": "none"}}
    with postgres_factory() as server:
        with client_factory(scene_store=server.url, store_timeout_s=2, warm=False) as c:
            assert c.put("/v1/scenes/cell", json={"obstacles": [SPHERE]}).status_code == 200
            ready = c.get("/v1/ready")
            assert ready.status_code == 200 and ready.json()["store"] == "ok"
            server.stop()
            for r in (
                c.get("/v1/scenes/cell"),
                c.get("/v1/scenes"),
                c.put("/v1/scenes/other", json={"obstacles": []}),
                c.delete("/v1/scenes/cell"),
                c.post("/v1/plan", json=body),
                c.post("/v1/plan/batch", json={"requests": [body]}),
                c.post("/v1/jobs", json={"kind": "plan", "request": body}),
                c.post("/v1/jobs", json={"kind": "regions", "request": {}}),  # no scene
                c.get("/v1/jobs/0123"),  # the jobs live in the store too
                c.get("/v1/jobs"),
                c.delete("/v1/jobs/0123"),
            ):
                assert "postgresql" in _unavailable(r)
            ready = c.get("/v1/ready")
            assert ready.status_code == 503, ready.text
            got = ready.json()
            assert (got["status"], got["store"]) == ("store_unavailable", "unavailable")
            assert "postgresql" in got["store_error"]
            assert c.get("/v1/health").status_code == 200
            server.start()
            assert c.get("/v1/scenes/cell").json()["scene"]["obstacles"] == [SPHERE]
            assert c.post("/v1/plan", json=body).status_code == 200
            assert c.get("/v1/ready").json()["store"] == "ok"
