"""The ``planner`` command line, on the top floor of the house (docs/architecture.md): it may
call the library, the wire, the client and the service, and nothing below imports it. The
console script ``planner`` and ``python -m planner_cli`` run :data:`app`."""

from __future__ import annotations

from planner_cli.app import app

__all__ = ["app"]
