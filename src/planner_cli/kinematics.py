"""``planner fk`` and ``planner ik``: the service's kinematics jobs run in this process, their
JSON printed as the endpoints answer it; ``ik`` says why when no posture reaches the point."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import typer

from planner_cli.common import DesignOption, L0Option, L1Option, L2Option, design_data
from planner_cli.errors import EXIT_NO_ANSWER, fail

if TYPE_CHECKING:
    from planner.design import Design

__all__ = ["fk", "ik", "no_assembly_reason", "no_posture_reason"]


def fk(
    q: Annotated[list[float], typer.Argument(help="Joint angles theta1 theta2 theta3, rad.")],
    assembly_mode: Annotated[str | None, typer.Option(help="'+' or '-' (default: both).")] = None,
    design: DesignOption = "default",
    l0: L0Option = None,
    l1: L1Option = None,
    l2: L2Option = None,
) -> None:
    """Direct kinematics of q, computed locally.

    Prints the JSON that POST /v1/fk answers. Example: planner fk 0.2 -1.0 2.0

    Exit status: 0 one posture or more; 1 none (the JSON's list is empty, and stderr says why:
    the loop does not close, |CD| > 2 L2, or C = D leaves P undetermined); 2 an invalid input."""
    from planner.endpoints.kinematics import fk as job
    from planner.wire import FKRequest

    data = {"q": q, "assembly_mode": assembly_mode, "design": design_data(design, l0, l1, l2)}
    body = FKRequest.model_validate(data)
    answer = job(body)
    typer.echo(answer.model_dump_json(indent=2))
    if not answer.postures:
        fail([no_assembly_reason(body.design.to_design(), body.q, assembly_mode)], EXIT_NO_ANSWER)


def no_assembly_reason(design: Design, q: list[float], assembly_mode: str | None) -> str:
    """Why no posture of ``design`` has the actuated joints ``q``: the library's own
    :class:`~planner.exceptions.AssemblyError` (|CD| against 2 L2, or C on D), which
    :meth:`planner.kinematics.Manipulator.posture` raises for either assembly mode."""
    import numpy as np

    from planner.exceptions import AssemblyError
    from planner.kinematics import Manipulator

    at = "(" + ", ".join(f"{x:.6g}" for x in q) + ")"
    mode = "in any assembly mode" if assembly_mode is None else f"in assembly mode {assembly_mode}"
    try:
        Manipulator(design).posture(np.array(q, dtype=float), "-" if assembly_mode == "-" else "+")
    except AssemblyError as exc:
        return f"no posture has q = {at} {mode}: {exc}"
    return f"no posture has q = {at} {mode}"


def ik(
    p: Annotated[list[float], typer.Argument(help="Coordinates x y z of the point P, m.")],
    working_mode: Annotated[str, typer.Option(help="e.g. '+-+', or 'any'.")] = "any",
    design: DesignOption = "default",
    l0: L0Option = None,
    l1: L1Option = None,
    l2: L2Option = None,
) -> None:
    """Inverse kinematics of P, computed locally.

    Prints the JSON that POST /v1/ik answers. Example: planner ik -0.25 0.1 0.3

    Exit status: 0 one posture or more; 1 none (the JSON's list is empty, and stderr says why:
    P out of reach of a leg, or reached only in other working modes); 2 an invalid input."""
    from planner.endpoints.kinematics import ik as job
    from planner.wire import IKRequest

    data = {"p": p, "working_mode": working_mode, "design": design_data(design, l0, l1, l2)}
    body = IKRequest.model_validate(data)
    answer = job(body)
    typer.echo(answer.model_dump_json(indent=2))
    if answer.postures:
        return
    modes = []  # the working modes that reach P, when the request asked for one of them
    if working_mode != "any":
        every = job(body.model_copy(update={"working_mode": "any"}))
        modes = [posture.working_mode for posture in every.postures]
    fail([no_posture_reason(body.design.to_design(), body.p, working_mode, modes)], EXIT_NO_ANSWER)


def no_posture_reason(design: Design, p: list[float], working_mode: str, reached: list[str]) -> str:
    """Why no posture of ``design`` in ``working_mode`` reaches P: the working modes that do
    reach it (``reached``, the labels of ``planner ik``'s postures in any mode; a '0' marks a
    posture on a serial singularity, where two modes meet), or, when none does, the leg that
    cannot (:func:`planner.kinematics.reach_reason`)."""
    at = "(" + ", ".join(f"{x:.6g}" for x in p) + ")"
    if reached:
        on_singularity = any("0" in mode for mode in reached)
        return (
            f"no posture in working mode {working_mode} reaches P = {at}; it is reached in "
            f"working mode{'s' if len(reached) > 1 else ''} {', '.join(reached)} only"
            + (
                " (a 0 sign: P on that serial singularity, where the + and - modes meet)"
                if on_singularity
                else ""
            )
        )
    from planner.kinematics import reach_reason

    why = reach_reason(design, p)
    return f"no posture reaches P = {at} in any working mode" + (f": {why}" if why else "")
