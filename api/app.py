"""Builds the FastAPI application: wiring only, the routes live in ``planner_api.routes``."""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI

import planner
from planner.wire import ErrorResponse
from planner_api.deps import ApiKey
from planner_api.errors import install_error_handlers
from planner_api.metrics import Metrics
from planner_api.metrics import router as metrics_router
from planner_api.middleware import RequestGate, RequestObserver
from planner_api.openapi import install_docs, install_openapi
from planner_api.routes import cartesian as cartesian_routes
from planner_api.routes import design, kinematics, meta, plan, scenes
from planner_api.routes import timing as timing_routes
from planner_api.routes import workspace as workspace_routes
from planner_api.routes.viewer import install_viewer
from planner_api.settings import Settings, get_settings
from planner_api.warmup import warm_up_worker
from planner_api.workers import WorkerPool

__all__ = ["create_app"]

#: Error answers of the job routes' own (the gate's and the pool's: planner_api.openapi).
_ERRORS = {422: {"model": ErrorResponse}}
#: Seconds the workers get to stop at the lifespan's end once the shutdown grace is spent.
_KILL_AFTER_DRAIN_S = 2.0


def create_app(settings: Settings | None = None, *, warm_up: bool = True) -> FastAPI:
    """The service, configured by ``settings`` (default: from the environment).

    The worker pool starts with the application's lifespan (``with TestClient(app)`` in
    tests, or a server). ``warm_up=False`` (tests of the gate, the key, the limits, the
    metrics) announces each worker ready as soon as it has started, without
    :func:`~planner_api.warmup.warm_up_worker`: its first job pays the imports instead.
    """
    settings = settings or get_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        pool = WorkerPool(
            settings.workers,
            settings.queue_size or 0,
            retry_after_s=settings.retry_after_s,
            log_setup=(settings.log_level, settings.log_format),
            warm_up=warm_up_worker if warm_up else None,
        )
        await pool.start()
        app.state.pool = pool
        try:
            yield
        finally:
            # after a drain (planner_api.server) the grace is spent: stop the workers at once
            drained = pool.state == "stopping"
            pool.shutdown(timeout_s=_KILL_AFTER_DRAIN_S if drained else settings.shutdown_timeout_s)
            store = getattr(app.state, "scene_store", None)
            if store is not None:
                store.close()

    app = FastAPI(
        title="hybrid-planner",
        version=planner.__version__,
        description="Motion planning, timing and design analysis for the 3-DOF hybrid "
        "manipulator (five-bar A-C-P-D-B turning about AB).",
        lifespan=lifespan,
        docs_url=None,  # served from the package's own assets (planner_api.openapi.install_docs)
        redoc_url=None,
    )
    app.state.settings = settings
    install_error_handlers(app)
    app.add_middleware(
        RequestGate,
        max_body_bytes=settings.max_body_bytes,
        timeout_s=settings.request_timeout_s,
        body_timeout_s=settings.body_timeout_s,
        api_key=settings.api_key.get_secret_value() if settings.api_key else None,
    )
    app.state.metrics = Metrics(lambda: getattr(app.state, "pool", None), planner.__version__)
    app.add_middleware(RequestObserver, metrics=app.state.metrics)  # outermost: sees all
    app.include_router(meta.router)
    if settings.metrics:
        app.include_router(metrics_router)
    for router in (design.router, kinematics.router, plan.router):
        app.include_router(router, dependencies=[ApiKey], responses=_ERRORS)
    for router in (timing_routes.router, workspace_routes.router):
        app.include_router(router, dependencies=[ApiKey], responses=_ERRORS)
    app.include_router(cartesian_routes.router, dependencies=[ApiKey], responses=_ERRORS)
    app.include_router(scenes.router, dependencies=[ApiKey], responses=_ERRORS)
    install_viewer(app)  # GET / and /viewer/: the page, without the API key
    install_docs(app)
    install_openapi(app, api_key=settings.api_key is not None)
    return app
