"""What several commands of the ``planner`` command line share: the design options
(``--design`` preset, ``--L0``/``--L1``/``--L2`` overrides) and the wire design they make."""

from __future__ import annotations

from typing import Annotated

import typer

__all__ = ["DesignOption", "L0Option", "L1Option", "L2Option", "design_data"]

DesignOption = Annotated[
    str, typer.Option("--design", help="Preset: default, singularity-free, paper-optimum.")
]
L0Option = Annotated[float | None, typer.Option("--L0", help="Override L0, m.")]
L1Option = Annotated[float | None, typer.Option("--L1", help="Override L1, m.")]
L2Option = Annotated[float | None, typer.Option("--L2", help="Override L2, m.")]


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
