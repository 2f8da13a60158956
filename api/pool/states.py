"""The life of one worker process as the pool sees it: five states, the events that move a
worker between them, and one table of every legal move. The pool changes a worker's state
only through :func:`next_state` (by :meth:`planner_api.pool.handle.Worker.change`), so a
move the table does not hold is an internal error, logged and raised
(:class:`IllegalTransitionError`), never a silent change.

The table (a row per state, a column per event; ``.``: illegal)::

    state \\ event  ready  take  done     kill     retire   lost  exit
    starting       warm   .     .        .        .        .     gone
    warm           .      busy  .        .        killing  gone  gone
    busy           .      .     warm     killing  .        .     gone
    killing        .      .     killing  .        killing  .     gone
    gone           .      .     .        .        .        .     gone

The states: ``starting`` (spawned or forked, its "ready" not yet read), ``warm`` (waits for a
job), ``busy`` (runs one), ``killing`` (the pool is ending it, its exit expected: SIGKILLed by
the watchdog, its job cancelled or past its deadline, or told to stop, recycled once its
replacement is warm; why is :attr:`~planner_api.pool.handle.Worker.killed`), ``gone`` (its exit
was seen, or its jobs pipe broke).

The events: ``ready`` (its warm-up is done), ``take`` (a job went down its pipe), ``done`` (its
job's answer came: a killed worker stays ``killing``, its answer having been written before the
kill landed), ``kill`` (the watchdog's SIGKILL), ``retire`` (told to stop; a killed worker whose
answer came before its replacement was warm is retired too), ``lost`` (a job could not be
written to its pipe: it died, its exit not yet seen), ``exit`` (its exit was seen: from every
state, at once for one never warm, after ``lost`` for one whose pipe broke).

A shutdown moves no worker until its exit is seen: it stops them all, whatever their state.
"""

from __future__ import annotations

import enum
import logging

__all__ = ["TRANSITIONS", "IllegalTransitionError", "WorkerEvent", "WorkerState", "next_state"]

logger = logging.getLogger("planner_api.pool")


class WorkerState(enum.StrEnum):
    """Where a worker is in its life (the module's table)."""

    STARTING = "starting"
    WARM = "warm"
    BUSY = "busy"
    KILLING = "killing"
    GONE = "gone"


class WorkerEvent(enum.StrEnum):
    """What happens to a worker (the module's table)."""

    READY = "ready"
    TAKE = "take"
    DONE = "done"
    KILL = "kill"
    RETIRE = "retire"
    LOST = "lost"
    EXIT = "exit"


_S, _E = WorkerState, WorkerEvent

#: Every legal move: (state, event) -> the new state (drawn in the module's docstring).
TRANSITIONS: dict[tuple[WorkerState, WorkerEvent], WorkerState] = {
    (_S.STARTING, _E.READY): _S.WARM,
    (_S.STARTING, _E.EXIT): _S.GONE,
    (_S.WARM, _E.TAKE): _S.BUSY,
    (_S.WARM, _E.RETIRE): _S.KILLING,
    (_S.WARM, _E.LOST): _S.GONE,
    (_S.WARM, _E.EXIT): _S.GONE,
    (_S.BUSY, _E.DONE): _S.WARM,
    (_S.BUSY, _E.KILL): _S.KILLING,
    (_S.BUSY, _E.EXIT): _S.GONE,
    (_S.KILLING, _E.DONE): _S.KILLING,
    (_S.KILLING, _E.RETIRE): _S.KILLING,
    (_S.KILLING, _E.EXIT): _S.GONE,
    (_S.GONE, _E.EXIT): _S.GONE,
}


class IllegalTransitionError(RuntimeError):
    """An internal error of the pool: an event the table does not allow in a state (a bug of
    the pool, never of a request)."""

    def __init__(self, state: WorkerState, event: WorkerEvent) -> None:
        super().__init__(f"a worker that is {state.value} cannot {event.value}")
        self.state = state
        self.event = event


def next_state(state: WorkerState, event: WorkerEvent) -> WorkerState:
    """The state a worker in ``state`` moves to on ``event``; :class:`IllegalTransitionError`
    (logged first, so that it is seen even where the raise lands in a thread or a loop
    callback) when the table holds no such move."""
    try:
        return TRANSITIONS[(state, event)]
    except KeyError:
        error = IllegalTransitionError(state, event)
        logger.error("illegal worker transition: %s (state %s, event %s)", error, state, event)
        raise error from None
