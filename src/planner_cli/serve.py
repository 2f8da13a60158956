"""``planner serve``: the HTTP service (:func:`planner_api.server.run`) with its settings from
the options and the PLANNER_* environment."""

from __future__ import annotations

from typing import Annotated, Any

import typer

__all__ = ["serve"]


def serve(
    host: Annotated[
        str | None, typer.Option(metavar="HOST", help="Interface to bind (env PLANNER_HOST).")
    ] = None,
    port: Annotated[
        int | None,
        typer.Option(metavar="PORT", help="TCP port (env PLANNER_PORT).", min=1, max=65535),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(
            metavar="N", help="Worker processes (env PLANNER_WORKERS, default: the CPUs).", min=1
        ),
    ] = None,
    log_level: Annotated[
        str | None,
        typer.Option(
            metavar="LEVEL", help="Log level: debug, info, warning, error (env PLANNER_LOG_LEVEL)."
        ),
    ] = None,
    log_format: Annotated[
        str | None,
        typer.Option(metavar="FORMAT", help="Log format: json or text (env PLANNER_LOG_FORMAT)."),
    ] = None,
    shutdown_timeout: Annotated[
        float | None,
        typer.Option(
            metavar="SECONDS",
            help="Seconds in-flight requests may finish after SIGTERM and the drain "
            "(env PLANNER_SHUTDOWN_TIMEOUT_S; the drain: PLANNER_DRAIN_S).",
            min=0.0,
        ),
    ] = None,
) -> None:
    """Start the HTTP service.

    Every setting can also come from a PLANNER_* environment variable; an option given here
    wins over the environment."""
    from planner_api.server import run
    from planner_api.settings import Settings

    given: dict[str, Any] = {
        "host": host,
        "port": port,
        "workers": workers,
        "log_level": log_level.lower() if log_level else None,
        "log_format": log_format,
        "shutdown_timeout_s": shutdown_timeout,
    }
    run(Settings(**{k: v for k, v in given.items() if v is not None}))
