"""A worker's states as one table (:mod:`planner_api.pool.states`): every legal move goes
where the table says, every other (state, event) is refused with an error naming both and a
log line, the docstring's drawing is the table, and the pool changes a worker's state only
through it."""

from __future__ import annotations

import ast
import itertools
import logging
from pathlib import Path
from types import SimpleNamespace

import pytest

from planner_api.pool import WorkerPool
from planner_api.pool import states as states_module
from planner_api.pool.handle import Worker
from planner_api.pool.states import (
    TRANSITIONS,
    IllegalTransitionError,
    WorkerEvent,
    WorkerState,
    next_state,
)

POOL = Path(__file__).resolve().parents[2] / "api" / "pool"
ILLEGAL = [
    (s, e) for s, e in itertools.product(WorkerState, WorkerEvent) if (s, e) not in TRANSITIONS
]


def _worker(state: WorkerState = WorkerState.STARTING) -> Worker:
    process = SimpleNamespace(pid=4242)  # what the pool's log lines read of a process
    worker = Worker(process=process, jobs=None, answers=None)  # type: ignore[arg-type]
    worker.state = state
    return worker


@pytest.mark.parametrize(("state", "event"), list(TRANSITIONS))
def test_each_legal_move_goes_where_the_table_says(state, event):
    worker = _worker(state)
    assert worker.change(event) is state
    assert worker.state is TRANSITIONS[(state, event)] is next_state(state, event)


@pytest.mark.parametrize(("state", "event"), ILLEGAL)
def test_each_illegal_move_is_refused_named_and_logged(state, event, caplog):
    worker = _worker(state)
    with caplog.at_level(logging.ERROR, logger="planner_api.pool"):
        with pytest.raises(IllegalTransitionError) as raised:
            worker.change(event)
    assert (raised.value.state, raised.value.event) == (state, event)
    assert state.value in str(raised.value) and event.value in str(raised.value)
    assert worker.state is state, "an illegal move changed the state"
    assert any(
        state.value in r.getMessage() and event.value in r.getMessage() for r in caplog.records
    )


def test_the_table_covers_the_life_of_a_worker():
    """Some moves are illegal (a table that allowed everything would check nothing), every
    state can end (``exit`` from each), and ``gone`` is the end: nothing leaves it."""
    assert len(ILLEGAL) > len(TRANSITIONS)
    assert all(TRANSITIONS[(s, WorkerEvent.EXIT)] is WorkerState.GONE for s in WorkerState)
    assert {new for (s, _), new in TRANSITIONS.items() if s is WorkerState.GONE} == {
        WorkerState.GONE
    }


def test_the_docstring_draws_the_table():
    """The grid in the module's docstring, read back, is :data:`TRANSITIONS` exactly."""
    doc = states_module.__doc__
    assert doc is not None
    lines = doc.splitlines()
    head = next(i for i, line in enumerate(lines) if "state \\ event" in line)
    events = [WorkerEvent(e) for e in lines[head].split()[3:]]
    drawn = {}
    for line in lines[head + 1 : head + 1 + len(WorkerState)]:
        state, *cells = line.split()
        for event, cell in zip(events, cells, strict=True):
            if cell != ".":
                drawn[(WorkerState(state), event)] = WorkerState(cell)
    assert sorted(events) == sorted(WorkerEvent)
    assert drawn == TRANSITIONS


def test_the_pool_changes_a_state_only_through_the_table():
    """No module of the pool assigns a worker's ``state`` but :meth:`Worker.change` (the
    template's own ``self.state`` is the template's, an error's is the refused state)."""
    found = []
    for path in sorted(POOL.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            targets = []
            if isinstance(node, ast.Assign):
                targets = [t for e in node.targets for t in getattr(e, "elts", [e])]
            elif isinstance(node, ast.AugAssign | ast.AnnAssign):
                targets = [node.target]
            for t in targets:
                if isinstance(t, ast.Attribute) and t.attr == "state":
                    found.append((path.name, node.lineno, ast.unparse(t)))
    allowed = {(f, "self.state") for f in ("handle.py", "states.py", "template.py")}
    assert [f for f in found if (f[0], f[2]) not in allowed] == []
    assert any(f[0] == "handle.py" for f in found), "the check found not even change()"


def test_a_message_the_table_refuses_leaves_the_pool_as_it_was():
    """The pool consults the table before it acts: an answer from a worker that runs no job
    is an internal error, and neither the job count nor the worker's state moves."""
    pool = WorkerPool(1, 0, template=False)
    worker = _worker()
    pool._workers.append(worker)
    with pytest.raises(IllegalTransitionError):
        pool._on_done(worker, "ok", 1)
    assert worker.state is WorkerState.STARTING and pool.in_flight == 0
    pool._on_ready(worker, 0.0)
    assert worker.state is WorkerState.WARM and pool.warm_workers == 1
    with pytest.raises(IllegalTransitionError):
        pool._on_ready(worker, 0.0)
    assert worker.state is WorkerState.WARM
