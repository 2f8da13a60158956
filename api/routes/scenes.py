"""Named scenes: ``PUT/GET/DELETE /v1/scenes/{name}``, ``GET /v1/scenes``, and the
resolution of a plan's or Cartesian request's ``scene`` (:func:`resolve_scene`).

Every scene belongs to a tenant (:mod:`planner_api.tenants`): the routes see, list, replace
and delete the scenes of the request's tenant only, and another tenant's scene of the same
name does not exist for them (404, or a new scene of their own for a PUT). The store's calls
go through :class:`planner_api.store_access.StoreAccess` (a thread pool of their own, a
bounded wait, a 503 ``store_unavailable`` when the store cannot answer); a PUT checks the
tenant's quotas (``PLANNER_SCENES_MAX``, ``PLANNER_SCENE_BYTES_MAX``) in the store's write
transaction. The service process keeps the library
obstacles of the scenes it resolved, keyed by their content hash (:data:`_RESOLVED`): the
next plan of an unchanged scene reads one row's metadata, not its body, and hands the
obstacles built once to the worker, whose tree cache (:func:`planner.geometry.
pack_obstacles`, by content) finds the index built too.
"""

from __future__ import annotations

import re
from typing import Annotated, Any

from fastapi import APIRouter, Path, Request, Response
from fastapi.concurrency import run_in_threadpool
from fastapi.exceptions import RequestValidationError
from starlette.exceptions import HTTPException

from planner.caching import BoundedCache, bounded_cache
from planner.exceptions import InputError
from planner.wire import (
    SCENE_NAME_PATTERN,
    ErrorResponse,
    Scene,
    SceneInfo,
    SceneList,
    SceneRequest,
    count_points,
    located,
    obstacles_to_core,
    scene_hash,
    with_scene,
)
from planner_api.deps import SettingsDep, Tenant, get_deadline, get_pool, request_tenant
from planner_api.exceptions import PoolNotRunningError
from planner_api.routes._common import check_obstacle_count, json_response
from planner_api.routes.worker_body import (
    BodyInvalidError,
    BodySpec,
    WorkerBodyRoute,
    parse_body,
    parsed_in_worker,
    unchanged,
)
from planner_api.scene_store import SceneRow
from planner_api.store_access import StoreAccess

__all__ = [
    "delete_scene",
    "get_scene",
    "list_scenes",
    "put_scene",
    "resolve_scene",
    "router",
    "serialise_raw_scene",
    "serialise_scene",
    "store_access",
]

router = APIRouter(prefix="/v1", tags=["scenes"], route_class=WorkerBodyRoute)

NamePath = Annotated[str, Path(pattern=SCENE_NAME_PATTERN, description="The scene's name.")]


#: hash -> (library obstacles, design model or None) of the scenes this process resolved
#: (``scenes.resolved`` of :data:`planner.caching.CACHES`)
_RESOLVED: BoundedCache[tuple[Any, ...]] = bounded_cache("scenes.resolved")


def store_access(request: Request) -> StoreAccess:
    """The application's way to its scene store (made with the application)."""
    access = getattr(request.app.state, "scene_access", None)
    if access is None:
        raise PoolNotRunningError("the scene store is not set up (application not built)")
    return access


def _not_found(name: str) -> HTTPException:
    return HTTPException(404, f"no scene named {name!r} (PUT /v1/scenes/{name} stores one)")


_STORE_ERRORS: dict[int | str, dict[str, Any]] = {
    503: {
        "model": ErrorResponse,
        "description": "The scene store cannot answer in time "
        "(store_unavailable, with Retry-After): nothing was changed.",
    },
}
_NOT_FOUND: dict[int | str, dict[str, Any]] = {
    **_STORE_ERRORS,
    404: {"model": ErrorResponse, "description": "No scene of this tenant has that name."},
}
_QUOTAS: dict[int | str, dict[str, Any]] = {
    **_STORE_ERRORS,
    413: {
        "model": ErrorResponse,
        "description": "The tenant's stored bytes would pass "
        "PLANNER_SCENE_BYTES_MAX (quota_exceeded).",
    },
    422: {
        "model": ErrorResponse,
        "description": "A field breaks a rule, or the tenant's "
        "scene count would pass PLANNER_SCENES_MAX (quota_exceeded).",
    },
}


def serialise_scene(body: SceneRequest, max_obstacles: int) -> tuple[str, str, int, int]:
    """A scene as the store keeps it: (its canonical JSON, that text's hash, its obstacle
    and point counts), once every rule of a plan's obstacles holds (a 422 naming the field)."""
    check_obstacle_count(body.obstacles, max_obstacles, ("body", "obstacles"))
    obstacles_to_core(body.obstacles)  # every rule of the library's obstacles, located
    text = body.model_dump_json(exclude_none=True)
    return text, scene_hash(text.encode()), len(body.obstacles), count_points(body.obstacles)


def serialise_raw_scene(work: tuple[bytes, int]) -> tuple[str, str, int, int]:
    """In a worker: a large PUT body (bytes) parsed as FastAPI parses it, then
    :func:`serialise_scene`."""
    raw, max_obstacles = work
    return serialise_scene(parse_body(SceneRequest, raw), max_obstacles)


async def _store(
    request: Request, tenant: str, name: str, stored: tuple[str, str, int, int]
) -> SceneInfo:
    """Keep a serialised scene (:func:`serialise_scene`) as the tenant's ``name``, within its
    quotas; what the store keeps about it."""
    settings = request.app.state.settings
    limits = {"max_scenes": settings.scenes_max, "max_bytes": settings.scene_bytes_max}
    row = await store_access(request).call(
        lambda store: store.put(tenant, name, *stored, **limits), write=True
    )
    return SceneInfo(**row.info())


async def _put_large_scene(request: Request, raw: bytes) -> Response:
    """A PUT whose body is larger than ``PLANNER_INLINE_PARSE_BYTES``: parsed, checked and
    serialised in a worker (:mod:`planner_api.routes.worker_body`), stored from here. The
    name is checked as the route's path parameter is."""
    name = request.path_params["name"]
    if re.fullmatch(SCENE_NAME_PATTERN, name) is None:
        raise RequestValidationError(
            [
                {
                    "loc": ("path", "name"),
                    "type": "string_pattern_mismatch",
                    "msg": f"String should match pattern '{SCENE_NAME_PATTERN}'",
                }
            ]
        )
    tenant = await request_tenant(request)
    settings = request.app.state.settings
    pool, deadline = await get_pool(request), await get_deadline(request)
    try:
        stored = await pool.run(
            serialise_raw_scene, (raw, settings.max_obstacles), deadline=deadline
        )
    except BodyInvalidError as exc:
        raise RequestValidationError(exc.items) from None
    info = await _store(request, tenant, name, stored)
    return json_response(info.model_dump_json().encode())


def _no_job(_: Request) -> None:
    return None


@router.put("/scenes/{name}", response_model=SceneInfo, responses=_QUOTAS)
@parsed_in_worker(BodySpec(SceneRequest, unchanged, _no_job, handle=_put_large_scene))
async def put_scene(
    name: NamePath, body: SceneRequest, request: Request, settings: SettingsDep, tenant: Tenant
) -> SceneInfo:
    """Store the scene ``name`` of the request's tenant (a new version; a scene of that name
    is replaced whole: the last writer wins). Its obstacles are checked as a plan's are (a
    422 naming the field); a scene that would take the tenant past ``PLANNER_SCENES_MAX``
    scenes is a 422, past ``PLANNER_SCENE_BYTES_MAX`` stored bytes a 413. The answer is what
    the store keeps about it. A body larger than ``PLANNER_INLINE_PARSE_BYTES`` is parsed and
    serialised in a worker instead of a thread of this process."""
    stored = await run_in_threadpool(serialise_scene, body, settings.max_obstacles)
    return await _store(request, tenant, name, stored)


@router.get("/scenes/{name}", response_model=Scene, responses=_NOT_FOUND)
async def get_scene(name: NamePath, request: Request, tenant: Tenant) -> Response:
    """The stored scene: its metadata (``name``, ``version``, ``hash``, ``updated_at``,
    ``obstacles`` and ``points`` counts are those of the list) and its ``scene`` body as it
    was stored (``{"obstacles": [...], "design": ...}``). 404 when the tenant has none."""
    row = await store_access(request).call(lambda store: store.get(tenant, name))
    if row is None:
        raise _not_found(name)
    info = SceneInfo(**row.info()).model_dump_json()
    return json_response(f'{info[:-1]},"scene":{row.body}}}'.encode())


@router.get("/scenes", response_model=SceneList, responses=_STORE_ERRORS)
async def list_scenes(request: Request, tenant: Tenant) -> SceneList:
    """Every scene of the request's tenant: its metadata, by name (no bodies)."""
    rows = await store_access(request).call(lambda store: store.list(tenant))
    return SceneList(scenes=[SceneInfo(**r.info()) for r in rows])


@router.delete("/scenes/{name}", response_model=SceneInfo, responses=_NOT_FOUND)
async def delete_scene(name: NamePath, request: Request, tenant: Tenant) -> SceneInfo:
    """Forget the tenant's scene; the answer is what the store kept about it. 404 when the
    tenant has none."""
    row = await store_access(request).call(lambda store: store.delete(tenant, name), write=True)
    if row is None:
        raise _not_found(name)
    return SceneInfo(**row.info())


def _build(row: SceneRow) -> tuple[Any, ...]:
    """(library obstacles, design) of a stored scene's body (CPU work: the routes' thread
    pool, not the store's)."""
    scene = SceneRequest.model_validate_json(row.body or "{}")
    with located("body", "scene"):
        value = (tuple(obstacles_to_core(scene.obstacles, ("body", "scene"))), scene.design)
    _RESOLVED.put(row.hash, value)
    return value


async def _resolve(access: StoreAccess, tenant: str, name: str) -> tuple[Any, ...]:
    """(library obstacles, design) of the scene's current version, built once per content."""
    head = await access.call(lambda store: store.get(tenant, name, body=False))
    hit = None if head is None else _RESOLVED.get(head.hash)
    if hit is not None:
        return hit
    # the body; a PUT in between gives the newer scene, whole
    row = await access.call(lambda store: store.get(tenant, name))
    if row is None:
        with located("body"):
            raise InputError(
                f"scene: no scene named {name!r} (PUT /v1/scenes/{name} stores one)",
                field="scene",
            )
    return await run_in_threadpool(_build, row)


async def resolve_scene(request: Request, body: Any) -> Any:
    """``body`` (a plan or Cartesian request) carrying its named scene's obstacles and
    design (:func:`planner.wire.with_scene`); unchanged when it names none. The scene is the
    request's tenant's. A 422 at ``scene`` when the tenant has no scene of that name, a 503
    ``store_unavailable`` when the store cannot answer in time."""
    name = getattr(body, "scene", None)
    if name is None:
        return body
    tenant = await request_tenant(request)
    obstacles, design = await _resolve(store_access(request), tenant, name)
    return with_scene(body, obstacles, design)
