"""The ``planner`` command line (typer)."""

from __future__ import annotations

from pathlib import Path
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


@app.command()
def figures(
    outdir: Annotated[Path, typer.Argument(help="Directory to write the figures into.")],
    n: Annotated[
        int, typer.Option(help="Cells per axis of the section grids.", min=16, max=2048)
    ] = 256,
    formats: Annotated[str, typer.Option(help="Comma-separated formats.")] = "png,svg",
    dpi: Annotated[int, typer.Option(help="Resolution of PNG files.", min=20, max=600)] = 80,
) -> None:
    """Write the paper's figures 4-15 (PNG and SVG), one file per figure and format."""
    from planner.plotting import write_figures

    fmts = tuple(f.strip() for f in formats.split(",") if f.strip())
    for path in write_figures(outdir, n=n, formats=fmts, dpi=dpi):
        typer.echo(str(path))


@app.command("check-design")
def check_design_command(
    l0: Annotated[float, typer.Argument(metavar="L0", help="|AB|, m.")],
    l1: Annotated[float, typer.Argument(metavar="L1", help="|AC| = |BD|, m.")],
    l2: Annotated[float, typer.Argument(metavar="L2", help="|CP| = |DP|, m.")],
    kappa_max: Annotated[float, typer.Option(help="Bound on kappa(A), >= 1.")] = 10.0,
) -> None:
    """Which parallel singularities a design (L0, L1, L2) can have, its operative working
    modes, workspace volume and well-conditioned fraction."""
    from planner.analysis.design_check import check_design
    from planner.design import Design
    from planner.exceptions import PlannerError

    try:
        check = check_design(Design(l0, l1, l2), kappa_max=kappa_max)
    except PlannerError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from None
    kinds = ", ".join(check.parallel_singularities) or "none"
    typer.echo(f"design: L0 = {l0:g} m, L1 = {l1:g} m, L2 = {l2:g} m")
    typer.echo(f"volume (closed form, no joint limits): {check.volume:.6g} m^3")
    typer.echo(f"parallel singularities: {kinds}")
    for kind, why in check.reasons.items():
        typer.echo(f"  {kind}: {why}")
    typer.echo(f"singularity free: {'yes' if check.singularity_free else 'no'}")
    typer.echo(f"operative working modes: {' '.join(check.operative_working_modes) or 'none'}")
    wc = check.well_conditioned_fraction
    typer.echo(
        f"well-conditioned fraction (kappa(A) <= {check.kappa_max:g}): "
        f"{wc.value:.4f} +- {wc.standard_error:.4f}"
    )


if __name__ == "__main__":  # pragma: no cover
    app()
