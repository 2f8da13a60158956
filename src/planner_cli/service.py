"""What the commands that talk to a running service share (``planner scene``, ``planner
job``): the ``--url`` and ``--api-key`` options, the typed client they make, and the one path
from its errors to the CLI's exit statuses.

The URL is ``--url``, else ``$PLANNER_URL``, else http://127.0.0.1:8000; the key
``--api-key``, else ``$PLANNER_API_KEY``. When no service answers there, the error names the
URL and how to set it (the usual mistake: no ``planner serve`` running, or another port).
"""

from __future__ import annotations

import os
from typing import Annotated, Any

import typer

from planner_cli.errors import EXIT_BAD_INPUT, EXIT_NO_ANSWER, fail

__all__ = ["DEFAULT_URL", "KeyOption", "UrlOption", "base_url", "call", "make_client"]

#: The service's URL without ``--url`` or ``$PLANNER_URL``.
DEFAULT_URL = "http://127.0.0.1:8000"

UrlOption = Annotated[
    str | None,
    typer.Option("--url", help="The service's base URL (default $PLANNER_URL or :8000)."),
]
KeyOption = Annotated[
    str | None, typer.Option("--api-key", help="The service's API key ($PLANNER_API_KEY).")
]


def base_url(url: str | None) -> str:
    """The URL the commands talk to (module docstring)."""
    return url or os.environ.get("PLANNER_URL") or DEFAULT_URL


def make_client(url: str | None, api_key: str | None) -> Any:
    """A :class:`planner.client.PlannerClient` of the service at :func:`base_url`."""
    from planner.client import PlannerClient

    key = api_key or os.environ.get("PLANNER_API_KEY") or None
    return PlannerClient(base_url(url), api_key=key)


def call(url: str | None, api_key: str | None, method: str, *args: Any, **kwargs: Any) -> Any:
    """``client.<method>(...)``, its errors as the CLI's: 404 exits 1; a refused input, an
    error answer or a service that does not answer exits 2 with the message (for the last,
    the URL and how to set it)."""
    from planner.client_errors import NotFoundError, PlannerClientError, TransportError

    try:
        with make_client(url, api_key) as client:
            return getattr(client, method)(*args, **kwargs)
    except NotFoundError as exc:
        fail([str(exc)], EXIT_NO_ANSWER)
    except TransportError as exc:
        fail(
            [
                f"no planning service answers at {base_url(url)} ({exc}): start one with "
                "'planner serve', or name its URL with --url or PLANNER_URL"
            ]
        )
    except PlannerClientError as exc:
        fail([str(exc)], EXIT_BAD_INPUT)
