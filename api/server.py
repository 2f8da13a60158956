"""Run the service under uvicorn with the settings' logging and a graceful shutdown.

On SIGTERM or SIGINT uvicorn stops accepting connections and waits up to
``shutdown_timeout_s`` for the requests in flight; this module's server first tells the worker
pool to drain (:meth:`planner_api.workers.WorkerPool.drain`): new jobs are refused with a 503, and
jobs still running shortly before the grace ends are cancelled with a clean 503
``shutting_down`` (``Retry-After``; a retry lands on another replica), so every request in
flight gets an answer. The lifespan's end then stops the worker processes, terminating any
still busy.
"""

from __future__ import annotations

import socket

import uvicorn
from fastapi import FastAPI

from planner_api.app import create_app
from planner_api.logging import configure_logging, uvicorn_log_config
from planner_api.settings import Settings

__all__ = ["GracefulServer", "job_grace_s", "run"]


def job_grace_s(shutdown_timeout_s: float) -> float:
    """The share of the shutdown grace given to jobs in flight: the rest (10 %, at most 1 s)
    is left to send the 503s of the jobs cancelled at its end."""
    return max(shutdown_timeout_s - min(0.1 * shutdown_timeout_s, 1.0), 0.0)


class GracefulServer(uvicorn.Server):
    """uvicorn's server that drains ``app``'s worker pool when a shutdown begins."""

    def __init__(self, config: uvicorn.Config, app: FastAPI, shutdown_timeout_s: float) -> None:
        super().__init__(config)
        self._app = app
        self._shutdown_timeout_s = shutdown_timeout_s

    async def shutdown(self, sockets: list[socket.socket] | None = None) -> None:
        pool = getattr(self._app.state, "pool", None)
        if pool is not None:
            pool.drain(job_grace_s(self._shutdown_timeout_s))
        await super().shutdown(sockets=sockets)


def run(settings: Settings, app: FastAPI | None = None) -> None:
    """Serve ``app`` (default: :func:`planner_api.app.create_app` of ``settings``) on
    ``settings.host:port`` until SIGTERM/SIGINT. Blocks."""
    configure_logging(settings.log_level, settings.log_format)
    app = app if app is not None else create_app(settings)
    config = uvicorn.Config(
        app,
        host=settings.host,
        port=settings.port,
        log_config=uvicorn_log_config(settings.log_level, settings.log_format),
        log_level=settings.log_level,
        access_log=False,  # planner_api.middleware.RequestObserver writes the access log
        timeout_graceful_shutdown=settings.shutdown_timeout_s,  # type: ignore[arg-type]
    )
    GracefulServer(config, app, settings.shutdown_timeout_s).run()
