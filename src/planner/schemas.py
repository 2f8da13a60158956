"""The wire vocabulary under its first name: a re-export of :mod:`planner.wire`, kept for
clients that import ``planner.schemas`` (new code imports :mod:`planner.wire`). It takes
``planner.wire``'s own export list, so the two can never disagree."""

from __future__ import annotations

from planner import wire as _wire
from planner.wire import *  # noqa: F403

__all__ = list(_wire.__all__)
