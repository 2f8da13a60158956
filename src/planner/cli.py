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
    host: Annotated[str | None, typer.Option(help="Interface to bind (env PLANNER_HOST).")] = None,
    port: Annotated[
        int | None, typer.Option(help="TCP port (env PLANNER_PORT).", min=1, max=65535)
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(help="Worker processes (env PLANNER_WORKERS, default: the CPUs).", min=1),
    ] = None,
    log_level: Annotated[
        str | None,
        typer.Option(help="Log level: debug, info, warning, error (env PLANNER_LOG_LEVEL)."),
    ] = None,
    log_format: Annotated[
        str | None, typer.Option(help="Log format: json or text (env PLANNER_LOG_FORMAT).")
    ] = None,
    shutdown_timeout: Annotated[
        float | None,
        typer.Option(
            help="Grace for in-flight requests on SIGTERM, s (env PLANNER_SHUTDOWN_TIMEOUT_S).",
            min=0.0,
        ),
    ] = None,
) -> None:
    """Start the HTTP service (every setting also from PLANNER_* environment variables)."""
    from pydantic import ValidationError

    from api.server import run
    from api.settings import Settings

    given = {
        "host": host,
        "port": port,
        "workers": workers,
        "log_level": log_level.lower() if log_level else None,
        "log_format": log_format,
        "shutdown_timeout_s": shutdown_timeout,
    }
    try:
        settings = Settings(**{k: v for k, v in given.items() if v is not None})
    except ValidationError as exc:
        for e in exc.errors():
            typer.echo(f"error: {'.'.join(map(str, e['loc']))}: {e['msg']}", err=True)
        raise typer.Exit(2) from None
    run(settings)


_PRESETS = {
    "default": "default",
    "singularity-free": "singularity_free",
    "paper-optimum": "paper_optimum",
}


def _design_option(preset: str, l0: float | None, l1: float | None, l2: float | None) -> dict:
    from planner.design import Design
    from planner.schemas import DesignModel

    if preset not in _PRESETS:
        raise typer.BadParameter(f"one of {', '.join(_PRESETS)}", param_hint="--design")
    base = DesignModel.from_design(getattr(Design, _PRESETS[preset])()).model_dump()
    base.update({k: v for k, v in {"L0": l0, "L1": l1, "L2": l2}.items() if v is not None})
    return base


def _run_job(job, model, data: dict) -> None:  # type: ignore[no-untyped-def]
    """Validate ``data`` as ``model``, run ``job`` locally and echo its JSON answer."""
    from pydantic import ValidationError

    from planner.exceptions import PlannerError

    try:
        answer = job(model.model_validate(data))
    except ValidationError as exc:
        for e in exc.errors():
            typer.echo(f"error: {'.'.join(map(str, e['loc']))}: {e['msg']}", err=True)
        raise typer.Exit(2) from None
    except PlannerError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from None
    typer.echo(answer.model_dump_json(indent=2))


_Design = Annotated[
    str, typer.Option("--design", help="Preset: default, singularity-free, paper-optimum.")
]
_L0 = Annotated[float | None, typer.Option("--L0", help="Override L0, m.")]
_L1 = Annotated[float | None, typer.Option("--L1", help="Override L1, m.")]
_L2 = Annotated[float | None, typer.Option("--L2", help="Override L2, m.")]


@app.command()
def fk(
    q: Annotated[
        list[float], typer.Argument(help="theta1 theta2 theta3, rad (after -- if one is negative).")
    ],
    assembly_mode: Annotated[str | None, typer.Option(help="'+' or '-' (default: both).")] = None,
    design: _Design = "default",
    l0: _L0 = None,
    l1: _L1 = None,
    l2: _L2 = None,
) -> None:
    """Direct kinematics of q, computed locally; prints the JSON of POST /v1/fk."""
    from api.compute import fk as job
    from planner.schemas import FKRequest

    _run_job(
        job,
        FKRequest,
        {"q": q, "assembly_mode": assembly_mode, "design": _design_option(design, l0, l1, l2)},
    )


@app.command()
def ik(
    p: Annotated[list[float], typer.Argument(help="x y z of P, m (after -- if one is negative).")],
    working_mode: Annotated[str, typer.Option(help="e.g. '+-+', or 'any'.")] = "any",
    design: _Design = "default",
    l0: _L0 = None,
    l1: _L1 = None,
    l2: _L2 = None,
) -> None:
    """Inverse kinematics of P, computed locally; prints the JSON of POST /v1/ik."""
    from api.compute import ik as job
    from planner.schemas import IKRequest

    _run_job(
        job,
        IKRequest,
        {"p": p, "working_mode": working_mode, "design": _design_option(design, l0, l1, l2)},
    )


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
