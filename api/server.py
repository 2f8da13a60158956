"""Run the service under uvicorn with the settings' logging, its connection timeouts and a
graceful shutdown in two phases: drain, then stop.

The connections are served by :func:`planner_api.protocol.guarded_protocol`: uvicorn's own
protocol with a header timeout (``header_timeout_s``) and a send timeout (``send_timeout_s``).

On SIGTERM or SIGINT:

1. **drain** (``drain_s``): the service keeps listening and serving every request as before,
   but ``/v1/ready`` answers 503 ``stopping`` and every answer carries ``Connection: close``,
   so that a load balancer probing readiness takes the replica out and clients reconnect
   elsewhere, while nothing it still sends meanwhile is refused. A second signal ends the
   drain at once;
2. **stop**: uvicorn stops accepting connections and waits up to ``shutdown_timeout_s`` for the
   requests in flight; this module's server first tells the worker pool to drain
   (:meth:`planner_api.pool.WorkerPool.drain`): new jobs are refused with a 503, and jobs
   still running shortly before the grace ends are cancelled with a clean 503
   ``shutting_down`` (``Retry-After``; a retry lands on another replica), so every request in
   flight gets an answer. The lifespan's end then stops the worker processes, terminating any
   still busy.

Why a drain before the listener closes: a load balancer learns that a replica is going only
from its probes (or, in Kubernetes, from the endpoint update, which takes seconds to reach
every proxy); a listener closed at once refuses the requests sent in that window.
"""

from __future__ import annotations

import asyncio
import ipaddress
import logging
import socket
import time

import uvicorn
from fastapi import FastAPI

from planner_api.app import create_app
from planner_api.logging import configure_logging, uvicorn_log_config
from planner_api.protocol import guarded_protocol
from planner_api.settings import Settings

__all__ = ["GracefulServer", "job_grace_s", "keyless_notice", "run"]

logger = logging.getLogger(__name__)

#: Seconds between two looks at a second signal during the drain.
_DRAIN_POLL_S = 0.05


def job_grace_s(shutdown_timeout_s: float) -> float:
    """The share of the shutdown grace given to jobs in flight: the rest (10 %, at most 1 s)
    is left to send the 503s of the jobs cancelled at its end."""
    return max(shutdown_timeout_s - min(0.1 * shutdown_timeout_s, 1.0), 0.0)


class GracefulServer(uvicorn.Server):
    """uvicorn's server that drains (module docstring) before it stops, and drains ``app``'s
    worker pool when it stops."""

    def __init__(
        self,
        config: uvicorn.Config,
        app: FastAPI,
        shutdown_timeout_s: float,
        drain_s: float = 0.0,
    ) -> None:
        super().__init__(config)
        self._app = app
        self._shutdown_timeout_s = shutdown_timeout_s
        self._drain_s = drain_s

    def handle_exit(self, sig: int, frame: object) -> None:
        if self.should_exit and getattr(self._app.state, "stopping", False):
            self._second_signal = True  # ends the drain (uvicorn's own: force_exit on SIGINT)
        super().handle_exit(sig, frame)  # type: ignore[arg-type]

    async def shutdown(self, sockets: list[socket.socket] | None = None) -> None:
        await self._drain()
        pool = getattr(self._app.state, "pool", None)
        if pool is not None:
            pool.drain(job_grace_s(self._shutdown_timeout_s))
        await super().shutdown(sockets=sockets)

    async def _drain(self) -> None:
        """Keep serving for ``drain_s`` with readiness 503 ``stopping`` (module docstring)."""
        self._app.state.stopping = True
        self._second_signal = False
        if self._drain_s <= 0:
            return
        logger.info(
            "draining for %g s: still serving, /v1/ready answers 503 stopping", self._drain_s
        )
        end = time.monotonic() + self._drain_s
        while time.monotonic() < end and not (self._second_signal or self.force_exit):
            await asyncio.sleep(min(_DRAIN_POLL_S, max(end - time.monotonic(), 0.0)))


def _loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def keyless_notice(settings: Settings) -> tuple[int, str] | None:
    """The start log's line about keys: None when keys are configured; else (level,
    message): INFO when bound to loopback (the default ``127.0.0.1``: only this machine can
    reach a service that asks no key), WARNING when bound elsewhere (``--host 0.0.0.0``:
    anyone who reaches the port plans, stores and deletes scenes). Never a refusal: the
    Docker image binds 0.0.0.0 by design, behind the container's own network."""
    if settings.tenant_keys is not None:
        return None
    if _loopback(settings.host):
        return logging.INFO, (
            f"no API key (PLANNER_API_KEY, PLANNER_API_KEYS): the service is keyless, bound to "
            f"loopback {settings.host} only; binding another interface exposes it to anyone "
            "who can reach it"
        )
    return logging.WARNING, (
        f"no API key (PLANNER_API_KEY, PLANNER_API_KEYS) and bound to {settings.host}, not "
        "loopback: anyone who can reach this port can use the service, store and delete "
        "scenes; set a key, or bind 127.0.0.1"
    )


def run(settings: Settings, app: FastAPI | None = None) -> None:
    """Serve ``app`` (default: :func:`planner_api.app.create_app` of ``settings``) on
    ``settings.host:port`` until SIGTERM/SIGINT. Blocks. The start log says when the
    service asks no key (:func:`keyless_notice`)."""
    configure_logging(settings.log_level, settings.log_format)
    notice = keyless_notice(settings)
    if notice is not None:
        logger.log(*notice)
    app = app if app is not None else create_app(settings)
    config = uvicorn.Config(
        app,
        host=settings.host,
        port=settings.port,
        http=guarded_protocol(settings.header_timeout_s, settings.send_timeout_s),
        log_config=uvicorn_log_config(settings.log_level, settings.log_format),
        log_level=settings.log_level,
        access_log=False,  # planner_api.middleware.RequestObserver writes the access log
        timeout_graceful_shutdown=settings.shutdown_timeout_s,  # type: ignore[arg-type]
    )
    GracefulServer(config, app, settings.shutdown_timeout_s, settings.drain_s).run()
