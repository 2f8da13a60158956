"""Named scenes: ``PUT/GET/DELETE /v1/scenes/{name}``, ``GET /v1/scenes``, and the
resolution of a plan's or Cartesian request's ``scene`` (:func:`resolve_scene`).

The store (:mod:`planner_api.scene_store`) is opened on first use from the setting
``scene_store`` and its calls run in a thread. The service process keeps the library
obstacles of the scenes it resolved, keyed by their content hash (:data:`_RESOLVED`): the
next plan of an unchanged scene reads one row's metadata, not its body, and hands the
obstacles built once to the worker, whose tree cache (:func:`planner.geometry.
pack_obstacles`, by content) finds the index built too.
"""

from __future__ import annotations

import threading
from typing import Annotated, Any

from fastapi import APIRouter, Path, Request, Response
from fastapi.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException

from planner.caching import BoundedCache
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
from planner_api.deps import SettingsDep
from planner_api.routes._common import check_obstacle_count, json_response
from planner_api.scene_store import SceneStore, open_store

__all__ = [
    "delete_scene",
    "get_scene",
    "list_scenes",
    "put_scene",
    "resolve_scene",
    "router",
    "scene_store",
]

router = APIRouter(prefix="/v1", tags=["scenes"])

NamePath = Annotated[str, Path(pattern=SCENE_NAME_PATTERN, description="The scene's name.")]
_STORE_LOCK = threading.Lock()


def _nbytes(value: tuple[Any, ...]) -> int:
    obstacles = value[0]
    return 256 + sum(getattr(getattr(o, "points", None), "nbytes", 64) for o in obstacles)


#: hash -> (library obstacles, design model or None) of the scenes this process resolved
_RESOLVED: BoundedCache[tuple[Any, ...]] = BoundedCache(32, 1 << 30, _nbytes)


def scene_store(request: Request) -> SceneStore:
    """The application's scene store, opened on first use."""
    store = getattr(request.app.state, "scene_store", None)
    if store is None:
        with _STORE_LOCK:
            store = getattr(request.app.state, "scene_store", None)
            if store is None:
                store = open_store(request.app.state.settings.scene_store)
                request.app.state.scene_store = store
    return store


def _not_found(name: str) -> HTTPException:
    return HTTPException(404, f"no scene named {name!r} (PUT /v1/scenes/{name} stores one)")


@router.put("/scenes/{name}", response_model=SceneInfo)
async def put_scene(
    name: NamePath, body: SceneRequest, request: Request, settings: SettingsDep
) -> SceneInfo:
    """Store the scene ``name`` (a new version; a scene of that name is replaced whole: the
    last writer wins). Its obstacles are checked as a plan's are (a 422 naming the field);
    the answer is what the store keeps about it."""
    check_obstacle_count(body.obstacles, settings.max_obstacles, ("body", "obstacles"))

    def store_it() -> SceneInfo:
        obstacles_to_core(body.obstacles)  # every rule of the library's obstacles, located
        text = body.model_dump_json(exclude_none=True)
        row = scene_store(request).put(
            name, text, scene_hash(text.encode()), len(body.obstacles), count_points(body.obstacles)
        )
        return SceneInfo(**row.info())

    return await run_in_threadpool(store_it)


_NOT_FOUND = {404: {"model": ErrorResponse, "description": "No scene has that name."}}


@router.get("/scenes/{name}", response_model=Scene, responses=_NOT_FOUND)
async def get_scene(name: NamePath, request: Request) -> Response:
    """The stored scene: its metadata (``name``, ``version``, ``hash``, ``updated_at``,
    ``obstacles`` and ``points`` counts are those of the list) and its ``scene`` body as it
    was stored (``{"obstacles": [...], "design": ...}``). 404 when there is none."""
    row = await run_in_threadpool(scene_store(request).get, name)
    if row is None:
        raise _not_found(name)
    info = SceneInfo(**row.info()).model_dump_json()
    return json_response(f'{info[:-1]},"scene":{row.body}}}'.encode())


@router.get("/scenes", response_model=SceneList)
async def list_scenes(request: Request) -> SceneList:
    """Every stored scene's metadata, by name (no bodies)."""
    rows = await run_in_threadpool(scene_store(request).list)
    return SceneList(scenes=[SceneInfo(**r.info()) for r in rows])


@router.delete("/scenes/{name}", response_model=SceneInfo, responses=_NOT_FOUND)
async def delete_scene(name: NamePath, request: Request) -> SceneInfo:
    """Forget the scene; the answer is what the store kept about it. 404 when there is none."""
    row = await run_in_threadpool(scene_store(request).delete, name)
    if row is None:
        raise _not_found(name)
    return SceneInfo(**row.info())


def _resolve(store: SceneStore, name: str) -> tuple[Any, ...]:
    """(library obstacles, design) of the scene's current version, built once per content."""
    head = store.get(name, body=False)
    hit = None if head is None else _RESOLVED.get(head.hash)
    if hit is not None:
        return hit
    row = store.get(name)  # the body; a PUT in between gives the newer scene, whole
    if row is None:
        with located("body"):
            raise InputError(
                f"scene: no scene named {name!r} (PUT /v1/scenes/{name} stores one)",
                field="scene",
            )
    scene = SceneRequest.model_validate_json(row.body or "{}")
    with located("body", "scene"):
        value = (tuple(obstacles_to_core(scene.obstacles, ("body", "scene"))), scene.design)
    _RESOLVED.put(row.hash, value)
    return value


async def resolve_scene(request: Request, body: Any) -> Any:
    """``body`` (a plan or Cartesian request) carrying its named scene's obstacles and
    design (:func:`planner.wire.with_scene`); unchanged when it names none. A 422 at
    ``scene`` when no scene has that name."""
    name = getattr(body, "scene", None)
    if name is None:
        return body
    obstacles, design = await run_in_threadpool(_resolve, scene_store(request), name)
    return with_scene(body, obstacles, design)
