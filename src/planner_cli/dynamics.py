"""``planner dynamics`` and ``planner mjcf``: the service's dynamics job run in this process
(its JSON printed as ``POST /v1/dynamics`` answers it), and the robot as an MJCF model for
MuJoCo (``docs/dynamics.md``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from planner_cli.common import DesignOption, L0Option, L1Option, L2Option, design_data
from planner_cli.errors import fail

__all__ = ["dynamics", "mjcf"]

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
) -> None:
    """Actuator torques and mass matrix of a motion, computed locally.

    Prints the JSON that POST /v1/dynamics answers (tau, N m; mass_matrix). Example:
    planner dynamics 0 2 1 --qdd 1,0,0  (the default inertia: docs/dynamics.md)"""
    from planner.wire import DynamicsRequest
    from planner_api.jobs.dynamics import dynamics as job

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
            "design": design_data(design, l0, l1, l2),
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
) -> None:
    """The robot as an MJCF model for MuJoCo: two legs from the turning base, the loop closed
    at P by an equality connect, motors on theta1..theta3, rotor inertia as armature, a
    keyframe 'home' assembled in the asked mode (default inertia: docs/dynamics.md)."""
    from planner.dynamics.mjcf import to_mjcf
    from planner.wire import DesignModel, located

    model = DesignModel.model_validate(design_data(design, l0, l1, l2))
    with located("home"):
        text = to_mjcf(
            model.to_design(), gravity=_triple("gravity", gravity),
            home=_triple("home", home), assembly_mode=assembly_mode,
        )  # fmt: skip
    if output is None:
        typer.echo(text, nl=False)
    else:
        output.write_text(text)
