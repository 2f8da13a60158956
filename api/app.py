"""Builds the FastAPI application: wiring only, the routes live in ``planner_api.routes``."""

from __future__ import annotations

import asyncio
import functools
import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI
from starlette.middleware.errors import ServerErrorMiddleware
from starlette.types import ASGIApp, Receive, Scope, Send

import planner
from planner import caching
from planner.wire import ErrorResponse
from planner_api.deps import ApiKey, WatchClient
from planner_api.errors import install_error_handlers
from planner_api.job_store import JobStore
from planner_api.metrics import Metrics
from planner_api.metrics import router as metrics_router
from planner_api.middleware import RequestGate, RequestObserver
from planner_api.openapi import install_docs, install_openapi, operation_id
from planner_api.pool import WorkerPool
from planner_api.routes import calibration as calibration_routes
from planner_api.routes import cartesian as cartesian_routes
from planner_api.routes import design, kinematics, meta, plan, scenes
from planner_api.routes import dynamics as dynamics_routes
from planner_api.routes import jobs as jobs_routes
from planner_api.routes import sequence as sequence_routes
from planner_api.routes import simulate as simulate_routes
from planner_api.routes import stop as stop_routes
from planner_api.routes import stream as stream_routes
from planner_api.routes import timing as timing_routes
from planner_api.routes import workspace as workspace_routes
from planner_api.routes.direct import index_routes
from planner_api.routes.viewer import install_viewer
from planner_api.settings import Settings, get_settings
from planner_api.store_access import StoreAccess
from planner_api.warmup import start_worker, warm_up_loop

__all__ = ["ServiceApp", "create_app"]

logger = logging.getLogger(__name__)

#: Error answers of the job routes' own (the gate's and the pool's: planner_api.openapi).
_ERRORS: dict[int | str, dict[str, Any]] = {422: {"model": ErrorResponse}}
#: Seconds the workers get to stop at the lifespan's end once the shutdown grace is spent.
_KILL_AFTER_DRAIN_S = 2.0


def _log_failure(task: asyncio.Task[float]) -> None:
    """Log the start-up warm-up's error, if any (its jobs then pay their loading later)."""
    if not task.cancelled() and task.exception() is not None:
        logger.error("the event loop's warm-up failed", exc_info=task.exception())


def create_app(settings: Settings | None = None, *, warm_up: bool = True) -> FastAPI:
    """The service, configured by ``settings`` (default: from the environment).

    The worker pool starts with the application's lifespan (``with TestClient(app)`` in
    tests, or a server). ``warm_up=False`` (tests of the gate, the key, the limits, the
    metrics) announces each worker ready as soon as it has sized its caches, without
    :func:`~planner_api.warmup.warm_up_worker`: its first job pays the imports instead.
    Every process's caches get ``settings.cache_mb`` (:func:`planner.caching.configure`).
    """
    settings = settings or get_settings()
    caching.configure(budget_mb=settings.cache_mb)  # this process's; the workers' at start

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        pool = WorkerPool(
            settings.workers,
            settings.queue_size or 0,
            retry_after_s=settings.retry_after_s,
            log_setup=(settings.log_level, settings.log_format),
            warm_up=functools.partial(start_worker, settings.cache_mb, warm_up),
            overrun_grace_s=settings.overrun_grace_s,
            overrun_max_s=settings.overrun_max_s,
            max_rss_mb=settings.worker_max_rss_mb or None,
            nice=settings.worker_nice,
        )
        await pool.start()
        app.state.pool = pool
        if warm_up:  # the event loop's own first calls (planner_api.warmup): /v1/ready waits
            app.state.warming = asyncio.create_task(warm_up_loop(app))
            app.state.warming.add_done_callback(_log_failure)
        app.state.jobs = jobs = JobStore(
            app.state.scene_access,
            max_jobs=settings.max_jobs,
            per_tenant=settings.jobs_per_tenant,
            ttl_s=settings.job_ttl_s,
            running=settings.jobs_running or 1,
            timeout_s=settings.job_timeout_s,
            max_result_bytes=int(settings.job_result_max_mb * 2**20),
            max_total_bytes=int(settings.jobs_max_mb * 2**20),
        )
        try:
            yield
        finally:
            if app.state.warming is not None:
                app.state.warming.cancel()  # a service stopped while still warming up
            # this replica's unfinished jobs are marked lost in the store, their tasks stopped
            await jobs.close()
            # after a drain (planner_api.server) the grace is spent: stop the workers at once
            drained = pool.state == "stopping"
            pool.shutdown(timeout_s=_KILL_AFTER_DRAIN_S if drained else settings.shutdown_timeout_s)
            app.state.scene_access.close()

    app = ServiceApp(
        title="hybrid-planner",
        version=planner.__version__,
        description="Motion planning, timing and design analysis for the 3-DOF hybrid "
        "manipulator (five-bar A-C-P-D-B turning about AB).",
        lifespan=lifespan,
        generate_unique_id_function=operation_id,  # "plan", not "plan_v1_plan_post"
        docs_url=None,  # served from the package's own assets (planner_api.openapi.install_docs)
        redoc_url=None,
    )
    app.state.settings = settings
    #: Set on SIGTERM by planner_api.server: /v1/ready answers 503 "stopping" from then on.
    app.state.stopping = False
    #: The start-up warm-up of the jobs run in the event loop (None: nothing to wait for).
    app.state.warming = None
    #: The store of scenes and long jobs, through its own bounded thread pool (opened at its
    #: first call).
    app.state.scene_access = StoreAccess(
        settings.scene_store,
        timeout_s=settings.store_timeout_s,
        threads=settings.store_threads,
        retry_after_s=settings.retry_after_s,
        job_ttl_s=settings.job_ttl_s,
    )
    install_error_handlers(app)
    app.add_middleware(
        RequestGate,
        max_body_bytes=settings.max_body_bytes,
        timeout_s=settings.request_timeout_s,
        body_timeout_s=settings.body_timeout_s,
        api_keys=settings.tenant_keys,
        allowed_hosts=settings.host_names,
    )
    app.state.metrics = Metrics(lambda: getattr(app.state, "pool", None), planner.__version__)
    app.add_middleware(
        RequestObserver, metrics=app.state.metrics, stopping=lambda: app.state.stopping
    )  # outermost: sees all
    _include_routes(app, settings)
    keyed = settings.tenant_keys is not None
    install_openapi(app, api_key=keyed, max_obstacles=settings.max_obstacles)
    return app


def _include_routes(app: FastAPI, settings: Settings) -> None:
    """The routes in the order routing tries them, each router with its dependencies (the
    API key; the client watch where a job waits on a worker), then the viewer's and the
    docs' pages, and the table that finds a request's route without a scan."""
    app.include_router(meta.router)
    if settings.metrics:
        app.include_router(metrics_router)
    # the kinematics answer in the event loop: no worker to cancel. They come first after the
    # probes because routing tries the routers in order, and these are the cheapest and most
    # frequent calls (matching the routers before them was ~8 % of an fk request's time)
    app.include_router(kinematics.router, dependencies=[ApiKey], responses=_ERRORS)
    # the routes that wait on a worker: a client that disconnects has its job cancelled
    # (WatchClient)
    watched = (design.router, plan.router, timing_routes.router, workspace_routes.router)
    for router in (
        *watched,
        cartesian_routes.router,
        dynamics_routes.router,
        calibration_routes.router,
        sequence_routes.router,
        simulate_routes.router,
        stop_routes.router,
    ):
        app.include_router(router, dependencies=[ApiKey, WatchClient], responses=_ERRORS)
    # the setpoint stream: a WebSocket, its API key checked by the route (the gate sees HTTP)
    app.include_router(stream_routes.router)
    # the scenes come from the store: no worker to cancel
    app.include_router(scenes.router, dependencies=[ApiKey], responses=_ERRORS)
    # long jobs outlive the request that submits them: no client watch
    app.include_router(jobs_routes.router, dependencies=[ApiKey], responses=_ERRORS)
    install_viewer(app)  # GET / and /viewer/: the page, without the API key
    install_docs(app)
    index_routes(app)  # a request's route found by its (method, path), not by a scan


class ServiceApp(FastAPI):
    """The service's FastAPI application with its front door in front of FastAPI's own
    layers: an HTTP request goes from the server straight to the 500 guard, the observer
    and the gate (:mod:`planner_api.middleware`; the gate then calls a hot route's direct
    answer, :mod:`planner_api.routes.direct`), without ``FastAPI.__call__``,
    ``Starlette.__call__`` and the two middlewares FastAPI puts between its 500 guard and
    the user's middleware (its exception telemetry and its body limit), which do nothing for
    such a request: the body limit is not set (the gate has its own) and the exception
    telemetry only records into a span that is not there. Why: the loop's CPU per request
    (issue 43); these layers were a few microseconds of a plain fk's ~150 in-process.

    The front is taken only when it changes nothing: once the middleware stack is built and
    has the shape it was made with (else :func:`_front_of` gives None), for HTTP (lifespan
    and WebSocket take FastAPI's path), without a ``root_path`` set on the application and
    without a parent's body limit in the scope, and while FastAPI's telemetry is off: it
    checks ``FastAPI._native_telemetry.enabled()`` itself on every request, as
    ``FastAPI.__call__`` does (an OpenTelemetry provider an operator configures, even after
    start, turns the front off at the next request, and FastAPI's tracing then sees every
    request, as before). The 500 guard is a ``ServerErrorMiddleware`` with the handler and
    debug flag of the one FastAPI built, so an error's 500 is the same."""

    _front: ASGIApp | None = None
    _body_key = ""

    def build_middleware_stack(self) -> ASGIApp:
        stack = super().build_middleware_stack()
        self._front = None
        layers = _private_layers()
        if layers is not None and hasattr(self, "_native_telemetry"):
            self._front = _front_of(stack, layers[0], layers[1])
            self._body_key = layers[2]
        return stack

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        front = self._front
        if (
            front is not None
            and scope["type"] == "http"
            and not self.root_path
            and self._body_key not in scope
            and not self._native_telemetry.enabled()
        ):
            scope["app"] = self  # as Starlette.__call__ sets it
            await front(scope, receive, send)
            return
        await super().__call__(scope, receive, send)


def _private_layers() -> tuple[type, type, str] | None:
    """FastAPI's private layers that :func:`_front_of` recognises (its body limit, its
    exception telemetry) and Starlette's scope key of a parent's body limit; None where the
    installed FastAPI has none of them (pyproject admits FastAPI releases older than these
    layers): the application then keeps FastAPI's own path, and starts as before."""
    try:
        from fastapi._body_limit import AppBodyLimitMiddleware
        from fastapi.telemetry._asgi import ExceptionTelemetryMiddleware
        from starlette.middleware.body_limit import MAX_BODY_SIZE_SCOPE_KEY
    except ImportError:
        return None
    return AppBodyLimitMiddleware, ExceptionTelemetryMiddleware, MAX_BODY_SIZE_SCOPE_KEY


def _front_of(stack: ASGIApp, limit_type: type, telemetry_type: type) -> ASGIApp | None:
    """The front door of a built middleware stack: its 500 guard (a copy) around the
    outermost user middleware, when the stack is ``ServerErrorMiddleware`` ->
    ``telemetry_type`` (FastAPI's ``ExceptionTelemetryMiddleware``) -> ``limit_type``
    (``AppBodyLimitMiddleware``) without a limit -> :class:`RequestObserver` (as FastAPI
    builds it for :func:`create_app`); None for any other shape (a FastAPI that builds its
    stack otherwise keeps its own path)."""
    if not isinstance(stack, ServerErrorMiddleware):
        return None
    telemetry = stack.app
    if not isinstance(telemetry, telemetry_type):
        return None
    limit = getattr(telemetry, "app", None)  # each layer holds the next as ``app``
    observer = getattr(limit, "app", None)
    if not isinstance(limit, limit_type) or not isinstance(observer, RequestObserver):
        return None  # a body limit set wraps the observer in its own middleware
    return ServerErrorMiddleware(observer, handler=stack.handler, debug=stack.debug)
