"""Dependencies of the routes, as ``Annotated`` aliases: settings, worker pool, the request's
deadline, the API-key check and the tenant it names, and the watch on the client's
connection.

All are ``async def``: none of them blocks, and FastAPI runs a plain ``def`` dependency in its
thread pool, a thread hop per dependency per request (~0.5 ms of the cheapest requests)."""

from __future__ import annotations

import asyncio
import time
from collections.abc import AsyncIterator
from typing import Annotated

from fastapi import Depends, Request

from planner_api.exceptions import AuthenticationError, PoolNotRunningError
from planner_api.middleware import API_KEY_REQUIRED
from planner_api.pool import CLIENT_GONE, WorkerPool
from planner_api.settings import Settings
from planner_api.tenants import DEFAULT_TENANT, tenant_of

__all__ = [
    "WATCH_AFTER_S",
    "ApiKey",
    "ClientWatch",
    "Deadline",
    "Pool",
    "SettingsDep",
    "Tenant",
    "WatchClient",
    "get_app_settings",
    "get_deadline",
    "get_pool",
    "request_tenant",
    "require_api_key",
    "watch_client",
]


async def get_app_settings(request: Request) -> Settings:
    """The settings the application was built with."""
    return request.app.state.settings


async def get_pool(request: Request) -> WorkerPool:
    """The application's worker pool (started by the application's lifespan)."""
    pool = getattr(request.app.state, "pool", None)
    if pool is None:
        raise PoolNotRunningError("the worker pool is not running (application not started)")
    return pool


async def get_deadline(request: Request) -> float:
    """The request's deadline, a :func:`time.monotonic` value (stamped on arrival by
    :mod:`planner_api.middleware`)."""
    deadline = getattr(request.state, "deadline", None)
    if deadline is not None:
        return deadline
    return time.monotonic() + request.app.state.settings.request_timeout_s


async def require_api_key(
    request: Request, settings: Annotated[Settings, Depends(get_app_settings)]
) -> str:
    """The request's tenant (:mod:`planner_api.tenants`): ``default`` when no key is
    configured; else the tenant whose key comes in ``X-API-Key`` or ``Authorization: Bearer
    <key>`` (compared in constant time), and :class:`AuthenticationError` (401) when none
    does. The gate (:mod:`planner_api.middleware`) checked it before the body was read; this
    is the routes' own check, and what tells them the tenant."""
    keys = settings.tenant_keys
    tenant = DEFAULT_TENANT if keys is None else tenant_of(request.headers, keys)
    if tenant is None:
        raise AuthenticationError(API_KEY_REQUIRED)
    request.state.tenant = tenant
    return tenant


async def request_tenant(request: Request) -> str:
    """The request's tenant, for code that has the request but no dependency of its own
    (:func:`planner_api.routes.scenes.resolve_scene`): the one :func:`require_api_key` found,
    else found now."""
    found = getattr(request.state, "tenant", None)
    if found is not None:
        return found
    return await require_api_key(request, request.app.state.settings)


#: Seconds a request waits on its job before its client's connection is watched
#: (:class:`ClientWatch`).
WATCH_AFTER_S = 0.02


class ClientWatch:
    """``async with ClientWatch(request):`` while the route runs, watch its connection: when
    the client disconnects, the future in :data:`planner_api.pool.CLIENT_GONE` is resolved,
    and the job the route awaits is cancelled (its worker stopped and replaced) instead of
    computing an answer nobody reads.

    The body has been read when this runs (FastAPI reads it before the dependencies, the
    front door before the route), so the next ASGI message is the client's disconnect; a
    route that reads no body has its empty one skipped here.

    The watch (a task reading the request's next message) starts only once the route has
    run :data:`WATCH_AFTER_S` (a timer, cancelled when it ends first): a small plan comes
    back from its worker in about a millisecond, and a task per request, created, stepped
    and cancelled, was ~8 us of the event loop's CPU per plan request (~10 % of what it
    spends above a bare app's). A client that leaves has its job cancelled at most that much
    later than it would be at once; what its worker was doing meanwhile is thrown away as
    before."""

    __slots__ = ("_gone", "_request", "_timer", "_token", "_watcher")

    def __init__(self, request: Request) -> None:
        self._request = request
        self._watcher: asyncio.Task[None] | None = None

    async def __aenter__(self) -> None:
        loop = asyncio.get_running_loop()
        self._gone: asyncio.Future[None] = loop.create_future()
        self._timer = loop.call_later(WATCH_AFTER_S, self._start)
        self._token = CLIENT_GONE.set(self._gone)

    def _start(self) -> None:
        self._watcher = asyncio.ensure_future(self._watch())

    async def _watch(self) -> None:
        while True:
            message = await self._request.receive()
            if message["type"] == "http.disconnect":
                if not self._gone.done():
                    self._gone.set_result(None)
                return

    async def __aexit__(self, *exc: object) -> None:
        self._timer.cancel()
        if self._watcher is not None:
            self._watcher.cancel()
        try:
            CLIENT_GONE.reset(self._token)
        except ValueError:  # the exit ran in another context: nothing of ours to undo there
            pass


async def watch_client(request: Request) -> AsyncIterator[None]:
    """The routes' dependency form of :class:`ClientWatch` (FastAPI's path)."""
    async with ClientWatch(request):
        yield


SettingsDep = Annotated[Settings, Depends(get_app_settings)]
Pool = Annotated[WorkerPool, Depends(get_pool)]
Deadline = Annotated[float, Depends(get_deadline)]
ApiKey = Depends(require_api_key)
#: The request's tenant (the key's check itself: FastAPI runs it once per request).
Tenant = Annotated[str, Depends(require_api_key)]
WatchClient = Depends(watch_client)
