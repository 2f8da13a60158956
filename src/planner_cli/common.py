"""What several commands of the ``planner`` command line share: the design options
(``--design`` preset, ``--L0``/``--L1``/``--L2`` overrides, and for the dynamics commands
``--inertia FILE`` / ``--payload-mass``) and the wire design they make."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

__all__ = [
    "DesignOption",
    "InertiaOption",
    "L0Option",
    "L1Option",
    "L2Option",
    "PayloadOption",
    "design_data",
    "with_inertia",
]

DesignOption = Annotated[
    str, typer.Option("--design", help="Preset: default, singularity-free, paper-optimum.")
]
L0Option = Annotated[float | None, typer.Option("--L0", help="Override L0, m.")]
L1Option = Annotated[float | None, typer.Option("--L1", help="Override L1, m.")]
L2Option = Annotated[float | None, typer.Option("--L2", help="Override L2, m.")]
InertiaOption = Annotated[
    Path | None,
    typer.Option(
        "--inertia",
        help='A JSON file: the design\'s inertia (e.g. {"proximal": {"mass": 0.3}, "payload": '
        '{"mass": 1}}); absent parts and fields take the defaults of docs/dynamics.md.',
    ),
]
PayloadOption = Annotated[
    float | None, typer.Option("--payload-mass", help="Payload at P, kg (over --inertia's).")
]


def design_data(preset: str, l0: float | None, l1: float | None, l2: float | None) -> dict:
    """The wire design (a :class:`planner.wire.DesignModel` dump) of the preset with the
    lengths given overriding its own; an unknown preset is a usage error naming --design.
    The request model that takes it checks the lengths (and names ``design.L2``)."""
    from planner.design import PRESET_NAMES, Design
    from planner.wire import DesignModel

    if preset not in PRESET_NAMES:
        raise typer.BadParameter(f"one of {', '.join(PRESET_NAMES)}", param_hint="--design")
    base = DesignModel.from_design(Design.preset(preset)).model_dump()
    base.update({k: v for k, v in {"L0": l0, "L1": l1, "L2": l2}.items() if v is not None})
    return base


def with_inertia(design: dict, inertia: Path | None, payload_mass: float | None) -> dict:
    """``design`` (a wire design dump) with the inertia of ``--inertia`` (a JSON file of
    ``design.inertia``) and ``--payload-mass`` over it; the request model checks the
    numbers (and names ``design.inertia.<part>.<field>``). Unreadable file: a usage error
    naming --inertia."""
    data: dict = {}
    if inertia is not None:
        try:
            data = json.loads(inertia.read_text())
        except (OSError, ValueError) as exc:
            raise typer.BadParameter(
                f"cannot read JSON from {str(inertia)!r}: {exc}", param_hint="--inertia"
            ) from exc
        if not isinstance(data, dict):
            raise typer.BadParameter(
                "a JSON object: {proximal, distal, payload, base, rotor}", param_hint="--inertia"
            )
    if payload_mass is not None:
        data = {**data, "payload": {"mass": payload_mass}}
    return {**design, "inertia": data} if data else design
