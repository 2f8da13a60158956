"""The ``planner`` command line (typer)."""

from __future__ import annotations

from typing import Annotated

import typer

app = typer.Typer(
    help="Plan, time and analyse motions of the 3-DOF hybrid manipulator.",
    no_args_is_help=True,
    add_completion=False,
)


@app.command()
def serve(
    host: Annotated[str, typer.Option(help="Interface to bind.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port.", min=1, max=65535)] = 8000,
) -> None:
    """Start the HTTP service."""
    import uvicorn

    from api.app import create_app
    from api.settings import Settings

    uvicorn.run(create_app(Settings(host=host, port=port)), host=host, port=port)


@app.command()
def version() -> None:
    """Print the package version."""
    import planner

    typer.echo(planner.__version__)


if __name__ == "__main__":  # pragma: no cover
    app()
