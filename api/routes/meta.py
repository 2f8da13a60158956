"""Liveness, readiness and version."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response

import planner
from planner.wire import ErrorResponse, Health, Readiness, ReadinessStatus, VersionInfo
from planner_api.deps import ApiKey, Pool, SettingsDep

__all__ = ["health", "ready", "router", "version"]

router = APIRouter(prefix="/v1", tags=["meta"])


@router.get("/health", response_model=Health)
async def health() -> Health:
    """Liveness: the process answers (never needs the API key)."""
    return Health(status="ok")


@router.get(
    "/ready",
    response_model=Readiness,
    response_model_exclude_none=True,
    responses={
        503: {
            "model": Readiness,
            "description": "No worker is warm (yet), stopping, or the scene store does not answer.",
        }
    },
)
async def ready(
    request: Request, pool: Pool, settings: SettingsDep, response: Response
) -> Readiness:
    """Readiness: every configured worker process was warm once and one is now (503
    otherwise: while starting, while no worker is warm, while stopping). Like
    ``/v1/health`` it never needs the API key: load-balancer health checks often cannot send
    one, and it tells nothing but the worker counts and the store's state. From a SIGTERM on
    it answers 503 ``stopping`` while the service still serves (the drain,
    :mod:`planner_api.server`).

    The scene store is asked a read each time (bounded by ``PLANNER_STORE_TIMEOUT_S``):
    when it cannot answer, ``store`` is ``unavailable`` with ``store_error`` saying why, and
    the answer is a 503 (``status`` ``store_unavailable`` when the workers are ready). Why
    a replica with its workers warm is not ready without its store: every scene request and
    every plan naming a scene would answer 503; with PostgreSQL down every replica says so,
    which an orchestrator shows instead of routing to replicas that cannot serve."""
    state: ReadinessStatus = pool.state
    warming = request.app.state.warming
    if request.app.state.stopping:
        state = "stopping"
    elif warming is not None and not warming.done() and state == "ready":
        state = "starting"  # the event loop's own jobs are not warm yet
    store_error = await request.app.state.scene_access.ping()
    if store_error is not None and state == "ready":
        state = "store_unavailable"
    if state != "ready":
        response.status_code = 503
        response.headers["Retry-After"] = str(settings.retry_after_s)
    return Readiness(
        status=state,
        workers=pool.workers,
        warm=pool.warm_workers,
        store="ok" if store_error is None else "unavailable",
        store_error=store_error,
    )


@router.get(
    "/version",
    response_model=VersionInfo,
    dependencies=[ApiKey],
    responses={401: {"model": ErrorResponse}},
)
def version() -> VersionInfo:
    """Versions of the service and of the libraries that shape its answers."""
    from importlib.metadata import version as dist_version

    return VersionInfo(
        version=planner.__version__,
        libraries={name: dist_version(name) for name in ("ompl", "toppra", "ruckig", "numpy")},
    )
