"""``planner check-design``, ``planner optimize-design`` and ``planner regions``: what a design
can do, the design that maximises an objective, and a design's region map, computed in this
process."""

from __future__ import annotations

from typing import Annotated, Any

import typer

from planner_cli._support import Progress
from planner_cli.common import DesignOption, L0Option, L1Option, L2Option, design_data

__all__ = ["check_design_command", "optimize_design_command", "regions", "regions_table"]


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

    check = check_design(Design(l0, l1, l2), kappa_max=kappa_max)
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
    d = best.design
    typer.echo(f"design: L0 = {d.L0:.6g} m, L1 = {d.L1:.6g} m, L2 = {d.L2:.6g} m")
    typer.echo(f"{objective}: {best.value:.6g}")
    typer.echo(f"volume (closed form): {closed_form_volume(d):.6g} m^3")
    typer.echo(f"evaluations: {best.evaluations}; converged: {'yes' if best.success else 'no'}")


def regions(
    design: DesignOption = "default",
    l0: L0Option = None,
    l1: L1Option = None,
    l2: L2Option = None,
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

    Prints its connected regions (working mode, assembly mode, cells) and the transits
    between them across serial surfaces (each end's region and its cells, and the crossing
    cells of the transit set that joins them), or with --json the answer of POST
    /v1/design/regions. Example: planner regions --design paper-optimum --resolution 128"""
    from planner.endpoints.design import regions as job
    from planner.wire import RegionsRequest

    margins = {k: v for k, v in {"kappa_max": kappa_max, "serial_min": serial_min}.items() if v}
    data = {"design": design_data(design, l0, l1, l2), "margins": margins, "resolution": resolution}
    answer = job(RegionsRequest.model_validate(data))
    if as_json:
        typer.echo(answer.model_dump_json(indent=2))
    else:
        typer.echo("\n".join(regions_table(answer)))


def regions_table(answer: Any) -> list[str]:
    """The lines of ``planner regions`` for a :class:`planner.wire.RegionsResponse`: the
    design, a table of the regions, and one of the transits.

    A transit's row gives each end's own cells (those of its region, as in the regions'
    table) and the ``crossing`` cells: the cells where the flipped measure may vanish, of the
    component of the transit set that holds both ends. One component can join several
    regions (region 0 with regions 3 and 4, say): its crossing count is then the same on
    each of their rows, being the component's and not a pair's.
    """
    d, m = answer.design, answer.margins
    cells = {r.id: r.cells for r in answer.regions}
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
    lines.append(
        f"transits: {len(answer.transits)} (cells: each end region's own; crossing: the cells "
        "where the flipped measure may vanish in the transit set's component joining them)"
    )
    lines.append(
        f"{'from':>4}  {'cells':>7}  {'to':>4}  {'cells':>7}  {'kind':<16}  {'flipped':<7}  "
        f"{'crossing':>8}"
    )
    lines += [
        f"{t.from_:>4}  {cells[t.from_]:>7}  {t.to:>4}  {cells[t.to]:>7}  {t.kind:<16}  "
        f"{t.flipped:<7}  {t.cells:>8}"
        for t in answer.transits
    ]
    return lines
