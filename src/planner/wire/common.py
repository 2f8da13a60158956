"""The shared objects of every endpoint family: number types with their sanity bounds, the
request and response bases, the design, joint postures and Cartesian targets, obstacles and
validity margins (``docs/conventions.md``, *Shared objects*).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    PrivateAttr,
    Tag,
    ValidationInfo,
    field_validator,
    model_serializer,
    model_validator,
)
from pydantic_core import PydanticCustomError

from planner.caching import cached
from planner.constants import MAX_POINTS
from planner.design import MAX_JOINT_TRAVEL, MAX_LENGTH, MIN_LENGTH, Design
from planner.exceptions import DesignError, InputError, PlannerError

if TYPE_CHECKING:
    from planner import geometry
    from planner.dynamics import Inertia, LinkInertia
    from planner.validity import Margins

__all__ = [
    "GRAVITY_FIELD",
    "MAX_BATCH_REQUESTS",
    "MAX_COORDINATE",
    "MAX_GOAL_TOLERANCE_M",
    "MAX_GOAL_TOLERANCE_RAD",
    "MAX_OBSTACLES",
    "MAX_POINTS",
    "Angle",
    "Angles3",
    "AssemblyModeLabel",
    "BaseInertiaModel",
    "BoxObstacle",
    "CapsuleObstacle",
    "CartesianTargetModel",
    "Coordinate",
    "DesignModel",
    "Finite",
    "Goal",
    "Gravity",
    "InertiaModel",
    "Integer",
    "JointGoal",
    "JointPostureModel",
    "Length",
    "LinkInertiaModel",
    "LinkLength",
    "MarginsModel",
    "Matrix3",
    "Obstacle",
    "PayloadModel",
    "Point3",
    "PointsObstacle",
    "PositiveSize",
    "Preference",
    "Rates3",
    "SphereObstacle",
    "Vec3",
    "WorkingModeLabel",
    "WorkingModeOrAny",
    "design_to_core",
    "inertia_to_core",
    "located",
    "margins_to_core",
    "obstacle_from_dict",
    "obstacles_to_core",
    "triple_to_core",
]

#: Largest |coordinate| of a point on the wire, m: a sanity bound far above any workcell.
MAX_COORDINATE = 1e4
#: Hard cap on obstacles in one request (the service's own, lower cap is a setting).
MAX_OBSTACLES = 10_000
#: Plan requests in one batch: the schema's ``maxItems`` and the service's real limit (its
#: setting ``PLANNER_MAX_BATCH`` may only lower it). A longer list is refused by its length,
#: before any item is parsed (:class:`planner.wire.plan.PlanBatchRequest`): 10,000 small
#: plans once took 3.5 s of the event loop to be told "at most 64".
MAX_BATCH_REQUESTS = 64
#: Largest sample count of a returned trajectory or path accepted by a client.
_MAX_SAMPLES = 10_000_000

_DEFAULT = Design.default()

WorkingModeLabel = Literal["+++", "++-", "+-+", "+--", "-++", "-+-", "--+", "---"]
WorkingModeOrAny = Literal["+++", "++-", "+-+", "+--", "-++", "-+-", "--+", "---", "any"]
AssemblyModeLabel = Literal["+", "-"]


# ---------------------------------------------------------------------------- number types
def _whole_number(value: Any) -> Any:
    """A JSON number written with a fraction of zero (``8.0``, which JSON does not tell from
    ``8``) as the integer it is; a fractional one (``8.5``) refused by name; anything else
    left to the strict integer check (``true`` and ``"8"`` stay refused)."""
    if isinstance(value, float):
        if value.is_integer():
            return int(value)
        raise PydanticCustomError(
            "int_from_float", "Input should be a whole number, got {value}", {"value": value}
        )
    return value


#: An integer field of a request: strict (no bool, no string) but a whole float is taken.
Integer = Annotated[int, BeforeValidator(_whole_number)]
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
    not a number, ``"1.5"`` is not a number; an integer is a number, and a whole number is an
    integer: ``8.0`` where a field is an :data:`Integer`): a client's mistake is named, not
    coerced."""

    model_config = ConfigDict(extra="forbid", strict=True)


class _Response(BaseModel):
    """Base of response models: unknown fields are ignored (forward compatibility)."""

    model_config = ConfigDict(extra="ignore")


# ---------------------------------------------------------------------------- inertia
#: A mass (kg) or an inertia (kg m^2): finite, >= 0, below the library's sanity bound.
Mass = Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=1e6)]
Moment = Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=1e6)]


class LinkInertiaModel(_Request):
    """One link as a rigid body: inertia tensor ``I_perp (Id - e e^T) + I_axial e e^T`` about
    its centre of mass, e the link's direction.

    Every field is optional; an absent one comes from the design's default link
    (:meth:`planner.dynamics.Inertia.default`, a uniform aluminium tube): ``com`` as it is,
    ``I_perp`` and ``I_axial`` scaled by ``mass / default mass`` when ``mass`` is given (the
    same tube made of a material that weighs ``mass``), else as they are; ``mass`` absent: the
    default's. So ``{"mass": 0.3}`` alone is a consistent rigid body.
    """

    mass: Mass | None = Field(None, description="kg, >= 0 (absent: the default link's).")
    com: Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=1.0)] | None = Field(
        None,
        description="Centre of mass as a fraction of the link's length from its proximal "
        "pivot (A or B for a proximal link, C or D for a distal one), in [0, 1] (absent: the "
        "default link's, 0.5).",
    )
    I_perp: Moment | None = Field(
        None,
        description="kg m^2 about an axis normal to the link, >= 0 (absent: the default "
        "link's, scaled by mass / its mass when mass is given).",
    )
    I_axial: Moment | None = Field(
        None,
        description="kg m^2 about the link's own line, >= 0 and <= 2 I_perp (the triangle "
        "inequality of a rod's inertia tensor; absent: as I_perp).",
    )

    @field_validator("I_axial")
    @classmethod
    def _triangle(cls, value: float | None, info: ValidationInfo) -> float | None:
        perp = info.data.get("I_perp")
        if value is not None and perp is not None and value > 2 * perp * (1 + 1e-12):
            raise ValueError(
                f"I_axial must be <= 2 I_perp (the triangle inequality of a rod's inertia "
                f"tensor), got I_axial = {value:g} > 2 x {perp:g}"
            )
        return value


class PayloadModel(_Request):
    """The payload: a point mass at P."""

    mass: Mass = Field(description="kg, >= 0.")


class BaseInertiaModel(_Request):
    """The body that turns with theta1 (carrying the motors of theta2 and theta3)."""

    inertia: Moment = Field(description="kg m^2 about AB, >= 0.")


class InertiaModel(_Request):
    """``design.inertia``: the inertial model; an absent part takes the product's documented
    default for the design (:meth:`planner.dynamics.Inertia.default`: aluminium tubes of the
    design's link_radius, a 0.5 kg payload, docs/dynamics.md)."""

    proximal: LinkInertiaModel | None = Field(None, description="AC and BD (com from A, B).")
    distal: LinkInertiaModel | None = Field(None, description="CP and DP (com from C, D).")
    payload: PayloadModel | None = None
    base: BaseInertiaModel | None = None
    rotor: Annotated[list[Moment], Field(min_length=3, max_length=3)] | None = Field(
        None, description="Each actuator's rotor inertia reflected to its joint, kg m^2."
    )


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
    inertia: InertiaModel | None = Field(
        None,
        description="Masses and inertias (docs/dynamics.md); absent: the documented defaults "
        "for this design.",
    )

    @field_validator("joint_max")
    @classmethod
    def _above_min(cls, value: list[float], info: ValidationInfo) -> list[float]:
        lo = info.data.get("joint_min")
        if lo is None:  # joint_min failed its own check: nothing to compare with
            return value
        for i in range(3):
            if not lo[i] < value[i]:
                raise ValueError(
                    f"joint_max[{i}] must be above joint_min[{i}], got {value[i]} <= {lo[i]}"
                )
        return value

    @model_serializer(mode="wrap")
    def _without_absent_inertia(self, handler: Any):
        """No ``inertia`` key when none was given: a design without one is written as it
        was before the field existed (clients compare designs by their JSON, e.g. the
        viewer against the presets). Not annotated: the schema stays the model's."""
        data = handler(self)
        if isinstance(data, dict) and data.get("inertia", 0) is None:
            del data["inertia"]
        return data

    #: The library design, built once when the model is validated (the check of every rule
    #: of :class:`planner.Design` is that construction); pickled with the model.
    _design: Design | None = PrivateAttr(default=None)

    @model_validator(mode="after")
    def _check_design(self) -> DesignModel:
        try:
            self._design = self._build()
        except DesignError as exc:  # any remaining rule of Design
            raise ValueError(str(exc)) from exc
        return self

    def to_design(self) -> Design:
        """The library's :class:`planner.Design` (the one built at validation: a request's
        design object is built once)."""
        if self._design is None:
            self._design = self._build()
        return self._design

    def _build(self) -> Design:
        return _design_of(
            self.L0,
            self.L1,
            self.L2,
            self.link_radius,
            triple_to_core(self.joint_min),
            triple_to_core(self.joint_max),
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


@cached("wire.designs")
def _design_of(
    L0: float,
    L1: float,
    L2: float,
    link_radius: float,
    joint_min: tuple[float, float, float],
    joint_max: tuple[float, float, float],
) -> Design:
    """The :class:`planner.Design` of these numbers, built (and its rules checked) once per
    distinct design: a service validates the same few designs in every request, and the
    design is immutable, so requests may share it. A design that breaks a rule raises each
    time (errors are not remembered)."""
    return Design(
        L0=L0, L1=L1, L2=L2, link_radius=link_radius, joint_min=joint_min, joint_max=joint_max
    )


_DesignField = Field(default_factory=DesignModel, description="The robot; default robot if absent.")


#: ``gravity``: m/s^2 in the base frame, a top-level request field.
Gravity = Annotated[
    list[Annotated[float, Field(allow_inf_nan=False, ge=-1e4, le=1e4)]],
    Field(min_length=3, max_length=3),
]
GRAVITY_FIELD = Field(
    default_factory=lambda: [0.0, 0.0, -9.81],
    description="Gravity in the base frame, m/s^2 (default [0, 0, -9.81]).",
)


# ---------------------------------------------------------------------------- postures, targets
class JointPostureModel(_Request):
    """A joint posture: actuated joints and the assembly mode (sign of sin(theta5 - theta4))."""

    q: Angles3 = Field(description="(theta1, theta2, theta3), rad.")
    assembly_mode: AssemblyModeLabel = Field(description="'+' or '-'.")


#: Largest ``goal.tolerance`` of a Cartesian target, m, and of a joint goal, rad.
MAX_GOAL_TOLERANCE_M = 1.0
MAX_GOAL_TOLERANCE_RAD = math.pi
#: How a working mode is chosen for a Cartesian target with ``working_mode`` "any".
Preference = Literal["shortest", "best_conditioned"]


class JointGoal(JointPostureModel):
    """A joint goal: a joint posture, and how far from it (rad) the path may end."""

    tolerance: Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=MAX_GOAL_TOLERANCE_RAD)] = (
        Field(
            0.0,
            description="Largest Euclidean distance in joint space (rad) between the path's end "
            "and q, in [0, pi]; 0 (default): exactly q. With a tolerance, a goal q that breaks a "
            "rule or cannot be reached is replaced by a valid posture within it.",
        )
    )


class CartesianTargetModel(_Request):
    """A Cartesian target for P, with the working mode to reach it in (or ``"any"``)."""

    p: Point3 = Field(description="(x, y, z) of P, m.")
    working_mode: WorkingModeOrAny = Field(
        "any", description="(s_axis, s_A, s_B) as '+-+'-style text, or 'any'."
    )
    prefer: Preference = Field(
        "shortest",
        description="With working_mode 'any': 'shortest' (default: the shortest joint path) "
        "or 'best_conditioned' (the reachable working mode whose path keeps the largest "
        "kappa(A) lowest: the most precise motion, the paper's section 3.3).",
    )
    velocity: Annotated[list[Finite], Field(min_length=3, max_length=3)] | None = Field(
        None,
        description="A part on a belt, in a sequence's targets only (elsewhere a 422): its "
        "constant velocity, m/s, |velocity| at most 2 m/s; p is where it is at time t0. The "
        "tool meets it (P and its velocity equal the part's) and moves with it for the "
        "target's dwell.",
    )
    t0: Finite | None = Field(
        None,
        description="With velocity: the sequence time at which the part is at p, s (default 0).",
    )
    tolerance: Annotated[float, Field(allow_inf_nan=False, ge=0.0, le=MAX_GOAL_TOLERANCE_M)] = (
        Field(
            0.0,
            description="Largest distance (m) of P at the path's end from p, in [0, 1]; 0 "
            "(default): exactly p. With a tolerance, a p that no allowed posture reaches is "
            "replaced by a reachable point within it.",
        )
    )

    @field_validator("prefer")
    @classmethod
    def _prefer_needs_any(cls, value: str, info: ValidationInfo) -> str:
        mode = info.data.get("working_mode", "any")
        if value != "shortest" and mode != "any":
            raise ValueError(
                f"prefer {value!r} chooses among working modes: it needs working_mode "
                f"'any', got {mode!r}"
            )
        return value


def _goal_kind(value: Any) -> str | None:
    if isinstance(value, dict):
        if "q" in value:
            return "q"
        return "p" if "p" in value else None
    if isinstance(value, CartesianTargetModel):
        return "p"
    if isinstance(value, JointPostureModel):
        return "q"
    return None


#: A goal: a joint goal (has ``q``) or a Cartesian target (has ``p``). Validation errors
#: name the branch taken: ``goal.q.<field>`` or ``goal.p.<field>``.
Goal = Annotated[
    Annotated[JointGoal, Tag("q")] | Annotated[CartesianTargetModel, Tag("p")],
    Discriminator(
        _goal_kind,
        custom_error_type="goal_kind",
        custom_error_message="goal must be a joint posture {q, assembly_mode} "
        "or a Cartesian target {p, working_mode}",
    ),
]


# ---------------------------------------------------------------------------- obstacles
def _tag_required(schema: dict[str, Any]) -> None:
    """An obstacle's JSON schema lists ``type`` as required, without a default: the union
    :data:`Obstacle` picks its member by ``type``, so a body without it is refused (the
    default only serves Python code that builds one member by its class)."""
    required = schema.setdefault("required", [])
    if "type" not in required:
        required.insert(0, "type")
    schema.get("properties", {}).get("type", {}).pop("default", None)


class _Obstacle(_Request):
    """Base of the obstacle members of :data:`Obstacle` (their schemas: :func:`_tag_required`)."""

    model_config = ConfigDict(json_schema_extra=_tag_required)


class SphereObstacle(_Obstacle):
    type: Literal["sphere"] = "sphere"
    center: Point3 = Field(description="m.")
    radius: PositiveSize = Field(description="m, > 0.")


class BoxObstacle(_Obstacle):
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


class CapsuleObstacle(_Obstacle):
    """The set of points within ``radius`` of the segment ``a``-``b``."""

    type: Literal["capsule"] = "capsule"
    a: Point3 = Field(description="m.")
    b: Point3 = Field(description="m.")
    radius: PositiveSize = Field(description="m, > 0.")


class PointsObstacle(_Obstacle):
    """A point cloud: every point a ball of ``radius`` (a depth camera's points, a CAD model
    sampled). At most :data:`MAX_POINTS` points in all the clouds of one request; the list's
    length is checked before its points are validated."""

    type: Literal["points"] = "points"
    points: Annotated[list[Point3], Field(min_length=1, max_length=MAX_POINTS)] = Field(
        description=f"N x 3 points, m, 1 <= N <= {MAX_POINTS}."
    )
    radius: PositiveSize = Field(description="m, > 0: the radius of every point's ball.")


Obstacle = Annotated[
    SphereObstacle | BoxObstacle | CapsuleObstacle | PointsObstacle, Field(discriminator="type")
]


# ---------------------------------------------------------------------------- plan options
class MarginsModel(_Request):
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


# ---------------------------------------------------------------------------- wire -> core
# The core modules are imported inside the conversions: the client and the CLI import the
# vocabulary without paying for numba, OMPL or toppra.


@contextmanager
def located(*loc: str | int) -> Iterator[None]:
    """Attach ``loc`` (the path of a request field, e.g. ``("body", "q")``) to a
    :class:`~planner.exceptions.PlannerError` raised inside, followed by the error's own
    ``field`` when it has one, unless an inner block already located it: the service turns
    ``loc`` into ``detail[].loc`` (:mod:`planner_api.errors`)."""
    try:
        yield
    except PlannerError as exc:
        if not hasattr(exc, "loc"):
            exc.loc = (*loc, *exc.field_path)  # type: ignore[attr-defined]
        raise


def obstacle_from_dict(data: Mapping[str, Any]) -> geometry.Obstacle:
    """A library obstacle from its wire dictionary (``{"type": "sphere", "center": ...}``).

    Raises
    ------
    InputError
        Unknown ``type``, a missing field, or a field breaking its rule (named).
    """
    from planner.geometry import Box, Capsule, Points, Sphere

    kind = data.get("type")
    try:
        if kind == "points":
            return Points(data["points"], data["radius"])
        if kind == "sphere":
            return Sphere(data["center"], data["radius"])
        if kind == "box":
            return Box(data["center"], data["size"], data.get("quaternion", (1.0, 0.0, 0.0, 0.0)))
        if kind == "capsule":
            return Capsule(data["a"], data["b"], data["radius"])
    except KeyError as exc:
        raise InputError(
            f"obstacle of type {kind!r} lacks the field {exc.args[0]!r}", field=exc.args[0]
        ) from exc
    raise InputError(
        f"obstacle type must be 'sphere', 'box', 'capsule' or 'points', got {kind!r}",
        field="type",
    )


def obstacles_to_core(
    models: Sequence[SphereObstacle | BoxObstacle | CapsuleObstacle | PointsObstacle],
    loc: tuple[str | int, ...] = ("body", "obstacles"),
    points_before: int = 0,
) -> list[geometry.Obstacle]:
    """The library obstacles of a request's ``obstacles``, built from the models' fields
    (errors located at ``loc.<i>``). The points of all clouds together, with the
    ``points_before`` of a named scene's clouds, are at most :data:`MAX_POINTS` (a 422 at the
    cloud that passes it, ``loc.<i>.points``)."""
    from planner.geometry import Box, Capsule, Points, Sphere

    out: list[geometry.Obstacle] = []
    n_points = points_before
    for i, model in enumerate(models):
        with located(*loc, i):
            if isinstance(model, PointsObstacle):
                n_points += len(model.points)
                if n_points > MAX_POINTS:
                    scene = f" (its scene's {points_before} included)" if points_before else ""
                    raise InputError(
                        f"the point clouds of one request{scene} hold at most {MAX_POINTS} "
                        f"points in all, got {n_points} by this one",
                        field="points",
                    )
                out.append(Points(np.asarray(model.points, dtype=float), model.radius))
            elif isinstance(model, SphereObstacle):
                out.append(Sphere(np.asarray(model.center, dtype=float), model.radius))
            elif isinstance(model, BoxObstacle):
                center, size = (np.asarray(v, dtype=float) for v in (model.center, model.size))
                out.append(Box(center, size, np.asarray(model.quaternion, dtype=float)))
            else:
                a, b = np.asarray(model.a, dtype=float), np.asarray(model.b, dtype=float)
                out.append(Capsule(a, b, model.radius))
    return out


def triple_to_core(values: Sequence[float]) -> tuple[float, float, float]:
    """Three numbers of the wire (a list its model holds to length 3: a joint vector, rates,
    gravity) as the library's triple."""
    x, y, z = values
    return (x, y, z)


def margins_to_core(
    model: MarginsModel, loc: tuple[str | int, ...] = ("body", "margins")
) -> Margins:
    """The library's :class:`planner.validity.Margins` (absent fields: its defaults)."""
    from planner.validity import Margins as CoreMargins

    with located(*loc):
        return CoreMargins(**model.model_dump(exclude_none=True))


def design_to_core(model: DesignModel, loc: tuple[str | int, ...] = ("body", "design")) -> Design:
    """The library design of a request's ``design`` (errors located at ``loc``)."""
    with located(*loc):
        return model.to_design()


def _completed_link(part: LinkInertiaModel, base: LinkInertia, name: str) -> LinkInertia:
    """A wire link with its absent fields from the design's default link ``base``
    (:class:`LinkInertiaModel`: a given mass scales the default's moments)."""
    from planner.dynamics import LinkInertia

    mass = base.mass if part.mass is None else part.mass
    scale = mass / base.mass if part.mass is not None and base.mass > 0 else 1.0
    return LinkInertia(
        mass,
        base.com if part.com is None else part.com,
        base.I_perp * scale if part.I_perp is None else part.I_perp,
        base.I_axial * scale if part.I_axial is None else part.I_axial,
        name,
    )


def inertia_to_core(
    model: DesignModel, loc: tuple[str | int, ...] = ("body", "design", "inertia")
) -> Inertia | None:
    """The library's :class:`planner.dynamics.Inertia` of a request's ``design.inertia``
    (absent parts: :meth:`~planner.dynamics.Inertia.default` of the design), or None when
    the request gives no inertia (the caller decides whether defaults apply)."""
    if model.inertia is None:
        return None
    from planner.dynamics import Inertia

    default = Inertia.default(model.to_design())
    wire = model.inertia
    with located(*loc):

        def link(part: LinkInertiaModel | None, name: str) -> LinkInertia:
            base: LinkInertia = getattr(default, name)
            if part is None:
                return base
            return _completed_link(part, base, name)

        return Inertia(
            proximal=link(wire.proximal, "proximal"),
            distal=link(wire.distal, "distal"),
            payload_mass=default.payload_mass if wire.payload is None else wire.payload.mass,
            base_inertia=default.base_inertia if wire.base is None else wire.base.inertia,
            rotor=default.rotor if wire.rotor is None else triple_to_core(wire.rotor),
        )
