"""Named scenes (``docs/scenes.md``): ``PUT/GET/DELETE /v1/scenes/{name}``, ``GET
/v1/scenes``, and the ``scene`` field of plan and Cartesian requests.

A scene is an obstacle set (and optionally a design) stored by the service under a name, so
that a plan names it instead of sending, say, a 100,000-point cloud with every request. The
service resolves the name (its store, :mod:`planner_api.scene_store`) and hands the scene's
library obstacles to the job with the request (:func:`with_scene`); the conversion of the
request (:func:`scene_obstacles`) then puts them before the request's own ``obstacles``.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from typing import TYPE_CHECKING, Annotated, Any, TypeVar

from pydantic import Field

from planner.exceptions import InputError
from planner.wire.common import (
    MAX_OBSTACLES,
    DesignModel,
    Obstacle,
    PointsObstacle,
    _Request,
    _Response,
    located,
    obstacles_to_core,
)

if TYPE_CHECKING:
    from planner import geometry
    from planner.wire.motion import MotionRequest

    #: A motion request of some kind (a plan, a sequence, a straight path), kept as it is.
    AnyMotionRequest = TypeVar("AnyMotionRequest", bound=MotionRequest)

__all__ = [
    "SCENE_NAME_PATTERN",
    "Scene",
    "SceneInfo",
    "SceneList",
    "SceneName",
    "SceneRequest",
    "count_points",
    "scene_hash",
    "scene_obstacles",
    "with_scene",
]

#: A scene name: a safe identifier (letters, digits, '_', '-', '.'; it starts with a letter or
#: a digit; at most 64 characters): usable in a URL path, a file name and a log line as it is.
SCENE_NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$"
SceneName = Annotated[
    str,
    Field(
        pattern=SCENE_NAME_PATTERN,
        description="A scene's name: 1-64 letters, digits, '_', '-' or '.', starting with a "
        "letter or a digit.",
    ),
]


class SceneRequest(_Request):
    """Body of ``PUT /v1/scenes/{name}``: the scene's obstacles (every type of a plan's
    ``obstacles``, point clouds included) and, optionally, its design (the robot of a plan in
    the scene that sends no design of its own)."""

    obstacles: list[Obstacle] = Field(default_factory=list, max_length=MAX_OBSTACLES)
    design: DesignModel | None = Field(None, description="The scene's robot; optional.")


class SceneInfo(_Response):
    """What the service keeps about a stored scene (the answer of a PUT, an item of the
    list)."""

    name: str
    version: int = Field(ge=1, description="1 at the first PUT of the name, +1 at each PUT.")
    hash: str = Field(description="SHA-256 (hex) of the scene's stored body: its content.")
    updated_at: float = Field(description="Time of the last PUT, s since the Unix epoch.")
    obstacles: int = Field(ge=0, description="Obstacles in the scene (a cloud counts once).")
    points: int = Field(ge=0, description="Points of its point clouds, all together.")


class Scene(SceneInfo):
    """Answer of ``GET /v1/scenes/{name}``: the metadata and the scene as stored."""

    scene: SceneRequest


class SceneList(_Response):
    """Answer of ``GET /v1/scenes``: every stored scene, by name."""

    scenes: list[SceneInfo]


def scene_hash(body: bytes) -> str:
    """The content hash of a scene's stored body (hex SHA-256)."""
    return hashlib.sha256(body).hexdigest()


def count_points(models: Sequence[Any]) -> int:
    """Points of the point clouds among obstacle models."""
    return sum(len(m.points) for m in models if isinstance(m, PointsObstacle))


def with_scene(
    request: AnyMotionRequest,
    obstacles: Sequence[geometry.Obstacle],
    design: DesignModel | None = None,
) -> AnyMotionRequest:
    """A copy of a plan or Cartesian request carrying its named scene's library obstacles
    (resolved by the service), and the scene's design when the request sends none."""
    update = (
        {"design": design}
        if design is not None and "design" not in request.model_fields_set
        else {}
    )
    copy = request.model_copy(update=update)
    copy._scene_obstacles = tuple(obstacles)
    return copy


def scene_obstacles(
    request: MotionRequest, loc: tuple[str | int, ...] = ("body",)
) -> list[geometry.Obstacle]:
    """The library obstacles of a request: its named scene's (when it names one) followed by
    its own ``obstacles``, the points of both together at most :data:`MAX_POINTS` (a 422 at
    the request's own cloud that passes it).

    Raises
    ------
    InputError
        The request names a scene that nobody resolved (a request built in-process, outside
        the service: a scene lives in the service's store), located at ``scene``.
    """
    if request.scene is None:
        return obstacles_to_core(request.obstacles, (*loc, "obstacles"))
    scene = request._scene_obstacles
    if scene is None:
        with located(*loc):
            raise InputError(
                f"scene {request.scene!r} is not resolved: a named scene lives in the "
                "service's store (PUT /v1/scenes/{name}); send the request to the service, or "
                "give its obstacles instead",
                field="scene",
            )
    # the scene's clouds count towards the request's points: a cloud of its own that passes
    # the limit is named where the client sent it (not at the index of the merged list)
    held = sum(len(o.points) for o in scene if hasattr(o, "points"))
    own = obstacles_to_core(request.obstacles, (*loc, "obstacles"), points_before=held)
    return [*scene, *own]
