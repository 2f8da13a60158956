"""``planner figures``: the paper's figures 4-15, or named figures of a design, as image
files."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from planner_cli._support import Progress
from planner_cli.common import DesignOption, L0Option, L1Option, L2Option, design_data
from planner_cli.errors import fail

__all__ = ["figures"]


def figures(
    outdir: Annotated[Path, typer.Argument(help="Directory to write the figures into.")],
    n: Annotated[
        int, typer.Option(help="Cells per axis of the section grids.", min=16, max=2048)
    ] = 256,
    formats: Annotated[str, typer.Option(help="Comma-separated formats.")] = "png,svg",
    dpi: Annotated[int, typer.Option(help="Resolution of PNG files.", min=20, max=600)] = 80,
    named: Annotated[
        str,
        typer.Option(
            help="Comma-separated figure names of GET /v1/figures (e.g. region_map) to write "
            "for --design instead of the paper's figures."
        ),
    ] = "",
    design: DesignOption = "default",
    l0: L0Option = None,
    l1: L1Option = None,
    l2: L2Option = None,
) -> None:
    """Write the paper's figures 4-15 as image files.

    One file per figure and format; prints the path of each file written. With --named, the
    named figures of a design instead (NAME.FORMAT), e.g. planner figures out --named
    region_map,regions_convex_mode --design paper-optimum"""
    from planner.exceptions import InputError
    from planner.plotting import FIGURE_FORMATS, FIGURES, check_formats, write_figures

    fmts = tuple(f.strip() for f in formats.split(",") if f.strip())
    try:  # before any figure is drawn: a named figure is served as PNG or SVG only
        check_formats(fmts, FIGURE_FORMATS if named else None)
    except InputError as exc:
        fail([f"--formats: {exc}"])
    if named:
        _write_named_figures(outdir, named, design_data(design, l0, l1, l2), n, fmts, dpi)
        return
    with Progress("figures", len(FIGURES)) as progress:
        for index, (number, (stem, _)) in enumerate(FIGURES.items()):
            progress.step(f"figure {number}: {stem}", index)
            for path in write_figures(outdir, n=n, formats=fmts, dpi=dpi, only=(number,)):
                progress.echo(str(path))
        progress.step("done", len(FIGURES))


def _write_named_figures(
    outdir: Path, named: str, design: dict, n: int, fmts: tuple[str, ...], dpi: int
) -> None:
    """``planner figures --named``: each named figure of ``design`` in each format."""
    from planner.plotting import NAMED_FIGURES, render_figure
    from planner.wire import DesignModel

    names = [name.strip() for name in named.split(",") if name.strip()]
    unknown = [name for name in names if name not in NAMED_FIGURES]
    if unknown:
        fail([f"--named: no figure {unknown[0]!r}; one of {sorted(NAMED_FIGURES)}"])
    outdir.mkdir(parents=True, exist_ok=True)
    with Progress("figures", len(names)) as progress:
        for index, name in enumerate(names):
            progress.step(f"figure {name}", index)
            for fmt in fmts:
                image = render_figure(
                    name, DesignModel(**design).to_design(), n=n, fmt=fmt, dpi=dpi
                )
                path = outdir / f"{name}.{fmt}"
                path.write_bytes(image)
                progress.echo(str(path))
        progress.step("done", len(names))
