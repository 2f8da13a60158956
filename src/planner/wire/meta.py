"""``GET /v1/health``, ``/v1/ready``, ``/v1/version`` and the error body of every 4xx/5xx."""

from __future__ import annotations

from typing import Literal

from pydantic import (
    Field,
)

from planner.wire.common import _Response

__all__ = ["ErrorItem", "ErrorResponse", "Health", "Readiness", "ReadinessStatus", "VersionInfo"]

#: ``status`` of :class:`Readiness`: the worker pool's state, or the scene store's failure.
ReadinessStatus = Literal[
    "ready", "starting", "recovering", "broken", "stopping", "store_unavailable"
]


# ---------------------------------------------------------------------------- meta, errors
class Health(_Response):
    """Answer of ``GET /v1/health``."""

    status: Literal["ok"]


class VersionInfo(_Response):
    """Answer of ``GET /v1/version``."""

    version: str
    libraries: dict[str, str]


class Readiness(_Response):
    """Answer of ``GET /v1/ready`` (HTTP 503 while not ready)."""

    status: ReadinessStatus = Field(
        description="'ready' once every configured worker was warm (imports done, kernels "
        "compiled), then while at least one is, and the scene store answers; 'starting' "
        "before the first time; 'recovering' while no worker is warm after that; 'broken' "
        "when none is and none can be started or warmed up; 'stopping' during a shutdown; "
        "'store_unavailable' when the workers are ready but the scene store does not answer "
        "(see store_error)."
    )
    workers: int = Field(ge=0, description="Worker processes configured.")
    warm: int = Field(0, ge=0, description="Worker processes alive and warm now.")
    store: Literal["ok", "unavailable"] = Field(
        "ok",
        description="The scene store (PLANNER_SCENE_STORE): 'ok' when it answered a read "
        "within PLANNER_STORE_TIMEOUT_S, else 'unavailable' (and the answer is a 503).",
    )
    store_error: str | None = Field(
        None, description="With store 'unavailable': why (which store, what failed)."
    )


class ErrorItem(_Response):
    """One error in FastAPI's format: ``loc`` is the path to the field, e.g.
    ``["body", "design", "L1"]``."""

    loc: list[str | int]
    msg: str
    type: str


class ErrorResponse(_Response):
    """Body of every 4xx/5xx answer of the service."""

    detail: list[ErrorItem]
