"""``POST /v1/calibrate`` (kinematic calibration), ``POST /v1/calibrate/poses`` (postures
to measure) and ``POST /v1/identify`` (dynamic identification): their vocabulary and the
conversions wire <-> core (``docs/calibration.md``)."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import Field, ValidationInfo, field_validator

from planner.wire.common import (
    GRAVITY_FIELD,
    Angles3,
    AssemblyModeLabel,
    DesignModel,
    Gravity,
    InertiaModel,
    Integer,
    LinkInertiaModel,
    Point3,
    Vec3,
    WorkingModeLabel,
    _DesignField,
    _Request,
    _Response,
    design_to_core,
    inertia_to_core,
    located,
)

if TYPE_CHECKING:
    from planner.calibration import CalibrationResult, Measurements, SuggestedPoses
    from planner.design import Design
    from planner.dynamics import Inertia
    from planner.dynamics.identify import IdentificationResult

__all__ = [
    "MAX_CALIBRATION_MEASUREMENTS",
    "MAX_IDENTIFY_SAMPLES",
    "CalibrateRequest",
    "CalibrateResponse",
    "CalibrationPosesRequest",
    "CalibrationPosesResponse",
    "FrameModel",
    "FrictionModel",
    "IdentifyRequest",
    "IdentifyResponse",
    "MeasurementModel",
    "MeasurementPosture",
    "ProvenanceModel",
    "calibrate_inputs",
    "calibrate_response",
    "identify_inputs",
    "identify_response",
    "inertia_model",
    "poses_response",
]

#: Most measurements of one ``POST /v1/calibrate``.
MAX_CALIBRATION_MEASUREMENTS = 10_000
#: Most samples of one ``POST /v1/identify``.
MAX_IDENTIFY_SAMPLES = 100_000

IdentifyItem = Literal["lengths", "leg_lengths", "offsets", "frame"]


def _default_identify() -> list[IdentifyItem]:
    """``identify``'s default: the lengths, the offsets and the frame."""
    return ["lengths", "offsets", "frame"]


_RotationComponent = Annotated[float, Field(allow_inf_nan=False, ge=-7.0, le=7.0)]
_RotationVector = Annotated[list[_RotationComponent], Field(min_length=3, max_length=3)]


class MeasurementModel(_Request):
    """One measurement: the commanded actuated joints and the measured P."""

    q: Angles3 = Field(description="Commanded (theta1, theta2, theta3), rad.")
    p: Point3 = Field(description="Measured P in the tracker's frame, m.")
    working_mode: WorkingModeLabel | None = Field(
        None, description="The measured working mode, when known (decides the branch)."
    )
    assembly_mode: AssemblyModeLabel | None = Field(
        None, description="The measured assembly mode, when known (decides the branch)."
    )


class FrameModel(_Request):
    """The tracker's frame relative to the base: ``p_base = R(rotation) p_tracker +
    position``."""

    position: Point3 = Field(description="m.")
    rotation: _RotationVector = Field(description="A rotation vector, rad (|r| <= 7).")


class CalibrateRequest(_Request):
    """Body of ``POST /v1/calibrate``."""

    design: DesignModel = _DesignField
    measurements: Annotated[
        list[MeasurementModel], Field(min_length=1, max_length=MAX_CALIBRATION_MEASUREMENTS)
    ]
    identify: Annotated[list[IdentifyItem], Field(min_length=1, max_length=4)] = Field(
        default_factory=_default_identify,
        description="What to identify: 'lengths' (L0, L1, L2), 'leg_lengths' (L0 and each "
        "leg's two lengths apart), 'offsets' (actuator zeros), 'frame' (the tracker's).",
    )
    frame: FrameModel | None = Field(
        None,
        description="The tracker's frame: a first guess, or the known frame when 'frame' is "
        "not identified (default: the identity).",
    )

    @field_validator("identify")
    @classmethod
    def _unique(cls, value: list[str]) -> list[str]:
        if len(set(value)) != len(value):
            raise ValueError(f"identify must not repeat an item, got {value}")
        return value


class ProvenanceModel(_Response):
    """Where an identified model comes from."""

    measurements: int
    residual_rms_m: float
    residual_max_m: float
    identify: list[str]
    date: str = Field(description="UTC, ISO 8601.")


class CalibrateResponse(_Response):
    """Answer of ``POST /v1/calibrate`` (``docs/calibration.md``)."""

    design: DesignModel = Field(description="The identified design (legs apart: their means).")
    leg_lengths: dict[str, float] | None = Field(
        None, description="With 'leg_lengths': L1_A = |AC|, L1_B = |BD|, L2_A = |CP|, L2_B = |DP|."
    )
    offsets: Vec3 = Field(description="Added to the commanded q before the kinematics, rad.")
    frame: FrameModel
    residual_rms_m: float
    residual_max_m: float
    residuals_m: list[float] = Field(description="Each measurement's distance from the model.")
    assembly_modes: list[AssemblyModeLabel] = Field(description="The branch used for each.")
    std: dict[str, float] = Field(description="Standard deviation of each identified parameter.")
    condition_number: float = Field(description="Of the column-scaled identification Jacobian.")
    unidentified: list[str] = Field(description="Rank-deficient parameters, held at nominal.")
    provenance: ProvenanceModel


class CalibrationPosesRequest(_Request):
    """Body of ``POST /v1/calibrate/poses``: postures worth measuring."""

    design: DesignModel = _DesignField
    n: Integer = Field(30, ge=1, le=500, description="How many postures.")
    identify: Annotated[list[IdentifyItem], Field(min_length=1, max_length=4)] = Field(
        default_factory=_default_identify
    )
    seed: Integer = Field(0, ge=0, le=2**32 - 1)


class MeasurementPosture(_Response):
    """One posture to measure."""

    q: Vec3
    working_mode: str
    assembly_mode: str


class CalibrationPosesResponse(_Response):
    """The postures, each with its modes (measure them in this assembly mode)."""

    postures: list[MeasurementPosture]


_Number = Annotated[float, Field(allow_inf_nan=False, ge=-1e6, le=1e6)]
#: One sample's three rates or torques (rad/s, rad/s^2 or N m).
_Row = Annotated[list[_Number], Field(min_length=3, max_length=3)]


class IdentifyRequest(_Request):
    """Body of ``POST /v1/identify``: measured motions and torques (N x 3 each)."""

    design: DesignModel = _DesignField
    gravity: Gravity = GRAVITY_FIELD
    assembly_mode: AssemblyModeLabel = "+"
    q: Annotated[list[Angles3], Field(min_length=1, max_length=MAX_IDENTIFY_SAMPLES)]
    qd: Annotated[list[_Row], Field(max_length=MAX_IDENTIFY_SAMPLES)]
    qdd: Annotated[list[_Row], Field(max_length=MAX_IDENTIFY_SAMPLES)]
    tau: Annotated[list[_Row], Field(max_length=MAX_IDENTIFY_SAMPLES)]
    friction: bool = Field(False, description="Also identify viscous and Coulomb friction.")

    @field_validator("qd", "qdd", "tau")
    @classmethod
    def _one_row_per_sample(cls, value: list, info: ValidationInfo) -> list:
        q = info.data.get("q")
        if q is not None and len(value) != len(q):
            raise ValueError(
                f"{info.field_name} must have one row per sample of q: {len(q)} rows, got "
                f"{len(value)}"
            )
        return value


class FrictionModel(_Response):
    """Per actuator: ``tau_f = viscous qd + coulomb sign(qd)``."""

    viscous: Vec3
    coulomb: Vec3


class IdentifyResponse(_Response):
    """Answer of ``POST /v1/identify``."""

    inertia: InertiaModel = Field(description="A design.inertia the other endpoints accept.")
    friction: FrictionModel | None = None
    residual_rms: float = Field(description="N m, of tau against the identified model.")
    unidentified: list[str]
    base_parameters: dict[str, float]
    condition_number: float
    notes: list[str]


# ---------------------------------------------------------------------------- conversions
def calibrate_inputs(
    request: CalibrateRequest,
) -> tuple[Design, Measurements, tuple[np.ndarray, np.ndarray] | None]:
    """The library's design, measurements and frame guess of a request."""
    from planner.calibration import Measurements

    design = design_to_core(request.design)
    ms = request.measurements
    with located("body"):
        m = Measurements(
            np.array([x.q for x in ms], dtype=float),
            np.array([x.p for x in ms], dtype=float),
            working_mode=[x.working_mode for x in ms],
            assembly_mode=[x.assembly_mode for x in ms],
        )
    frame = None
    if request.frame is not None:
        frame = (np.asarray(request.frame.position), np.asarray(request.frame.rotation))
    return design, m, frame


def calibrate_response(result: CalibrationResult, identify: list[str]) -> CalibrateResponse:
    """The wire answer of a :class:`planner.calibration.CalibrationResult`."""
    n = len(result.residuals)
    return CalibrateResponse(
        design=DesignModel.from_design(result.design),
        leg_lengths=result.leg_lengths,
        offsets=result.offsets.tolist(),
        frame=FrameModel(
            position=result.frame_position.tolist(), rotation=result.frame_rotation.tolist()
        ),
        residual_rms_m=result.residual_rms,
        residual_max_m=result.residual_max,
        residuals_m=result.residuals.tolist(),
        assembly_modes=result.assembly_modes,
        std=result.std,
        condition_number=result.condition_number,
        unidentified=result.unidentified,
        provenance=ProvenanceModel(
            measurements=n,
            residual_rms_m=result.residual_rms,
            residual_max_m=result.residual_max,
            identify=list(identify),
            date=datetime.now(UTC).isoformat(timespec="seconds"),
        ),
    )


def poses_response(poses: SuggestedPoses) -> CalibrationPosesResponse:
    """The wire answer of :func:`planner.calibration.suggest_poses`."""
    return CalibrationPosesResponse(
        postures=[
            MeasurementPosture(q=q.tolist(), working_mode=wm, assembly_mode=am)
            for q, wm, am in zip(poses.q, poses.working_mode, poses.assembly_mode, strict=True)
        ]
    )


def identify_inputs(request: IdentifyRequest) -> tuple[Design, Inertia | None]:
    """The library's design and prior inertia (None: the defaults) of a request."""
    return design_to_core(request.design), inertia_to_core(request.design)


def inertia_model(inertia: Inertia) -> InertiaModel:
    """The wire form (``design.inertia``) of a library inertia."""
    from planner.wire.common import BaseInertiaModel, PayloadModel

    def link(part) -> LinkInertiaModel:
        return LinkInertiaModel(
            mass=part.mass, com=part.com, I_perp=part.I_perp, I_axial=part.I_axial
        )

    return InertiaModel(
        proximal=link(inertia.proximal),
        distal=link(inertia.distal),
        payload=PayloadModel(mass=inertia.payload_mass),
        base=BaseInertiaModel(inertia=inertia.base_inertia),
        rotor=list(inertia.rotor),
    )


def identify_response(result: IdentificationResult) -> IdentifyResponse:
    """The wire answer of :func:`planner.dynamics.identify.identify_inertia`."""
    friction = None
    if result.friction is not None:
        friction = FrictionModel(
            viscous=result.friction[0].tolist(), coulomb=result.friction[1].tolist()
        )
    return IdentifyResponse(
        inertia=inertia_model(result.inertia),
        friction=friction,
        residual_rms=result.residual_rms,
        unidentified=result.unidentified,
        base_parameters=result.base_parameters,
        condition_number=result.condition_number,
        notes=result.notes,
    )
