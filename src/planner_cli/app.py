"""The ``planner`` command line (typer).

Results go to stdout, progress and errors to stderr; every command that can run for more than
a few seconds shows what it is doing (see :class:`planner_cli._support.Progress`). Negative
numbers are arguments (``planner ik -0.25 0.1 0.3``) unless they are an option's value.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from planner_cli._support import Command, Group, Progress

__all__ = [
    "app",
    "bench",
    "builtin_bench_rows",
    "cartesian",
    "check_design_command",
    "command",
    "figures",
    "fk",
    "ik",
    "optimize_design_command",
    "plan",
    "regions",
    "serve",
    "version",
    "warm_up_command",
]

app = typer.Typer(
    cls=Group,
    help="Plan, time and analyse motions of the 3-DOF hybrid manipulator.",
    no_args_is_help=True,
    add_completion=False,
)


def command(name: str | None = None):  # type: ignore[no-untyped-def]
    """``app.command`` with :class:`planner_cli._support.Command` (negative numbers, help)."""
    return app.command(name, cls=Command)


@command()
def serve(
    host: Annotated[
        str | None, typer.Option(metavar="HOST", help="Interface to bind (env PLANNER_HOST).")
    ] = None,
    port: Annotated[
        int | None,
        typer.Option(metavar="PORT", help="TCP port (env PLANNER_PORT).", min=1, max=65535),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(
            metavar="N", help="Worker processes (env PLANNER_WORKERS, default: the CPUs).", min=1
        ),
    ] = None,
    log_level: Annotated[
        str | None,
        typer.Option(
            metavar="LEVEL", help="Log level: debug, info, warning, error (env PLANNER_LOG_LEVEL)."
        ),
    ] = None,
    log_format: Annotated[
        str | None,
        typer.Option(metavar="FORMAT", help="Log format: json or text (env PLANNER_LOG_FORMAT)."),
    ] = None,
    shutdown_timeout: Annotated[
        float | None,
        typer.Option(
            metavar="SECONDS",
            help="Seconds in-flight requests may finish after SIGTERM "
            "(env PLANNER_SHUTDOWN_TIMEOUT_S).",
            min=0.0,
        ),
    ] = None,
) -> None:
    """Start the HTTP service.

    Every setting can also come from a PLANNER_* environment variable; an option given here
    wins over the environment."""
    from pydantic import ValidationError

    from planner_api.server import run
    from planner_api.settings import Settings

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


def _design_option(preset: str, l0: float | None, l1: float | None, l2: float | None) -> dict:
    from planner.design import PRESET_NAMES, Design
    from planner.wire import DesignModel

    if preset not in PRESET_NAMES:
        raise typer.BadParameter(f"one of {', '.join(PRESET_NAMES)}", param_hint="--design")
    base = DesignModel.from_design(Design.preset(preset)).model_dump()
    base.update({k: v for k, v in {"L0": l0, "L1": l1, "L2": l2}.items() if v is not None})
    return base


def _run_job(job, model, data: dict) -> None:  # type: ignore[no-untyped-def]
    """Validate ``data`` as ``model``, run ``job`` locally and echo its JSON answer."""
    typer.echo(_job_answer(job, model, data).model_dump_json(indent=2))


def _job_answer(job, model, data: dict):  # type: ignore[no-untyped-def]
    """Validate ``data`` as ``model`` and run ``job`` locally; a bad field or a library
    error is printed (naming the field) and exits with status 2."""
    from pydantic import ValidationError

    from planner.exceptions import PlannerError

    try:
        return job(model.model_validate(data))
    except ValidationError as exc:
        for e in exc.errors():
            typer.echo(f"error: {'.'.join(map(str, e['loc']))}: {e['msg']}", err=True)
        raise typer.Exit(2) from None
    except PlannerError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from None


_Design = Annotated[
    str, typer.Option("--design", help="Preset: default, singularity-free, paper-optimum.")
]
_L0 = Annotated[float | None, typer.Option("--L0", help="Override L0, m.")]
_L1 = Annotated[float | None, typer.Option("--L1", help="Override L1, m.")]
_L2 = Annotated[float | None, typer.Option("--L2", help="Override L2, m.")]


@command()
def fk(
    q: Annotated[list[float], typer.Argument(help="Joint angles theta1 theta2 theta3, rad.")],
    assembly_mode: Annotated[str | None, typer.Option(help="'+' or '-' (default: both).")] = None,
    design: _Design = "default",
    l0: _L0 = None,
    l1: _L1 = None,
    l2: _L2 = None,
) -> None:
    """Direct kinematics of q, computed locally.

    Prints the JSON that POST /v1/fk answers. Example: planner fk 0.2 -1.0 2.0"""
    from planner.wire import FKRequest
    from planner_api.compute import fk as job

    _run_job(
        job,
        FKRequest,
        {"q": q, "assembly_mode": assembly_mode, "design": _design_option(design, l0, l1, l2)},
    )


@command()
def ik(
    p: Annotated[list[float], typer.Argument(help="Coordinates x y z of the point P, m.")],
    working_mode: Annotated[str, typer.Option(help="e.g. '+-+', or 'any'.")] = "any",
    design: _Design = "default",
    l0: _L0 = None,
    l1: _L1 = None,
    l2: _L2 = None,
) -> None:
    """Inverse kinematics of P, computed locally.

    Prints the JSON that POST /v1/ik answers. Example: planner ik -0.25 0.1 0.3"""
    from planner.wire import IKRequest
    from planner_api.compute import ik as job

    _run_job(
        job,
        IKRequest,
        {"p": p, "working_mode": working_mode, "design": _design_option(design, l0, l1, l2)},
    )


@command("warm-up")
def warm_up_command() -> None:
    """Compile the numba kernels and pay every first-call cost once.

    Compiles (or loads from numba's cache) every kernel, and runs a tiny plan, its timing
    with TOPPRA and Ruckig, an analysis and a figure, so that later processes start fast.
    The first run in an installation compiles for tens of seconds; later runs take seconds."""
    from planner.warmup import STEPS, warm_up

    with Progress("warm-up", len(STEPS)) as progress:
        seconds = warm_up(progress.step)
    typer.echo(f"warmed up in {seconds:.1f} s")


@command()
def version() -> None:
    """Print the package version."""
    import planner

    typer.echo(planner.__version__)


@command()
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
    design: _Design = "default",
    l0: _L0 = None,
    l1: _L1 = None,
    l2: _L2 = None,
) -> None:
    """Write the paper's figures 4-15 as image files.

    One file per figure and format; prints the path of each file written. With --named, the named figures of a design instead (NAME.FORMAT), e.g. planner figures out --named region_map,regions_convex_mode --design paper-optimum"""
    from planner.plotting import FIGURES, write_figures

    fmts = tuple(f.strip() for f in formats.split(",") if f.strip())
    if named:
        _write_named_figures(outdir, named, _design_option(design, l0, l1, l2), n, fmts, dpi)
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
    from planner.exceptions import PlannerError
    from planner.plotting import NAMED_FIGURES, render_figure
    from planner.wire import DesignModel

    names = [name.strip() for name in named.split(",") if name.strip()]
    unknown = [name for name in names if name not in NAMED_FIGURES]
    if unknown:
        typer.echo(f"error: --named: no figure {unknown[0]!r}; one of {sorted(NAMED_FIGURES)}",
                   err=True)  # fmt: skip
        raise typer.Exit(2)
    outdir.mkdir(parents=True, exist_ok=True)
    with Progress("figures", len(names)) as progress:
        for index, name in enumerate(names):
            progress.step(f"figure {name}", index)
            for fmt in fmts:
                try:
                    image = render_figure(name, DesignModel(**design).to_design(), n=n,
                                          fmt=fmt, dpi=dpi)  # fmt: skip
                except PlannerError as exc:
                    typer.echo(f"error: {exc}", err=True)
                    raise typer.Exit(2) from None
                path = outdir / f"{name}.{fmt}"
                path.write_bytes(image)
                progress.echo(str(path))
        progress.step("done", len(names))


@command("check-design")
def check_design_command(
    l0: Annotated[float, typer.Argument(metavar="L0", help="|AB|, m.")],
    l1: Annotated[float, typer.Argument(metavar="L1", help="|AC| = |BD|, m.")],
    l2: Annotated[float, typer.Argument(metavar="L2", help="|CP| = |DP|, m.")],
    kappa_max: Annotated[float, typer.Option(help="Bound on kappa(A), >= 1.")] = 10.0,
) -> None:
    """What a design (L0, L1, L2) can do.

    Prints which parallel singularities it can have and why, its operative working modes,
    its workspace volume and the well-conditioned fraction of it. Example:
    planner check-design 0 0.4 0.4"""
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


@command("optimize-design")
def optimize_design_command(
    objective: Annotated[
        str, typer.Option(help="volume, well_conditioned_volume or gci.")
    ] = "volume",
    reach: Annotated[
        float, typer.Option(help="Fixed L1 + L2, m (the variables are L0 and L1).", min=0.0)
    ] = 0.8,
    kappa_max: Annotated[
        float, typer.Option(help="Bound on kappa(A) of the well-conditioned volume.")
    ] = 10.0,
    samples: Annotated[
        int, typer.Option(help="Points per evaluation of a sampled objective.", min=8)
    ] = 4096,
    maxiter: Annotated[
        int, typer.Option(help="Generations of the differential evolution.", min=1)
    ] = 30,
    seed: Annotated[int, typer.Option(help="Seed of the sample and of the optimiser.")] = 0,
) -> None:
    """Find the link lengths that maximise an objective.

    The sampled objectives (well_conditioned_volume, gci) run a differential evolution for
    up to --maxiter generations, which can take minutes; the progress shows the generation.
    Prints the best design and its values."""
    from planner.analysis.optimize import optimize_design
    from planner.analysis.workspace import closed_form_volume
    from planner.exceptions import PlannerError

    try:
        with Progress("optimize-design") as progress:
            best = optimize_design(
                objective,
                reach=reach,
                kappa_max=kappa_max,
                n_samples=samples,
                maxiter=maxiter,
                seed=seed,
                progress=progress.step,
            )
    except PlannerError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from None
    d = best.design
    typer.echo(f"design: L0 = {d.L0:.6g} m, L1 = {d.L1:.6g} m, L2 = {d.L2:.6g} m")
    typer.echo(f"{objective}: {best.value:.6g}")
    typer.echo(f"volume (closed form): {closed_form_volume(d):.6g} m^3")
    typer.echo(f"evaluations: {best.evaluations}; converged: {'yes' if best.success else 'no'}")


# ---------------------------------------------------------------------------- plan
#: Exit statuses of ``planner plan``.
EXIT_SOLVED, EXIT_NOT_SOLVED, EXIT_BAD_INPUT = 0, 1, 2


def _regions_table(answer) -> list[str]:  # type: ignore[no-untyped-def]
    """The lines of ``planner regions``: the design, then a table of the regions and one of
    the transits."""
    d, m = answer.design, answer.margins
    lines = [
        f"design: L0 = {d.L0:g} m, L1 = {d.L1:g} m, L2 = {d.L2:g} m; kappa_max {m.kappa_max:g}, "
        f"serial_min {m.serial_min:g}; {answer.resolution} x {answer.resolution} cells",
        f"regions: {len(answer.regions)} in {answer.components} union-graph components",
        f"{'id':>4}  {'asm':>3}  {'mode':>4}  {'cells':>7}  {'valid':>7}  {'component':>9}",
    ]
    lines += [
        f"{r.id:>4}  {r.assembly_mode:>3}  {r.working_mode:>4}  {r.cells:>7}  {r.valid_cells:>7}  "
        f"{r.component:>9}"
        for r in answer.regions
    ]
    lines.append(f"transits: {len(answer.transits)}")
    lines.append(f"{'from':>4}  {'to':>4}  {'kind':<16}  {'flipped':<7}  {'cells':>6}")
    lines += [
        f"{t.from_:>4}  {t.to:>4}  {t.kind:<16}  {t.flipped:<7}  {t.cells:>6}"
        for t in answer.transits
    ]
    return lines


@command()
def regions(
    design: _Design = "default",
    l0: _L0 = None,
    l1: _L1 = None,
    l2: _L2 = None,
    kappa_max: Annotated[float | None, typer.Option(help="Bound on kappa(A), > 1.")] = None,
    serial_min: Annotated[
        float | None, typer.Option(help="Bound on each serial measure, in (0, 1).")
    ] = None,
    resolution: Annotated[int, typer.Option(help="Cells per axis, 16 .. 512.")] = 256,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print the JSON of POST /v1/design/regions.")
    ] = False,
) -> None:
    """The region map of a design, computed locally.

    Prints its connected regions (working mode, assembly mode, cells) and the transits between them across serial surfaces, or with --json the answer of POST /v1/design/regions. Example: planner regions --design paper-optimum --resolution 128"""
    from planner.wire import RegionsRequest
    from planner_api.compute_analysis import regions as job

    margins = {k: v for k, v in {"kappa_max": kappa_max, "serial_min": serial_min}.items() if v}
    data = {
        "design": _design_option(design, l0, l1, l2),
        "margins": margins,
        "resolution": resolution,
    }
    answer = _job_answer(job, RegionsRequest, data)
    if as_json:
        typer.echo(answer.model_dump_json(indent=2))
    else:
        typer.echo("\n".join(_regions_table(answer)))


def _plan_summary(response) -> list[str]:  # type: ignore[no-untyped-def]
    """One screen of text about a :class:`planner.wire.PlanResponse` (or a
    :class:`planner.wire.CartesianResponse`: with its fraction and stopping point)."""
    lines = [f"status: {response.status}"]
    if response.message:
        lines.append(f"message: {response.message}")
    fraction = getattr(response, "fraction", None)
    if fraction is not None:
        lines.append(f"fraction: {fraction:.6g}")
    stop = getattr(response, "stop", None)
    if stop is not None:
        p = ", ".join(f"{x:.5f}" for x in stop.p)
        value = "none" if stop.value is None else f"{stop.value:.6g}"
        lines.append(f"stopped by: {stop.rule} (value {value}) at P = [{p}]")
    path = response.path
    if path is not None:
        lines.append(f"waypoints: {len(path.waypoints)}")
        lines.append(f"segments: {len(path.segments)}")
        for seg in path.segments:
            lines.append(
                f"  working mode {seg.working_mode}, assembly mode {seg.assembly_mode}: "
                f"waypoints {seg.start_index}..{seg.end_index}"
            )
        lines.append(f"transits: {len(path.transits)}")
        for tr in path.transits:
            q = ", ".join(f"{x:.4f}" for x in tr.q)
            lines.append(f"  #{tr.index} {tr.kind} (flips {tr.flipped}) at q = [{q}]")
    traj = response.trajectory
    if traj is not None:
        samples = len(traj.points) if hasattr(traj, "points") else len(traj.t)
        lines.append(f"duration: {traj.duration:.4f} s ({traj.method}, {samples} samples)")
    else:
        lines.append("duration: none (no trajectory)")
    diag = response.diagnostics.model_dump(exclude_none=True)
    if diag:
        lines.append("diagnostics:")
        for key, value in diag.items():
            shown = f"{value:.6g}" if isinstance(value, float) else value
            lines.append(f"  {key}: {shown}")
    return lines


def _validation_lines(exc) -> list[str]:  # type: ignore[no-untyped-def]
    return [f"{'.'.join(map(str, e['loc'])) or 'body'}: {e['msg']}" for e in exc.errors()]


def _solve(job, body):  # type: ignore[no-untyped-def]
    """``job(body)`` in this process: the response, or the error lines naming the field."""
    from planner.exceptions import PlannerError

    try:
        return job(body), []
    except PlannerError as exc:
        where = ".".join(str(x) for x in getattr(exc, "loc", ())[1:])
        return None, [f"{where + ': ' if where else ''}{exc}"]


def _answer(response, errors: list[str], out: Path | None, csv: Path | None) -> None:  # type: ignore[no-untyped-def]
    """Print the summary, write ``--out`` and ``--csv``, and exit with the status's code."""
    if response is None:
        for line in errors:
            typer.echo(f"error: {line}", err=True)
        raise typer.Exit(EXIT_BAD_INPUT)
    for line in _plan_summary(response):
        typer.echo(line)
    if out is not None:
        out.write_text(response.model_dump_json(indent=2))
        typer.echo(f"full result: {out}")
    if csv is not None:
        if response.trajectory is None:
            typer.echo(f"error: no trajectory to write to {csv}", err=True)
        else:
            from planner.client import write_csv

            write_csv(response.trajectory, csv)
            typer.echo(f"trajectory CSV: {csv}")
    raise typer.Exit(EXIT_SOLVED if response.status == "solved" else EXIT_NOT_SOLVED)


_Out = Annotated[
    Path | None, typer.Option("--out", "-o", help="Write the full response JSON here.")
]
_Csv = Annotated[
    Path | None,
    typer.Option(
        "--csv",
        help="Write the trajectory as CSV here: columns t, theta1 to theta3 and their rates, "
        "under a line naming the units.",
    ),
]


@command()
def plan(
    request: Annotated[
        Path, typer.Argument(help="A PlanRequest as JSON (the body of POST /v1/plan).")
    ],
    out: _Out = None,
    csv: _Csv = None,
) -> None:
    """Plan and time a motion in this process, and print a summary.

    The summary gives the status, waypoints, segments, transits, duration and diagnostics.
    Exit status: 0 solved, 1 another status (no_path, unreachable, ...), 2 an invalid
    request."""
    errors: list[str] = []
    response = None
    with Progress("plan") as progress:
        progress.step("loading the planner", 0)
        from pydantic import ValidationError

        from planner.wire import PlanRequest
        from planner_api import compute

        try:
            body = PlanRequest.model_validate_json(request.read_bytes())
        except OSError as exc:
            errors.append(f"cannot read {request}: {exc}")
        except ValidationError as exc:
            errors += _validation_lines(exc)
        else:
            budget = body.planner.time_budget_s
            progress.step(f"planning (search budget {budget:g} s) and timing", 0)
            response, errors = _solve(compute.plan, body)
    _answer(response, errors, out, csv)


@command()
def cartesian(
    numbers: Annotated[
        list[float],
        typer.Argument(
            help="The start's joints theta1 theta2 theta3 (rad), then each waypoint's x y z "
            "(m), in order."
        ),
    ],
    assembly_mode: Annotated[str, typer.Option(help="The start's assembly mode, '+' or '-'.")] = (
        "+"
    ),
    path_tolerance: Annotated[
        float, typer.Option(help="Largest distance of P from the polyline, m.")
    ] = 1e-3,
    speed: Annotated[
        float | None, typer.Option(help="Tool speed bound (limits.cartesian_speed), m/s.")
    ] = None,
    method: Annotated[str, typer.Option(help="Timing: toppra, ruckig or none.")] = "toppra",
    velocity_scaling: Annotated[
        float, typer.Option(help="Factor in (0, 1] on the velocity limits.")
    ] = 1.0,
    acceleration_scaling: Annotated[
        float, typer.Option(help="Factor in (0, 1] on the acceleration limits.")
    ] = 1.0,
    trajectory_format: Annotated[
        str, typer.Option("--format", help="Trajectory of --out: arrays or points.")
    ] = "arrays",
    design: _Design = "default",
    l0: _L0 = None,
    l1: _L1 = None,
    l2: _L2 = None,
    out: _Out = None,
    csv: _Csv = None,
) -> None:
    """Move P on straight lines from the start through the waypoints, in this process.

    P keeps the start's working and assembly mode; where a rule would break, the path stops
    at the last valid point and the summary names the rule, the value and the point.
    Example: planner cartesian -0.2187 2.8609 0.2807 0.45 0.3 0.1 --speed 0.25. Exit
    status: 0 solved (the whole polyline), 1 stopped short, 2 an invalid request."""
    errors: list[str] = []
    response = None
    with Progress("cartesian") as progress:
        progress.step("loading the planner", 0)
        from pydantic import ValidationError

        from planner.wire import CartesianRequest
        from planner_api import compute

        if len(numbers) < 6 or len(numbers) % 3:
            errors.append(
                "numbers: give the start's 3 joint angles, then 3 coordinates per waypoint "
                f"(at least one waypoint), got {len(numbers)} numbers"
            )
        else:
            data = {
                "design": _design_option(design, l0, l1, l2),
                "start": {"q": numbers[:3], "assembly_mode": assembly_mode},
                "waypoints": [numbers[i : i + 3] for i in range(3, len(numbers), 3)],
                "path_tolerance": path_tolerance,
                "timing": {"method": method, "format": trajectory_format},
                "limits": {
                    "velocity_scaling": velocity_scaling,
                    "acceleration_scaling": acceleration_scaling,
                    **({"cartesian_speed": speed} if speed is not None else {}),
                },
            }
            try:
                body = CartesianRequest.model_validate(data)
            except ValidationError as exc:
                errors += _validation_lines(exc)
            else:
                progress.step(f"following {len(body.waypoints)} segment(s) and timing", 0)
                response, errors = _solve(compute.cartesian, body)
    _answer(response, errors, out, csv)


# ---------------------------------------------------------------------------- bench
#: Arguments of each benchmark script for ``planner bench --quick`` (small sizes).
QUICK_BENCH_ARGS: dict[str, list[str]] = {
    "kinematics": ["--n", "100000", "--loop-n", "200", "--repeat", "3"],
    "analysis": ["--n", "64", "--rel-se", "0.02", "--repeat", "3"],
    "timing": ["--paths", "10"],
    "service": ["--workers", "2", "--requests", "60"],
    "warmup": ["--repeat", "1"],
}


def _benchmarks_dir() -> Path | None:
    """The repository's ``benchmarks/`` (next to ``src/``), if this is a source checkout."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        candidate = parent / "benchmarks"
        if candidate.is_dir() and (parent / "src" / "planner").is_dir():
            return candidate
    return None


def _median_ms(fn, repeat: int = 5) -> float:  # type: ignore[no-untyped-def]
    import statistics
    import time

    fn()  # warm-up (numba compilation, imports)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def builtin_bench_rows(progress: Progress | None = None) -> list[tuple[str, float]]:
    """The quick built-in subset: (task, median ms) of the core operations, in-process;
    ``progress`` (optional) is told each task as it starts."""
    import numpy as np

    from planner.analysis.workspace import sample_workspace
    from planner.design import Design
    from planner.kinematics import forward_batch, inverse_batch
    from planner.timing import JointLimits, time_path

    design = Design.default()
    rng = np.random.default_rng(0)
    q = rng.uniform(-np.pi, np.pi, (100_000, 3))
    p = forward_batch(design, q, "+").p
    p = p[np.all(np.isfinite(p), axis=1)]
    path = np.cumsum(rng.uniform(-0.15, 0.15, (20, 3)), axis=0) + np.array([0.0, 0.5, 1.5])
    limits = JointLimits.default()
    tasks = [
        ("forward_batch, 100k postures", lambda: forward_batch(design, q, "+")),
        (f"inverse_batch, {len(p) // 1000}k points x 8 modes", lambda: inverse_batch(design, p)),
        (
            "sample_workspace, 1 % relative error",
            lambda: sample_workspace(design, rel_se=0.01, kappa_max=10.0),
        ),
        ("time_path toppra, 20 waypoints", lambda: time_path(design, path, limits)),
    ]
    rows = []
    for index, (task, fn) in enumerate(tasks):
        if progress is not None:
            progress.step(task, index, len(tasks))
        rows.append((task, _median_ms(fn)))
    if progress is not None:
        progress.step("done", len(tasks), len(tasks))
    return rows


@command()
def bench(
    names: Annotated[
        list[str] | None,
        typer.Argument(
            help="Benchmarks to run, among the scripts of benchmarks/ (default: all).",
            show_default=False,
        ),
    ] = None,
    quick: Annotated[bool, typer.Option(help="Small sizes (a minute or so in all).")] = False,
    builtin: Annotated[
        bool, typer.Option(help="Only the built-in in-process subset (no scripts).")
    ] = False,
) -> None:
    """Run the benchmarks and print their tables.

    Runs the scripts of benchmarks/ (each prints its table), or a built-in quick subset when
    asked or when there is no benchmarks/ directory (an installed package)."""
    import os
    import subprocess
    import sys

    folder = None if builtin else _benchmarks_dir()
    if folder is None:
        with Progress("bench", 4) as progress:
            rows = builtin_bench_rows(progress)
        typer.echo("built-in benchmark (median of 5 runs after a warm-up, one process):")
        typer.echo(f"{'task':<45} {'median ms':>10}")
        for task, ms in rows:
            typer.echo(f"{task:<45} {ms:>10.3f}")
        return
    available = sorted(f.stem for f in folder.glob("*.py") if not f.stem.startswith("_"))
    chosen = names or available
    unknown = [n for n in chosen if n not in available]
    if unknown:
        raise typer.BadParameter(
            f"unknown benchmark {', '.join(unknown)}; one of {', '.join(available)}",
            param_hint="NAMES",
        )
    root = folder.parent
    env = {**os.environ}
    env["PYTHONPATH"] = os.pathsep.join(
        [str(root / "src"), str(root), *filter(None, [env.get("PYTHONPATH")])]
    )
    failed = []
    with Progress("bench", len(chosen)) as progress:
        for index, name in enumerate(chosen):
            args = QUICK_BENCH_ARGS.get(name, []) if quick else []
            progress.step(name, index)
            progress.echo(f"== {name} ({' '.join(['benchmarks/' + name + '.py', *args])})")
            argv = [sys.executable, str(folder / f"{name}.py"), *args]
            if progress.terminal:  # its table is printed when it ends, not across the bar
                done = subprocess.run(argv, cwd=root, env=env, capture_output=True, text=True)
                progress.echo(done.stdout.rstrip("\n"))
                if done.stderr:
                    progress.echo(done.stderr.rstrip("\n"), err=True)
                code = done.returncode
            else:  # a log or a pipe: the table as it comes
                sys.stdout.flush()
                code = subprocess.call(argv, cwd=root, env=env)
            if code != 0:
                failed.append(name)
        progress.step("done", len(chosen))
    if failed:
        typer.echo(f"failed: {', '.join(failed)}", err=True)
        raise typer.Exit(1)
