"""``planner dynamics`` and ``planner mjcf``: the service's dynamics job run in this process
(its JSON printed as ``POST /v1/dynamics`` answers it), and the robot as an MJCF model for
MuJoCo (``docs/dynamics.md``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from planner_cli.common import (
    DesignOption,
    InertiaOption,
    L0Option,
    L1Option,
    L2Option,
    PayloadOption,
    design_data,
    with_inertia,
)
from planner_cli.errors import fail

__all__ = ["dynamics", "inertia_report", "mjcf"]

_TripleOption = Annotated[str, typer.Option(help="Three comma-separated numbers.")]


def _triple(name: str, text: str) -> list[float]:
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        fail([f"--{name} must be three comma-separated numbers, got {text!r}"])
    if len(values) != 3:
        fail([f"--{name} must be three comma-separated numbers, got {len(values)}"])
    return values


def dynamics(
    q: Annotated[
        list[float] | None, typer.Argument(help="Joint angles theta1 theta2 theta3, rad.")
    ] = None,
    qd: _TripleOption = "0,0,0",
    qdd: _TripleOption = "0,0,0",
    gravity: _TripleOption = "0,0,-9.81",
    assembly_mode: Annotated[str, typer.Option(help="'+' or '-'.")] = "+",
    request: Annotated[
        Path | None,
        typer.Option(help="A JSON body of POST /v1/dynamics (N postures) instead of q."),
    ] = None,
    design: DesignOption = "default",
    l0: L0Option = None,
    l1: L1Option = None,
    l2: L2Option = None,
    inertia: InertiaOption = None,
    payload_mass: PayloadOption = None,
) -> None:
    """Actuator torques and mass matrix of a motion, computed locally.

    Prints the JSON that POST /v1/dynamics answers (tau, N m; mass_matrix). Example:
    planner dynamics 0 2 1 --qdd 1,0,0  (the default inertia: docs/dynamics.md)"""
    from planner.endpoints.dynamics import dynamics as job
    from planner.wire import DynamicsRequest

    if request is not None:
        try:
            data = json.loads(request.read_text())
        except (OSError, ValueError) as exc:
            fail([f"--request: cannot read a JSON body from {str(request)!r}: {exc}"])
    else:
        if q is None or len(q) != 3:
            fail(["give q as three angles theta1 theta2 theta3 (rad), or --request FILE"])
        data = {
            "q": [q],
            "qd": [_triple("qd", qd)],
            "qdd": [_triple("qdd", qdd)],
            "gravity": _triple("gravity", gravity),
            "assembly_mode": assembly_mode,
            "design": with_inertia(design_data(design, l0, l1, l2), inertia, payload_mass),
        }
    typer.echo(job(DynamicsRequest.model_validate(data)).model_dump_json(indent=2))


def mjcf(
    output: Annotated[
        Path | None, typer.Option(help="Write the model here (default: stdout).")
    ] = None,
    home: Annotated[str, typer.Option(help="Keyframe q, three comma-separated rad.")] = "0,2,1",
    assembly_mode: Annotated[str, typer.Option(help="'+' or '-' of the keyframe.")] = "+",
    gravity: _TripleOption = "0,0,-9.81",
    design: DesignOption = "default",
    l0: L0Option = None,
    l1: L1Option = None,
    l2: L2Option = None,
    inertia: InertiaOption = None,
    payload_mass: PayloadOption = None,
) -> None:
    """The robot as an MJCF model for MuJoCo: two legs from the turning base, the loop closed
    at P by an equality connect, motors on theta1..theta3, rotor inertia as armature, a
    keyframe 'home' assembled in the asked mode.

    Inertia: the defaults of docs/dynamics.md, or --inertia FILE (a design.inertia object;
    absent parts and fields default) and --payload-mass. Example: planner mjcf --inertia
    arm.json --payload-mass 1.5 -o arm.xml"""
    from planner.dynamics.mjcf import to_mjcf
    from planner.exceptions import InputError
    from planner.wire import DesignModel, inertia_to_core

    data = with_inertia(design_data(design, l0, l1, l2), inertia, payload_mass)
    model = DesignModel.model_validate(data)
    try:
        text = to_mjcf(
            model.to_design(),
            inertia_to_core(model, ("design", "inertia")),
            gravity=_triple("gravity", gravity),
            home=_triple("home", home),
            assembly_mode=assembly_mode,
        )
    except InputError as exc:  # about an option of this command: name it as typed
        if exc.field_path[:1] not in (("home",), ("gravity",)):
            raise
        fail([f"--{exc.field_path[0]}: {exc}"])
    if output is None:
        typer.echo(text, nl=False)
    else:
        output.write_text(text)


def inertia_report(
    resolution: Annotated[
        int, typer.Option(help="Cells per axis of the (theta2, theta3) grid.", min=8, max=256)
    ] = 256,
    samples: Annotated[
        int, typer.Option(help="Times at which the cycle's torques are taken.", min=100)
    ] = 4001,
) -> None:
    """The tables of docs/analysis.md, "Inertia against a serial arm": for the default and
    the paper-optimum designs with their default inertia, the largest eigenvalue of M per
    working mode over the workspace (kappa(A) <= 10, serial measures >= 0.05) for the
    five-bar and its serial counterpart (planner.dynamics.serial), and the peak and RMS
    torque of each actuator over the all-stops Adept cycle (planner.sequence.adept, TOPPRA
    under the default limits) for both robots moving P the same way, with gravity (total)
    and without it (the inertial part). Prints markdown."""
    import numpy as np

    from planner import Design
    from planner.dynamics import Inertia
    from planner.dynamics.analysis import cycle_torques, serial_comparison
    from planner.sequence.adept import place_adept_cycle

    designs = {"default": Design.default(), "paper-optimum": Design.paper_optimum()}
    typer.echo(
        "| design | working mode | cells | five-bar: median | p95 | max | serial: "
        "median | p95 | max | median ratio | planar block: five-bar median | serial "
        "median | median ratio |"
    )
    typer.echo("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, design in designs.items():
        cmp = serial_comparison(design, Inertia.default(design), resolution=resolution)
        for mode, r in cmp.by_mode().items():
            typer.echo(
                f"| {name} | {mode} | {int(r['cells'])} | {r['parallel_median']:.3f} | "
                f"{r['parallel_p95']:.3f} | {r['parallel_max']:.3f} | {r['serial_median']:.3f} | "
                f"{r['serial_p95']:.3f} | {r['serial_max']:.3f} | {r['ratio_median']:.2f} | "
                f"{r['parallel_planar_median']:.3f} | {r['serial_planar_median']:.3f} | "
                f"{r['planar_ratio_median']:.2f} |"
            )
    typer.echo("")
    typer.echo(
        "| design | cycle [s] | torque | robot | peak tau1, tau2, tau3 [N m] | "
        "RMS tau1, tau2, tau3 [N m] |"
    )
    typer.echo("|---|---|---|---|---|---|")
    for name, design in designs.items():
        inertia = Inertia.default(design)
        cycle = place_adept_cycle(design, inertia=inertia)
        traj = cycle.result.trajectory
        t = np.linspace(0.0, traj.duration, samples)
        q, qd, qdd, _ = traj.at(t)
        for part, gravity in (("total", (0.0, 0.0, -9.81)), ("inertial", (0.0, 0.0, 0.0))):
            par, ser = cycle_torques(
                design,
                inertia,
                t,
                q,
                qd,
                qdd,
                gravity=gravity,
                assembly_mode=cycle.start.assembly_mode,
            )
            for robot, st in (("five-bar", par), ("serial", ser)):
                typer.echo(
                    f"| {name} | {traj.duration:.3f} | {part} | {robot} | "
                    f"{', '.join(f'{x:.3f}' for x in st.peak)} | "
                    f"{', '.join(f'{x:.3f}' for x in st.rms)} |"
                )
