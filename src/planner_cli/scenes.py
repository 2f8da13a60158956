"""``planner scene put|get|list|delete``: a running service's named scenes, through the
typed client (:class:`planner.client.PlannerClient`). A scene lives in the service's store,
so these commands talk to a service (``--url``, default ``$PLANNER_URL`` or
http://127.0.0.1:8000; ``--api-key`` or ``$PLANNER_API_KEY``).

Exit status: 0 done, 1 no such scene, 2 a bad input (the message naming the field), or a
service that cannot be reached (the message naming the URL and how to set it:
:mod:`planner_cli.service`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from planner_cli._support import Group
from planner_cli.errors import fail, reported
from planner_cli.service import KeyOption, UrlOption
from planner_cli.service import call as _call

__all__ = ["delete", "get", "list_scenes", "put", "scene_app"]

scene_app = typer.Typer(
    cls=Group,
    help="Named scenes of a running service: put, get, list, delete.",
    no_args_is_help=True,
    add_completion=False,
)

NameArgument = Annotated[str, typer.Argument(help="The scene's name (letters, digits, _-.).")]


@reported
def put(
    name: NameArgument,
    scene: Annotated[
        Path,
        typer.Argument(
            help='A JSON file: {"obstacles": [...], "design": {...}} (design optional).'
        ),
    ],
    url: UrlOption = None,
    api_key: KeyOption = None,
) -> None:
    """Store (or replace) the scene NAME from a JSON file; print its version and hash."""
    try:
        data = json.loads(scene.read_text())
    except (OSError, ValueError) as exc:
        fail([f"cannot read {scene} as JSON: {exc}"])
    if not isinstance(data, dict):
        fail([f"{scene}: a scene is a JSON object with 'obstacles' (and optionally 'design')"])
    info = _call(
        url, api_key, "put_scene", name, data.get("obstacles", []), design=data.get("design")
    )
    typer.echo(
        f"{info.name}: version {info.version}, hash {info.hash[:16]}, "
        f"{info.obstacles} obstacles, {info.points} points"
    )


@reported
def get(
    name: NameArgument,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Write the scene JSON here.")
    ] = None,
    url: UrlOption = None,
    api_key: KeyOption = None,
) -> None:
    """Print (or write to --out) the stored scene NAME as JSON (the body of its PUT)."""
    found = _call(url, api_key, "scene", name)
    text = found.scene.model_dump_json(exclude_none=True, indent=2)
    if out is None:
        typer.echo(text)
    else:
        out.write_text(text)
        typer.echo(f"{found.name}: version {found.version} written to {out}", err=True)


@reported
def list_scenes(url: UrlOption = None, api_key: KeyOption = None) -> None:
    """List the stored scenes: name, version, obstacles, points, hash."""
    for s in _call(url, api_key, "scenes").scenes:
        typer.echo(
            f"{s.name}\tv{s.version}\t{s.obstacles} obstacles\t{s.points} points\t{s.hash[:16]}"
        )


@reported
def delete(name: NameArgument, url: UrlOption = None, api_key: KeyOption = None) -> None:
    """Forget the scene NAME."""
    info = _call(url, api_key, "delete_scene", name)
    typer.echo(f"{info.name}: deleted (was version {info.version})")


scene_app.command("put")(put)
scene_app.command("get")(get)
scene_app.command("list")(list_scenes)
scene_app.command("delete")(delete)
