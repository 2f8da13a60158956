"""``GET /v1/designs``, ``POST /v1/design/check`` and ``/v1/design/optimize``."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import (
    ConfigDict,
    Field,
    field_validator,
)

from planner.design import MAX_LENGTH
from planner.wire.common import (
    AssemblyModeLabel,
    DesignModel,
    Integer,
    Length,
    MarginsModel,
    WorkingModeLabel,
    _DesignField,
    _Request,
    _Response,
)
from planner.wire.plan import TransitKind

if TYPE_CHECKING:
    from planner.analysis.regions import RegionMap
    from planner.analysis.workspace import Estimate

__all__ = [
    "MAX_REGION_RESOLUTION",
    "MIN_REGION_RESOLUTION",
    "DesignCheckRequest",
    "DesignCheckResponse",
    "DesignOptimizeRequest",
    "DesignOptimizeResponse",
    "DesignPreset",
    "DesignsResponse",
    "LengthBounds",
    "RegionModel",
    "RegionTransitModel",
    "RegionsRequest",
    "RegionsResponse",
    "SampledValue",
    "regions_model",
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
    seed: Integer = Field(0, ge=0, le=2**32 - 1, description="Seed of the quasi-random sampling.")


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
    n_samples: Integer = Field(
        2048, ge=64, le=8192, description="Quasi-random points per sampled evaluation."
    )
    maxiter: Integer = Field(10, ge=1, le=30, description="Generations of differential evolution.")
    seed: Integer = Field(0, ge=0, le=2**32 - 1)

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


def sampled_value(estimate: Estimate | None) -> SampledValue:
    """The wire form of an :class:`planner.analysis.workspace.Estimate` (None: zero, no
    samples)."""
    if estimate is None:
        return SampledValue(value=0.0, standard_error=0.0, n_samples=0)
    return SampledValue(
        value=estimate.value, standard_error=estimate.standard_error, n_samples=estimate.n_samples
    )


# ---------------------------------------------------------------------------- region maps
#: Cells per axis of ``POST /v1/design/regions``: the least (coarser maps cut thin regions)
#: and the most (a map of n x n cells holds about 250 n^2 bytes, built in time ~ n^2: 512 is
#: 4 times the default's work, about 62 MB and 0.1-0.3 s on one core, and fits the cache
#: of each worker; 1024 would hold 250 MB per map and 0.5 GB at its peak).
MIN_REGION_RESOLUTION, MAX_REGION_RESOLUTION = 16, 512


class RegionsRequest(_Request):
    """Body of ``POST /v1/design/regions``: the region map of a design under its margins
    (:func:`planner.analysis.regions.region_map`; no obstacles, so ``margins.clearance``
    plays no part)."""

    design: DesignModel = _DesignField
    margins: MarginsModel = Field(default_factory=MarginsModel)
    resolution: Integer = Field(
        256,
        ge=MIN_REGION_RESOLUTION,
        le=MAX_REGION_RESOLUTION,
        description="Cells per axis of the (theta2, theta3) grid over the joint limits.",
    )
    cell_regions: bool = Field(
        False,
        description="Also answer ``cell_regions``: the region of each cell's centre posture "
        "(what the viewer draws).",
    )


class RegionModel(_Response):
    """One region: a connected component of the cells of one working mode that are not
    surely invalid (8-connected cells of the grid)."""

    id: int = Field(ge=0, description="Index in ``regions``, the name transits use.")
    working_mode: WorkingModeLabel
    assembly_mode: AssemblyModeLabel
    cells: int = Field(ge=1, description="Cells of the region (surely valid + undecided).")
    valid_cells: int = Field(ge=0, description="Its surely valid cells.")
    component: int = Field(
        ge=0, description="Component of the union graph: regions joined by transits."
    )


class RegionTransitModel(_Response):
    """Two regions of one assembly mode whose working modes differ by one sign, touching
    across a serial surface of kind ``kind`` (one entry per kind)."""

    model_config = ConfigDict(
        extra="ignore", serialize_by_alias=True, validate_by_alias=True, validate_by_name=True
    )

    from_: int = Field(alias="from", ge=0, description="Region id (its flipped sign '+').")
    to: int = Field(ge=0, description="Region id (its flipped sign '-').")
    kind: TransitKind
    flipped: Literal["axis", "A", "B"]
    cells: int = Field(
        ge=0, description="Cells of the transit set where the flipped measure may vanish."
    )


class RegionsResponse(_Response):
    """Answer of ``POST /v1/design/regions``."""

    design: DesignModel
    margins: MarginsModel = Field(description="The margins used (kappa_max, serial_min).")
    resolution: int
    regions: list[RegionModel]
    transits: list[RegionTransitModel]
    components: int = Field(ge=0, description="Components of the union graph.")
    computation_time_s: float = Field(description="Time to build the map (0 when cached), s.")
    cell_regions: list[list[list[int]]] | None = Field(
        None,
        description="With ``cell_regions: true``: shape (2, n, n), per assembly mode ('+', "
        "'-'), rows theta3, columns theta2 (cell centres ``joint_min + (k + 0.5) (joint_max - "
        "joint_min) / n``), the id of the region holding the posture at the cell's centre, "
        "-1 where that posture is in none (surely invalid, or not assembled).",
    )


def _cell_regions(rmap: RegionMap) -> np.ndarray:
    """Shape (2, n, n), int: the region id of each cell centre's posture per assembly mode
    (its working mode ``rmap.centre_mode``, its label in that mode's layer), -1 where none."""
    mode = np.asarray(rmap.centre_mode, dtype=np.int64)  # (2, n, n), -1: no mode
    a = np.arange(2)[:, None, None]
    k3 = np.arange(rmap.n)[None, :, None]
    k2 = np.arange(rmap.n)[None, None, :]
    safe = np.maximum(mode, 0)
    label = np.asarray(rmap.labels)[a, safe, k3, k2]
    ids = np.asarray(rmap.region_index)[a, safe, label]
    return np.where((mode >= 0) & (label > 0), ids, -1)


def regions_model(
    rmap: RegionMap, computation_time_s: float = 0.0, *, with_cells: bool = False
) -> RegionsResponse:
    """The wire form of a :class:`planner.analysis.regions.RegionMap`: its regions, and one
    transit per pair of regions and kind of serial surface between them."""
    regions = [
        RegionModel(
            id=r.id,
            working_mode=r.working_mode,
            assembly_mode=r.assembly_mode,
            cells=r.cells,
            valid_cells=r.valid_cells,
            component=r.component,
        )
        for r in rmap.regions
    ]
    transits = [
        RegionTransitModel(from_=t.a, to=t.b, kind=kind, flipped=t.flipped, cells=cells)
        for t in rmap.transits
        for kind, cells in zip(t.kinds, t.cells, strict=True)
    ]
    m = rmap.margins
    return RegionsResponse(
        design=DesignModel.from_design(rmap.design),
        margins=MarginsModel(kappa_max=m.kappa_max, serial_min=m.serial_min),
        resolution=rmap.n,
        regions=regions,
        transits=transits,
        components=len({r.component for r in rmap.regions}),
        computation_time_s=computation_time_s,
        cell_regions=_cell_regions(rmap).tolist() if with_cells else None,
    )
