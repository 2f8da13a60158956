"""``POST /v1/fk``, ``/v1/ik`` and ``/v1/analyze``: postures, Jacobians and margins."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import (
    Field,
)

from planner.wire.common import (
    Angles3,
    AssemblyModeLabel,
    DesignModel,
    Matrix3,
    Point3,
    Vec3,
    WorkingModeOrAny,
    _DesignField,
    _Request,
    _Response,
)

if TYPE_CHECKING:
    from planner.kinematics import Manipulator, Posture

__all__ = [
    "AnalyzeRequest",
    "AnalyzeResponse",
    "FKRequest",
    "FKResponse",
    "IKRequest",
    "IKResponse",
    "PostureModel",
    "SerialMargins",
    "posture_model",
]


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


def posture_model(manipulator: Manipulator, posture: Posture) -> PostureModel:
    """The wire form of a library :class:`planner.kinematics.Posture` of ``manipulator``."""
    return PostureModel(
        q=posture.q.tolist(),
        passive=posture.passive.tolist(),
        p=posture.p.tolist(),
        points={k: v.tolist() for k, v in posture.points.items()},
        w=posture.w,
        working_mode=posture.working_mode,
        assembly_mode=posture.assembly_mode,
        within_limits=manipulator.within_limits(posture.q),
    )
