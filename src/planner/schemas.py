"""Pydantic models of the HTTP wire vocabulary (``CONVENTIONS.md``), shared by the service
and the client: the one definition of every field name on /v1."""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

from planner.design import MAX_JOINT_TRAVEL, MAX_LENGTH, MIN_LENGTH, Design


class _Wire(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Health(_Wire):
    """Answer of ``GET /v1/health``."""

    status: Literal["ok"]


class VersionInfo(_Wire):
    """Answer of ``GET /v1/version``."""

    version: str
    libraries: dict[str, str]


# ----------------------------------------------------------------------------- design
_FULL_TURN_MIN = (-math.pi, -math.pi, -math.pi)
_FULL_TURN_MAX = (math.pi, math.pi, math.pi)

#: A link length or L0 on the wire, m: finite, at most MAX_LENGTH.
_Length = Annotated[float, Field(allow_inf_nan=False, le=MAX_LENGTH)]
#: A joint limit on the wire, rad: finite, within +-MAX_JOINT_TRAVEL.
_JointLimit = Annotated[
    float, Field(allow_inf_nan=False, ge=-MAX_JOINT_TRAVEL, le=MAX_JOINT_TRAVEL)
]


class DesignModel(_Wire):
    """The ``design`` object of the wire vocabulary (m, rad); ``to_design()`` builds the
    library's :class:`planner.Design`. Every rule of ``Design`` is checked here so that a bad
    value is a 422 naming its field."""

    L0: _Length = Field(ge=0.0, description="Distance |AB| between the actuated pivots, m.")
    L1: _Length = Field(ge=MIN_LENGTH, description="Proximal links |AC| = |BD|, m.")
    L2: _Length = Field(ge=MIN_LENGTH, description="Distal links |CP| = |DP|, m.")
    link_radius: _Length = Field(0.02, ge=0.0, description="Capsule radius of the links, m.")
    joint_min: tuple[_JointLimit, _JointLimit, _JointLimit] = Field(
        _FULL_TURN_MIN, description="Literal lower limits of (theta1, theta2, theta3), rad."
    )
    joint_max: tuple[_JointLimit, _JointLimit, _JointLimit] = Field(
        _FULL_TURN_MAX, description="Literal upper limits of (theta1, theta2, theta3), rad."
    )

    @field_validator("joint_max")
    @classmethod
    def _above_min(cls, value: tuple[float, float, float], info: ValidationInfo):
        lo = info.data.get("joint_min")
        if lo is not None:
            for i in range(3):
                if not lo[i] < value[i]:
                    raise ValueError(
                        f"joint_max[{i}] must be above joint_min[{i}], got {value[i]} <= {lo[i]}"
                    )
        return value

    @classmethod
    def from_design(cls, design: Design) -> DesignModel:
        """The wire form of a library design."""
        return cls(
            L0=design.L0,
            L1=design.L1,
            L2=design.L2,
            link_radius=design.link_radius,
            joint_min=design.joint_min,
            joint_max=design.joint_max,
        )

    def to_design(self) -> Design:
        """The library's :class:`planner.Design` of these numbers."""
        return Design(
            L0=self.L0,
            L1=self.L1,
            L2=self.L2,
            link_radius=self.link_radius,
            joint_min=self.joint_min,
            joint_max=self.joint_max,
        )


def _default_design() -> DesignModel:
    return DesignModel.from_design(Design.default())


class DesignCheckRequest(_Wire):
    """Body of ``POST /v1/design/check``."""

    design: DesignModel = Field(default_factory=_default_design)
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


class SampledValue(_Wire):
    """A sampled quantity and its standard error."""

    value: float
    standard_error: float
    n_samples: int


class DesignCheckResponse(_Wire):
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
