"""``POST /v1/workspace`` (sampled volumes and sections) and the figure query of
``GET /v1/figures/{name}``.
"""

from __future__ import annotations

from typing import Literal

from pydantic import (
    ConfigDict,
    Field,
    model_validator,
)

from planner.design import Design
from planner.exceptions import DesignError
from planner.wire.common import (
    _DEFAULT,
    Angle,
    DesignModel,
    Integer,
    Length,
    LinkLength,
    WorkingModeLabel,
    _DesignField,
    _Request,
    _Response,
)
from planner.wire.design import SampledValue

__all__ = [
    "MAX_SECTION_RESOLUTION",
    "FigureQuery",
    "SectionGrid",
    "SectionOptions",
    "WorkspaceRequest",
    "WorkspaceResponse",
]

# ---------------------------------------------------------------------------- workspace
#: Hard cap on the cells per axis of a section grid (the service's own, lower cap is the
#: setting ``max_section_resolution``); the library's bound (``analysis.sections.MAX_GRID``).
MAX_SECTION_RESOLUTION = 2048


class SectionOptions(_Request):
    """Which sections of ``POST /v1/workspace`` to compute, and how fine."""

    resolution: Integer = Field(
        64,
        ge=2,
        le=MAX_SECTION_RESOLUTION,
        description="Cells per axis of each grid (the service caps it with a setting).",
    )
    theta1: Angle = Field(0.0, description="Plane of the Cartesian section, rad.")
    cartesian: bool = Field(True, description="Compute the (u, w) section of the linkage plane.")
    joint: bool = Field(True, description="Compute the (theta2, theta3) section.")


class WorkspaceRequest(_Request):
    """Body of ``POST /v1/workspace``: volumes (closed form and sampled) and sections."""

    design: DesignModel = _DesignField
    rel_se: float = Field(
        0.01,
        ge=1e-3,
        le=0.5,
        allow_inf_nan=False,
        description="Relative standard error asked of the sampled volume.",
    )
    kappa_max: float = Field(
        10.0,
        ge=1.0,
        le=1e12,
        allow_inf_nan=False,
        description="Bound on kappa(A) of the well-conditioned volume.",
    )
    working_modes: list[WorkingModeLabel] | None = Field(
        None,
        min_length=1,
        max_length=8,
        description="Working modes counted in the sampled volume (absent: all eight).",
    )
    joint_limits: bool = Field(True, description="Apply the design's joint limits.")
    seed: Integer = Field(0, ge=0, le=2**32 - 1, description="Seed of the quasi-random sampling.")
    sections: SectionOptions = Field(default_factory=SectionOptions)


class SectionGrid(_Response):
    """One labelled section as grids of ny x nx cells (row j: ``y[j]``, column i: ``x[i]``).

    Per cell, ``reached`` and ``singular`` are bit masks over ``labels`` (bit k set: slot
    ``labels[k]``); ``best_kappa`` is the smallest kappa(A) over the reaching slots (null where
    none reaches, or all reaching postures are parallel-singular). A joint section also gives
    the working mode of each assembly mode's posture (null where it does not assemble)."""

    kind: Literal["cartesian", "joint"]
    x: list[float] = Field(description="Cell centres: u (m) or theta2 (rad).")
    y: list[float] = Field(description="Cell centres: w (m) or theta3 (rad).")
    theta1: float = Field(description="The section's theta1, rad.")
    labels: list[str] = Field(description="Slots: the 8 working modes or the 2 assembly modes.")
    reached: list[list[int]] = Field(description="ny x nx bit masks of the reaching slots.")
    singular: list[list[int]] = Field(description="ny x nx bit masks of the singular slots.")
    best_kappa: list[list[float | None]] = Field(description="ny x nx smallest kappa(A).")
    working_mode: list[list[list[str | None]]] | None = Field(
        None, description="Joint section: ny x nx x 2 working-mode labels ('0': singular sign)."
    )


class WorkspaceResponse(_Response):
    """Answer of ``POST /v1/workspace``."""

    design: DesignModel
    volume: float = Field(description="Closed-form workspace volume without joint limits, m^3.")
    sampled_volume: SampledValue = Field(
        description="Volume reached by an allowed working mode (within the joint limits), m^3."
    )
    per_mode: dict[str, SampledValue] = Field(description="Volume reached by each mode, m^3.")
    kappa_max: float
    well_conditioned_volume: SampledValue = Field(
        description="Volume where some allowed posture has kappa(A) <= kappa_max, m^3."
    )
    well_conditioned_fraction: SampledValue
    gci: SampledValue = Field(description="Global conditioning index (mean 1/kappa(A)).")
    cartesian_section: SectionGrid | None = None
    joint_section: SectionGrid | None = None


# ---------------------------------------------------------------------------- figures
class FigureQuery(_Request):
    """Query parameters of ``GET /v1/figures/{name}.png|svg``: the design (absent fields: the
    default robot) and the rendering. Query strings are text: numbers are parsed (lax)."""

    model_config = ConfigDict(extra="forbid", strict=False)

    L0: Length = Field(_DEFAULT.L0, description="|AB|, m.")
    L1: LinkLength = Field(_DEFAULT.L1, description="|AC| = |BD|, m.")
    L2: LinkLength = Field(_DEFAULT.L2, description="|CP| = |DP|, m.")
    resolution: int = Field(
        96,
        ge=16,
        le=MAX_SECTION_RESOLUTION,
        description="Cells per axis of section grids: 96 (screen, the viewer's default) or "
        "256 for print quality (the service caps it with a setting).",
    )
    dpi: int = Field(80, ge=20, le=300, description="Resolution of a PNG (150 for print).")

    @model_validator(mode="after")
    def _check_design(self) -> FigureQuery:
        try:
            self.design()
        except DesignError as exc:
            raise ValueError(str(exc)) from exc
        return self

    def design(self) -> Design:
        """The library design drawn (full joint turns, default link radius)."""
        return Design(L0=self.L0, L1=self.L1, L2=self.L2)
