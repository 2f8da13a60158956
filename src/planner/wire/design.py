"""``GET /v1/designs``, ``POST /v1/design/check`` and ``/v1/design/optimize``."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import (
    Field,
    field_validator,
)

from planner.design import MAX_LENGTH
from planner.wire.common import DesignModel, Length, _DesignField, _Request, _Response

__all__ = [
    "DesignCheckRequest",
    "DesignCheckResponse",
    "DesignOptimizeRequest",
    "DesignOptimizeResponse",
    "DesignPreset",
    "DesignsResponse",
    "LengthBounds",
    "SampledValue",
    "sampled_value",
]


class DesignPreset(_Response):
    """One named design of ``GET /v1/designs``."""

    name: str
    description: str
    design: DesignModel


class DesignsResponse(_Response):
    """Answer of ``GET /v1/designs``: the presets, ``default`` first."""

    presets: list[DesignPreset]


# ---------------------------------------------------------------------------- design check
class DesignCheckRequest(_Request):
    """Body of ``POST /v1/design/check``."""

    design: DesignModel = _DesignField
    kappa_max: float = Field(
        10.0,
        ge=1.0,
        le=1e12,
        allow_inf_nan=False,
        description="Bound on kappa(A) for the well-conditioned fraction.",
    )
    rel_se: float = Field(
        0.01,
        ge=1e-3,
        le=0.5,
        allow_inf_nan=False,
        description="Relative standard error asked of the sampled volume.",
    )
    seed: int = Field(0, ge=0, le=2**32 - 1, description="Seed of the quasi-random sampling.")


class SampledValue(_Response):
    """A sampled quantity and its standard error."""

    value: float
    standard_error: float
    n_samples: int


class DesignCheckResponse(_Response):
    """Answer of ``POST /v1/design/check``."""

    design: DesignModel
    volume: float = Field(description="Closed-form workspace volume without joint limits, m^3.")
    parallel_singularities: list[Literal["C=D", "CD_stretched"]] = Field(
        description="Parallel-singularity kinds that occur in the workspace."
    )
    singularity_free: bool = Field(description="No parallel singularity anywhere.")
    reasons: dict[str, str] = Field(description="Why each kind can or cannot occur.")
    operative_working_modes: list[str] = Field(
        description="Working modes with a regular (kappa(A) finite) posture in some volume."
    )
    sampled_volume: SampledValue = Field(description="Volume within the joint limits, m^3.")
    kappa_max: float
    well_conditioned_fraction: SampledValue = Field(
        description="Fraction of the sampled volume where some posture has kappa(A) <= kappa_max."
    )
    gci: SampledValue = Field(description="Global conditioning index (mean 1/kappa(A)).")


# ---------------------------------------------------------------------------- optimisation
#: Bounds (low, high) of one link length, m.
LengthBounds = Annotated[list[Length], Field(min_length=2, max_length=2)]


class DesignOptimizeRequest(_Request):
    """Body of ``POST /v1/design/optimize``: maximise an objective over the link lengths
    (:func:`planner.analysis.optimize.optimize_design`), with a bounded budget."""

    objective: Literal["volume", "well_conditioned_volume", "gci"] = "volume"
    reach: Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=MAX_LENGTH)] | None = Field(
        0.8, description="Fixed L1 + L2, m; null: L0, L1, L2 vary inside their bounds."
    )
    L0_bounds: LengthBounds | None = Field(None, description="[low, high] of L0, m.")
    L1_bounds: LengthBounds | None = Field(None, description="[low, high] of L1, m.")
    L2_bounds: LengthBounds | None = Field(
        None, description="[low, high] of L2, m (L1_bounds and L2_bounds required without reach)."
    )
    design: DesignModel = Field(
        default_factory=DesignModel,
        description="Template of the candidates: their link_radius and joint limits.",
    )
    kappa_max: float = Field(10.0, ge=1.0, le=1e12, allow_inf_nan=False)
    n_samples: int = Field(
        2048, ge=64, le=8192, description="Quasi-random points per sampled evaluation."
    )
    maxiter: int = Field(10, ge=1, le=30, description="Generations of differential evolution.")
    seed: int = Field(0, ge=0, le=2**32 - 1)

    @field_validator("L0_bounds", "L1_bounds", "L2_bounds")
    @classmethod
    def _ordered(cls, value: list[float] | None) -> list[float] | None:
        if value is not None and not value[0] <= value[1]:
            raise ValueError(f"bounds must be [low, high] with low <= high, got {value}")
        return value


class DesignOptimizeResponse(_Response):
    """Answer of ``POST /v1/design/optimize``."""

    design: DesignModel = Field(description="The best design found.")
    objective: str
    value: float = Field(description="Objective at the design (m^3 for volumes).")
    volume: float = Field(description="Closed-form workspace volume of the design, m^3.")
    success: bool = Field(description="The optimiser reported convergence.")
    message: str
    evaluations: int


def sampled_value(estimate: Any) -> SampledValue:
    """The wire form of an :class:`planner.analysis.workspace.Estimate` (None: zero, no
    samples)."""
    if estimate is None:
        return SampledValue(value=0.0, standard_error=0.0, n_samples=0)
    return SampledValue(
        value=estimate.value, standard_error=estimate.standard_error, n_samples=estimate.n_samples
    )
