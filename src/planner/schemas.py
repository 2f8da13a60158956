"""Pydantic models of the HTTP wire vocabulary (``docs/conventions.md``), shared by the service
and the client: the one definition of every field name on /v1.

Requests forbid unknown fields (a typo is a 422 naming the field, not a silently ignored
option) and check every number for finiteness and a sane range, so the library never sees
NaN, an infinity or an absurd size. Responses ignore fields they do not know, so an older
client keeps working against a newer server.

Units: metres, radians and seconds everywhere. An infinite quantity (kappa at a singularity)
is written ``null`` on the wire: JSON has no infinity.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    ValidationInfo,
    field_validator,
    model_validator,
)

from planner.design import MAX_JOINT_TRAVEL, MAX_LENGTH, MIN_LENGTH, Design
from planner.exceptions import DesignError

__all__ = [
    "MAX_BATCH_REQUESTS",
    "MAX_COORDINATE",
    "MAX_OBSTACLES",
    "MAX_SECTION_RESOLUTION",
    "MAX_TIMING_WAYPOINTS",
    "AnalyzeRequest",
    "AnalyzeResponse",
    "BoxObstacle",
    "CapsuleObstacle",
    "CartesianTarget",
    "DesignCheckRequest",
    "DesignCheckResponse",
    "DesignModel",
    "DesignOptimizeRequest",
    "DesignOptimizeResponse",
    "DesignPreset",
    "DesignsResponse",
    "Diagnostics",
    "ErrorItem",
    "ErrorResponse",
    "FKRequest",
    "FKResponse",
    "FigureQuery",
    "Goal",
    "Health",
    "IKRequest",
    "IKResponse",
    "JointPosture",
    "Limits",
    "Margins",
    "Obstacle",
    "PathModel",
    "PlanBatchRequest",
    "PlanBatchResponse",
    "PlanRequest",
    "PlanResponse",
    "PlanStatus",
    "PlannerOptions",
    "PostureModel",
    "Readiness",
    "SampledValue",
    "SectionGrid",
    "SectionOptions",
    "SegmentModel",
    "SerialMargins",
    "SphereObstacle",
    "TimingOptions",
    "TimingRequest",
    "TimingResponse",
    "TimingStatus",
    "TrajectoryModel",
    "TransitModel",
    "VersionInfo",
    "WorkspaceRequest",
    "WorkspaceResponse",
]

#: Largest |coordinate| of a point on the wire, m: a sanity bound far above any workcell.
MAX_COORDINATE = 1e4
#: Hard cap on obstacles in one request (the service's own, lower cap is a setting).
MAX_OBSTACLES = 10_000
#: Hard cap on plan requests in one batch (the service's own, lower cap is a setting).
MAX_BATCH_REQUESTS = 10_000
#: Largest sample count of a returned trajectory or path accepted by a client.
_MAX_SAMPLES = 10_000_000

_DEFAULT = Design.default()

WorkingModeLabel = Literal["+++", "++-", "+-+", "+--", "-++", "-+-", "--+", "---"]
WorkingModeOrAny = Literal["+++", "++-", "+-+", "+--", "-++", "-+-", "--+", "---", "any"]
AssemblyModeLabel = Literal["+", "-"]

# ---------------------------------------------------------------------------- number types
Finite = Annotated[float, Field(allow_inf_nan=False)]
Length = Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=MAX_LENGTH)]
LinkLength = Annotated[float, Field(allow_inf_nan=False, ge=MIN_LENGTH, le=MAX_LENGTH)]
Coordinate = Annotated[float, Field(allow_inf_nan=False, ge=-MAX_COORDINATE, le=MAX_COORDINATE)]
Angle = Annotated[float, Field(allow_inf_nan=False, ge=-MAX_JOINT_TRAVEL, le=MAX_JOINT_TRAVEL)]
PositiveSize = Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=MAX_COORDINATE)]
#: Three angles, rad (a joint vector).
Angles3 = Annotated[list[Angle], Field(min_length=3, max_length=3)]
#: A point, m.
Point3 = Annotated[list[Coordinate], Field(min_length=3, max_length=3)]
#: Three positive rates (one per joint).
Rates3 = Annotated[
    list[Annotated[float, Field(allow_inf_nan=False, ge=1e-6, le=1e6)]],  # = timing MIN/MAX_RATE
    Field(min_length=3, max_length=3),
]
#: A 3-vector of any finite numbers (responses).
Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]
Matrix3 = Annotated[list[Vec3], Field(min_length=3, max_length=3)]


class _Request(BaseModel):
    """Base of request models: unknown fields are errors, and types are strict (``true`` is
    not a number, ``"1.5"`` is not a number; an integer is a number): a client's mistake is
    named, not coerced."""

    model_config = ConfigDict(extra="forbid", strict=True)


class _Response(BaseModel):
    """Base of response models: unknown fields are ignored (forward compatibility)."""

    model_config = ConfigDict(extra="ignore")


# ---------------------------------------------------------------------------- design
class DesignModel(_Request):
    """A design on the wire; every field defaults to the default robot
    (:meth:`planner.Design.default`: L0 = 0.5, L1 = 0.2, L2 = 0.6 m, joints within +-pi)."""

    L0: Length = Field(_DEFAULT.L0, description="|AB|, m, >= 0.")
    L1: LinkLength = Field(_DEFAULT.L1, description="|AC| = |BD|, m, > 0.")
    L2: LinkLength = Field(_DEFAULT.L2, description="|CP| = |DP|, m, > 0.")
    link_radius: Length = Field(
        _DEFAULT.link_radius, description="Radius of the link capsules, m, >= 0."
    )
    joint_min: Angles3 = Field(
        default_factory=lambda: list(_DEFAULT.joint_min),
        description="Lower limits of (theta1, theta2, theta3), rad, literal (never wrapped).",
    )
    joint_max: Angles3 = Field(
        default_factory=lambda: list(_DEFAULT.joint_max),
        description="Upper limits of (theta1, theta2, theta3), rad, literal (never wrapped).",
    )

    @field_validator("joint_max")
    @classmethod
    def _above_min(cls, value: list[float], info: ValidationInfo) -> list[float]:
        lo = info.data.get("joint_min")
        for i in range(3 if lo is not None else 0):
            if not lo[i] < value[i]:
                raise ValueError(
                    f"joint_max[{i}] must be above joint_min[{i}], got {value[i]} <= {lo[i]}"
                )
        return value

    @model_validator(mode="after")
    def _check_design(self) -> DesignModel:
        try:
            self.to_design()
        except DesignError as exc:  # any remaining rule of Design
            raise ValueError(str(exc)) from exc
        return self

    def to_design(self) -> Design:
        """The library's :class:`planner.Design`."""
        return Design(
            L0=self.L0,
            L1=self.L1,
            L2=self.L2,
            link_radius=self.link_radius,
            joint_min=tuple(self.joint_min),
            joint_max=tuple(self.joint_max),
        )

    @classmethod
    def from_design(cls, design: Design) -> DesignModel:
        """The wire form of a library design."""
        return cls(
            L0=design.L0,
            L1=design.L1,
            L2=design.L2,
            link_radius=design.link_radius,
            joint_min=list(design.joint_min),
            joint_max=list(design.joint_max),
        )


_DesignField = Field(default_factory=DesignModel, description="The robot; default robot if absent.")


class DesignPreset(_Response):
    """One named design of ``GET /v1/designs``."""

    name: str
    description: str
    design: DesignModel


class DesignsResponse(_Response):
    """Answer of ``GET /v1/designs``: the presets, ``default`` first."""

    presets: list[DesignPreset]


# ---------------------------------------------------------------------------- postures, targets
class JointPosture(_Request):
    """A joint posture: actuated joints and the assembly mode (sign of sin(theta5 - theta4))."""

    q: Angles3 = Field(description="(theta1, theta2, theta3), rad.")
    assembly_mode: AssemblyModeLabel = Field(description="'+' or '-'.")


class CartesianTarget(_Request):
    """A Cartesian target for P, with the working mode to reach it in (or ``"any"``)."""

    p: Point3 = Field(description="(x, y, z) of P, m.")
    working_mode: WorkingModeOrAny = Field(
        "any", description="(s_axis, s_A, s_B) as '+-+'-style text, or 'any'."
    )


def _goal_kind(value: Any) -> str | None:
    if isinstance(value, dict):
        if "q" in value:
            return "q"
        return "p" if "p" in value else None
    if isinstance(value, CartesianTarget):
        return "p"
    if isinstance(value, JointPosture):
        return "q"
    return None


#: A goal: a joint posture (has ``q``) or a Cartesian target (has ``p``). Validation errors
#: name the branch taken: ``goal.q.<field>`` or ``goal.p.<field>``.
Goal = Annotated[
    Annotated[JointPosture, Tag("q")] | Annotated[CartesianTarget, Tag("p")],
    Discriminator(
        _goal_kind,
        custom_error_type="goal_kind",
        custom_error_message="goal must be a joint posture {q, assembly_mode} "
        "or a Cartesian target {p, working_mode}",
    ),
]


# ---------------------------------------------------------------------------- obstacles
class SphereObstacle(_Request):
    type: Literal["sphere"] = "sphere"
    center: Point3 = Field(description="m.")
    radius: PositiveSize = Field(description="m, > 0.")


class BoxObstacle(_Request):
    """An oriented box: ``size`` is the full edge lengths along its own axes, turned by the
    unit quaternion ``[w, x, y, z]`` (normalised here; a zero quaternion is an error)."""

    type: Literal["box"] = "box"
    center: Point3 = Field(description="m.")
    size: Annotated[list[PositiveSize], Field(min_length=3, max_length=3)] = Field(
        description="Full edge lengths (sx, sy, sz), m, > 0."
    )
    quaternion: Annotated[list[Finite], Field(min_length=4, max_length=4)] = Field(
        default_factory=lambda: [1.0, 0.0, 0.0, 0.0], description="[w, x, y, z]."
    )

    @field_validator("quaternion")
    @classmethod
    def _unit(cls, value: list[float]) -> list[float]:
        norm = math.sqrt(sum(v * v for v in value))
        if not 1e-9 < norm < 1e9:
            raise ValueError(f"quaternion must have a norm in (1e-9, 1e9), got {norm:.3g}")
        return [v / norm for v in value]


class CapsuleObstacle(_Request):
    """The set of points within ``radius`` of the segment ``a``-``b``."""

    type: Literal["capsule"] = "capsule"
    a: Point3 = Field(description="m.")
    b: Point3 = Field(description="m.")
    radius: PositiveSize = Field(description="m, > 0.")


Obstacle = Annotated[SphereObstacle | BoxObstacle | CapsuleObstacle, Field(discriminator="type")]


# ---------------------------------------------------------------------------- plan options
class Margins(_Request):
    """Validity margins of a plan; an absent field takes the planner's documented default."""

    kappa_max: Annotated[float, Field(allow_inf_nan=False, gt=1.0, le=1e12)] | None = Field(
        None, description="Upper bound on kappa(A), > 1."
    )
    serial_min: Annotated[float, Field(allow_inf_nan=False, gt=0.0, lt=1.0)] | None = Field(
        None,
        description="Lower bound on |sin(t4 - t2)|, |sin(t5 - t3)| and |w| / (L1 + L2), in "
        "(0, 1): a zero margin would let a motion touch a serial singularity.",
    )
    clearance: Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=MAX_LENGTH)] | None = Field(
        None, description="Least distance from every link capsule to every obstacle, m."
    )


class PlannerOptions(_Request):
    """Search options of a plan."""

    name: str = Field(
        "rrtconnect",
        pattern=r"^[A-Za-z][A-Za-z0-9_]{0,31}$",
        description="Planner (case-insensitive): rrtconnect (default), rrt, rrtstar, prmstar, "
        "bitstar, aorrtc, lbkpiece.",
    )
    time_budget_s: Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=600.0)] = Field(
        1.0, description="Search budget, s (at most the service's request budget)."
    )
    seed: Annotated[int, Field(ge=1, le=2**31 - 1)] | None = Field(
        None,
        description="Seed of the planner's random numbers, >= 1 (reproducible results); "
        "absent: the planner's default seed.",
    )
    simplify: bool = Field(True, description="Shorten and smooth the path (OMPL simplifier).")
    stop_at_transits: bool = Field(
        False,
        description="Come to rest at each working-mode transit (the timed trajectory stops "
        "on the serial-singularity posture); default: pass it at speed.",
    )

    @field_validator("name")
    @classmethod
    def _lower(cls, value: str) -> str:
        return value.lower()


class TimingOptions(_Request):
    """How the planned path is turned into a trajectory."""

    method: Literal["toppra", "ruckig", "none"] = "toppra"
    sample_rate_hz: Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=10_000.0)] = 100.0
    stop_at_transits: bool = Field(False, description="Come to rest at each mode transit.")
    max_deviation: Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=1.0)] | None = Field(
        None,
        description="Largest joint-space distance from a waypoint to its corner blend, rad "
        "(0: stop at every waypoint); absent: the timing default.",
    )


class Limits(_Request):
    """Per-joint limits (rad/s, rad/s^2, rad/s^3); an absent field takes the timing default
    (:meth:`planner.timing.JointLimits.default`: 2 rad/s, 8 rad/s^2, 200 rad/s^3)."""

    velocity: Rates3 | None = None
    acceleration: Rates3 | None = None
    jerk: Rates3 | None = None
    cartesian_speed: Annotated[float, Field(allow_inf_nan=False, ge=1e-6, le=1e3)] | None = Field(
        None, description="Bound on the speed of P, m/s (optional)."
    )


# ---------------------------------------------------------------------------- plan
class PlanRequest(_Request):
    """Body of ``POST /v1/plan``. Only ``start`` and ``goal`` are required."""

    design: DesignModel = _DesignField
    start: JointPosture
    goal: Goal
    obstacles: list[Obstacle] = Field(default_factory=list, max_length=MAX_OBSTACLES)
    margins: Margins = Field(default_factory=Margins)
    planner: PlannerOptions = Field(default_factory=PlannerOptions)
    timing: TimingOptions = Field(default_factory=TimingOptions)
    limits: Limits = Field(default_factory=Limits)


PlanStatus = Literal["solved", "no_path", "unreachable", "invalid_start", "invalid_goal", "timeout"]
TransitKind = Literal[
    "P_on_axis", "leg_A_stretched", "leg_A_folded", "leg_B_stretched", "leg_B_folded"
]


class SegmentModel(_Response):
    """A run of waypoints in one working and assembly mode; indices inclusive."""

    working_mode: WorkingModeLabel
    assembly_mode: AssemblyModeLabel
    start_index: int = Field(ge=0)
    end_index: int = Field(ge=0)


class TransitModel(_Response):
    """A serial-singularity posture where exactly one working-mode sign flips."""

    index: int = Field(ge=0)
    q: Vec3
    kind: TransitKind
    flipped: Literal["axis", "A", "B"]


class PathModel(_Response):
    """The planned joint path: waypoints (N x 3, rad), its segments and transits."""

    waypoints: Annotated[list[Vec3], Field(max_length=_MAX_SAMPLES)]
    segments: list[SegmentModel] = Field(default_factory=list)
    transits: list[TransitModel] = Field(default_factory=list)


class TrajectoryModel(_Response):
    """The timed trajectory: M samples of t (s), q (rad), qd (rad/s), qdd (rad/s^2); for
    ruckig also the jerk (rad/s^3); P (m) and its speed (m/s); the largest deviation from the
    planned path in joint space (rad) and at P (m)."""

    duration: float
    t: Annotated[list[float], Field(max_length=_MAX_SAMPLES)]
    q: Annotated[list[Vec3], Field(max_length=_MAX_SAMPLES)]
    qd: Annotated[list[Vec3], Field(max_length=_MAX_SAMPLES)]
    qdd: Annotated[list[Vec3], Field(max_length=_MAX_SAMPLES)]
    jerk: Annotated[list[Vec3], Field(max_length=_MAX_SAMPLES)] | None = None
    p: Annotated[list[Vec3], Field(max_length=_MAX_SAMPLES)] | None = None
    p_speed: Annotated[list[float], Field(max_length=_MAX_SAMPLES)] | None = None
    method: Literal["toppra", "ruckig"] | None = None
    max_deviation_q: float | None = None
    max_deviation_p: float | None = None


class Diagnostics(BaseModel):
    """Timings and margins met; the service may add fields (kept, not dropped)."""

    model_config = ConfigDict(extra="allow")

    planning_time_s: float | None = None
    timing_time_s: float | None = None
    min_clearance: float | None = None
    max_kappa_A: float | None = None
    min_serial_margin: float | None = None


class PlanResponse(_Response):
    """Answer of ``POST /v1/plan``: a finished search is a 200 with one of the statuses."""

    status: PlanStatus
    message: str = ""
    path: PathModel | None = None
    trajectory: TrajectoryModel | None = None
    diagnostics: Diagnostics = Field(default_factory=Diagnostics)


class PlanBatchRequest(_Request):
    """Body of ``POST /v1/plan/batch``."""

    requests: list[PlanRequest] = Field(min_length=1, max_length=MAX_BATCH_REQUESTS)


class PlanBatchResponse(_Response):
    """Answer of ``POST /v1/plan/batch``: one response per request, in the same order."""

    results: list[PlanResponse]


# ---------------------------------------------------------------------------- kinematics
class PostureModel(_Response):
    """One posture. Mode labels hold '0' where the posture sits exactly on that singularity."""

    q: Vec3 = Field(description="(theta1, theta2, theta3), rad.")
    passive: Annotated[list[float], Field(min_length=2, max_length=2)] = Field(
        description="(theta4, theta5), rad, in (-pi, pi]."
    )
    p: Vec3 = Field(description="Point P, m.")
    points: dict[Literal["A", "B", "C", "D", "P"], Vec3] = Field(description="Joint centres, m.")
    w: float = Field(description="Signed distance of P from the axis AB in the plane, m.")
    working_mode: str = Field(pattern=r"^[+\-0]{3}$")
    assembly_mode: str = Field(pattern=r"^[+\-0]$")
    within_limits: bool = Field(description="q lies inside the design's joint limits.")


class FKRequest(_Request):
    """Body of ``POST /v1/fk``: actuated joints; all assembly modes when none is given."""

    design: DesignModel = _DesignField
    q: Angles3 = Field(description="(theta1, theta2, theta3), rad.")
    assembly_mode: AssemblyModeLabel | None = None


class FKResponse(_Response):
    """Answer of ``POST /v1/fk``: 0, 1 or 2 postures ('+' first); none when q does not
    assemble."""

    postures: list[PostureModel]


class IKRequest(_Request):
    """Body of ``POST /v1/ik``: a point P and the working mode(s) wanted."""

    design: DesignModel = _DesignField
    p: Point3 = Field(description="(x, y, z) of P, m.")
    working_mode: WorkingModeOrAny = "any"


class IKResponse(_Response):
    """Answer of ``POST /v1/ik``: up to eight postures, one per working mode reaching P, in
    the order ``+++, ++-, +-+, +--, -++, -+-, --+, ---``; empty when P is out of reach.
    Joint limits are not applied (see ``within_limits``)."""

    postures: list[PostureModel]


class AnalyzeRequest(_Request):
    """Body of ``POST /v1/analyze``: one joint posture (and optionally joint rates)."""

    design: DesignModel = _DesignField
    q: Angles3 = Field(description="(theta1, theta2, theta3), rad.")
    assembly_mode: AssemblyModeLabel
    qd: (
        Annotated[
            list[Annotated[float, Field(allow_inf_nan=False, ge=-1e6, le=1e6)]],
            Field(min_length=3, max_length=3),
        ]
        | None
    ) = Field(None, description="Joint rates, rad/s: ask for the velocity of P.")


class SerialMargins(_Response):
    """The dimensionless serial-singularity measures (0 on that singularity)."""

    P_on_axis: float = Field(description="|w| / (L1 + L2).")
    leg_A: float = Field(description="|sin(theta4 - theta2)|.")
    leg_B: float = Field(description="|sin(theta5 - theta3)|.")
    min: float
    nearest: Literal["P_on_axis", "leg_A", "leg_B"]


class AnalyzeResponse(_Response):
    """Answer of ``POST /v1/analyze``: the Jacobians of ``A p_dot = B q_dot`` (eq. 2-4),
    their condition numbers (``null`` = infinite: singular) and the singularity margins."""

    posture: PostureModel
    A: Matrix3
    B: Matrix3
    det_A: float
    det_B: float
    kappa_A: float | None = Field(
        description="Condition number of A; null at a parallel singularity."
    )
    kappa_B: float | None = Field(
        description="Condition number of B; null at a serial singularity."
    )
    serial: SerialMargins
    parallel: float = Field(
        description="Distance of theta4 - theta5 to the nearest multiple "
        "of pi, rad (0: C, D, P aligned)."
    )
    parallel_singular: bool
    serial_singular: list[Literal["P_on_axis", "leg_A", "leg_B"]]
    pd: Vec3 | None = Field(
        None, description="Velocity of P for qd, m/s (null when not asked or A is singular)."
    )


# ---------------------------------------------------------------------------- meta, errors
class Health(_Response):
    """Answer of ``GET /v1/health``."""

    status: Literal["ok"]


class VersionInfo(_Response):
    """Answer of ``GET /v1/version``."""

    version: str
    libraries: dict[str, str]


class Readiness(_Response):
    """Answer of ``GET /v1/ready`` (HTTP 503 while not ready)."""

    status: Literal["ready", "starting", "recovering", "broken", "stopping"] = Field(
        description="'ready' while every configured worker is warm (imports done, kernels "
        "compiled); 'starting' before the first time; 'recovering' while a replacement of a "
        "dead worker warms up; 'broken' when a worker cannot be started or warmed up; "
        "'stopping' during a shutdown."
    )
    workers: int = Field(ge=0, description="Worker processes configured.")
    warm: int = Field(0, ge=0, description="Worker processes alive and warm now.")


class ErrorItem(_Response):
    """One error in FastAPI's format: ``loc`` is the path to the field, e.g.
    ``["body", "design", "L1"]``."""

    loc: list[str | int]
    msg: str
    type: str


class ErrorResponse(_Response):
    """Body of every 4xx/5xx answer of the service."""

    detail: list[ErrorItem]


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


# ---------------------------------------------------------------------------- workspace
#: Hard cap on the cells per axis of a section grid (the service's own, lower cap is the
#: setting ``max_section_resolution``); the library's bound (``analysis.sections.MAX_GRID``).
MAX_SECTION_RESOLUTION = 2048


class SectionOptions(_Request):
    """Which sections of ``POST /v1/workspace`` to compute, and how fine."""

    resolution: int = Field(
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
    seed: int = Field(0, ge=0, le=2**32 - 1, description="Seed of the quasi-random sampling.")
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


# ---------------------------------------------------------------------------- timing
#: Hard cap on the waypoints of a path sent to ``POST /v1/timing``.
MAX_TIMING_WAYPOINTS = 10_000


class TimingRequest(_Request):
    """Body of ``POST /v1/timing``: time-parameterise a joint path (N x 3 waypoints, rad,
    joined by straight joint-space segments, literal values) from rest to rest, checked
    densely against the design's joint limits, the assembly mode and, when ``margins`` or
    ``obstacles`` are given, the planner's validity rules."""

    design: DesignModel = _DesignField
    waypoints: Annotated[list[Angles3], Field(min_length=2, max_length=MAX_TIMING_WAYPOINTS)] = (
        Field(description="N x 3 joint waypoints, rad, N >= 2.")
    )
    assembly_mode: AssemblyModeLabel = Field("+", description="Assembly mode of the path.")
    method: Literal["toppra", "ruckig"] = "toppra"
    sample_rate_hz: Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=10_000.0)] = 100.0
    limits: Limits = Field(default_factory=Limits)
    max_deviation: Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=1.0)] | None = Field(
        None, description="Largest distance from a waypoint to its corner blend, rad."
    )
    stop_at: list[Annotated[int, Field(ge=0)]] = Field(
        default_factory=list,
        max_length=MAX_TIMING_WAYPOINTS,
        description="Waypoint indices where the trajectory comes to rest.",
    )
    margins: Margins | None = Field(
        None, description="Validity margins of the dense re-check (the planner's rules)."
    )
    obstacles: list[Obstacle] = Field(default_factory=list, max_length=MAX_OBSTACLES)
    working_mode: WorkingModeLabel | None = Field(
        None,
        description="Working mode the validity rules hold the path to (absent: that of the "
        "first waypoint); used with margins or obstacles.",
    )

    @field_validator("stop_at")
    @classmethod
    def _stop_at_in_range(cls, value: list[int], info: ValidationInfo) -> list[int]:
        waypoints = info.data.get("waypoints")
        n = len(waypoints) if waypoints is not None else None
        for i in value if n is not None else ():
            if i >= n:
                raise ValueError(f"stop_at holds waypoint indices in [0, {n}), got {i}")
        return value


TimingStatus = Literal["solved", "invalid_path", "infeasible", "timeout"]


class TimingResponse(_Response):
    """Answer of ``POST /v1/timing``. ``solved``: ``trajectory`` passed the dense re-check;
    ``invalid_path``: the path itself breaks a rule between its waypoints, or no repair kept
    the trajectory valid (``diagnostics.timing_error`` names the rule, time and posture);
    ``infeasible``: the solver found no profile; ``timeout``: the request's deadline passed."""

    status: TimingStatus
    message: str = ""
    trajectory: TrajectoryModel | None = None
    diagnostics: Diagnostics = Field(default_factory=Diagnostics)


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
