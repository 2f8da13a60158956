"""The worker pool of the service: the processes that run the CPU-bound work (plans, timing,
analysis), one job per process at a time, each a fork of one warm template.

Its parts, one job each: :mod:`~planner_api.pool.pool` (the pool: its life cycle and its
jobs), :mod:`~planner_api.pool.handle` (the parent's record of one worker),
:mod:`~planner_api.pool.states` (a worker's states and their one table of moves),
:mod:`~planner_api.pool.process` (the worker's side), :mod:`~planner_api.pool.template` (the
warm template), :mod:`~planner_api.pool.wait` (how a request waits for its jobs),
:mod:`~planner_api.pool.watchdog` (the kills of jobs past their deadline or cancelled) and
:mod:`~planner_api.pool.shutdown` (the drain and the shutdown). Why it is built so is the
docstring of :mod:`planner_api.pool.pool`.
"""

from planner_api.pool.pool import CLIENT_GONE, PoolState, WorkerPool, default_overrun_max

__all__ = ["CLIENT_GONE", "PoolState", "WorkerPool", "default_overrun_max"]
