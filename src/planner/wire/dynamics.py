"""``POST /v1/dynamics``: actuator torques and the mass matrix of N motions;
``GET|POST /v1/design/mjcf``: the robot as an MJCF model for MuJoCo."""

from __future__ import annotations

from typing import Annotated, Any

import numpy as np
from pydantic import ConfigDict, Field, ValidationInfo, field_validator

from planner.wire.common import (
    GRAVITY_FIELD,
    Angles3,
    AssemblyModeLabel,
    DesignModel,
    Gravity,
    Length,
    LinkLength,
    Matrix3,
    Vec3,
    _DesignField,
    _Request,
    _Response,
    design_to_core,
    inertia_to_core,
    located,
)

__all__ = [
    "MAX_DYNAMICS_POSTURES",
    "MJCF_MEDIA_TYPE",
    "DynamicsRequest",
    "DynamicsResponse",
    "MjcfQuery",
    "MjcfRequest",
    "dynamics_answer",
    "mjcf_answer",
]

#: Media type of an MJCF answer (MJCF is XML; MuJoCo has no registered type of its own).
MJCF_MEDIA_TYPE = "application/xml"

#: Most postures in one ``POST /v1/dynamics`` (each answer row is ~12 numbers of M and tau).
MAX_DYNAMICS_POSTURES = 100_000

_Rate = Annotated[float, Field(allow_inf_nan=False, ge=-1e6, le=1e6)]
_Rates = Annotated[list[_Rate], Field(min_length=3, max_length=3)]


class DynamicsRequest(_Request):
    """Body of ``POST /v1/dynamics``: N motions (q, qd, qdd) of one robot in one assembly
    mode. ``design.inertia`` absent: the documented defaults (docs/dynamics.md).

    ``q`` is N x 3, or one posture ``[theta1, theta2, theta3]`` (read as N = 1: the answer is
    always N rows). ``qd`` and ``qdd`` absent: zeros (a static query: ``tau`` is then the
    torque that holds the posture against gravity); given, one row per posture of ``q`` (a
    single row may be written flat too).
    """

    design: DesignModel = _DesignField
    gravity: Gravity = GRAVITY_FIELD
    assembly_mode: AssemblyModeLabel = Field("+", description="'+' or '-'.")
    q: Annotated[list[Angles3], Field(min_length=1, max_length=MAX_DYNAMICS_POSTURES)] = Field(
        description="N x 3 actuated joints, rad (or one posture, 3 numbers: N = 1)."
    )
    qd: Annotated[list[_Rates], Field(max_length=MAX_DYNAMICS_POSTURES)] | None = Field(
        None, description="N x 3 joint velocities, rad/s (absent: zeros)."
    )
    qdd: Annotated[list[_Rates], Field(max_length=MAX_DYNAMICS_POSTURES)] | None = Field(
        None, description="N x 3 joint accelerations, rad/s^2 (absent: zeros)."
    )

    @field_validator("q", "qd", "qdd", mode="before")
    @classmethod
    def _one_posture_as_a_row(cls, value: Any) -> Any:
        """A flat list of 3 numbers is one row (N = 1); anything else goes on to the checks
        of N x 3, which name the element that breaks them."""
        if isinstance(value, list) and value and all(_is_number(x) for x in value):
            if len(value) != 3:
                raise ValueError(
                    f"one posture is 3 numbers (theta1, theta2, theta3), got {len(value)}; "
                    "N postures are N rows of 3"
                )
            return [value]
        return value

    @field_validator("qd", "qdd")
    @classmethod
    def _one_row_per_posture(cls, value: list | None, info: ValidationInfo) -> list | None:
        q = info.data.get("q")
        if value is not None and q is not None and len(value) != len(q):
            raise ValueError(
                f"{info.field_name} must have one row per posture of q: {len(q)} rows, got "
                f"{len(value)}"
            )
        return value


def _is_number(x: object) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


class DynamicsResponse(_Response):
    """Answer of ``POST /v1/dynamics``: ``tau = M(q) qdd + h(q, qd)`` per posture."""

    tau: list[Vec3] = Field(description="N x 3 actuator torques producing the motions, N m.")
    mass_matrix: list[Matrix3] = Field(
        description="N x 3 x 3 inertia matrices in actuated coordinates (kg m^2)."
    )
    kappa_A: list[float] = Field(description="kappa(A) of each posture.")


def dynamics_answer(request: DynamicsRequest) -> DynamicsResponse:
    """The torques and mass matrices of a request; a posture that does not assemble or is
    parallel-singular (kappa(A) above the solvable bound: M is unbounded there) raises
    :class:`~planner.exceptions.SingularPostureError` located at ``q.<i>``."""
    from planner.constants import KAPPA_SOLVABLE
    from planner.dynamics import Inertia, inverse_dynamics
    from planner.exceptions import SingularPostureError

    design = design_to_core(request.design)
    inertia = inertia_to_core(request.design)
    inertia = inertia if inertia is not None else Inertia.default(design)
    q = np.asarray(request.q, dtype=float)
    zeros = np.zeros_like(q)
    batch = inverse_dynamics(
        design,
        inertia,
        q,
        zeros if request.qd is None else np.asarray(request.qd, dtype=float),
        zeros if request.qdd is None else np.asarray(request.qdd, dtype=float),
        assembly_mode=request.assembly_mode,
        gravity=request.gravity,
        with_mass_matrix=True,
    )
    bad = np.flatnonzero(~batch.ok)
    if bad.size:
        i = int(bad[0])
        with located("body", "q", i):
            raise SingularPostureError(
                f"q[{i}] = {q[i].tolist()} is singular in assembly mode "
                f"{request.assembly_mode!r}: it does not assemble, or kappa(A) exceeds "
                f"{KAPPA_SOLVABLE:g} (a parallel singularity, where M is unbounded)"
            )
    m: Any = batch.mass_matrix
    return DynamicsResponse(
        tau=batch.tau.tolist(), mass_matrix=m.tolist(), kappa_A=batch.kappa_A.tolist()
    )


class MjcfRequest(_Request):
    """Body of ``POST /v1/design/mjcf`` (and, without ``design.inertia``, ``home`` and
    ``gravity``, the query of ``GET /v1/design/mjcf``): the robot to export.
    ``design.inertia`` absent: the documented defaults (docs/dynamics.md)."""

    design: DesignModel = _DesignField
    gravity: Gravity = GRAVITY_FIELD
    assembly_mode: AssemblyModeLabel = Field("+", description="Assembly mode of the keyframe.")
    home: Angles3 | None = Field(
        None,
        description="Actuated joints of the keyframe 'home', rad (default [0, 2, 1], or when "
        "it does not assemble the design's posture nearest to it that does); a given one must "
        "assemble in assembly_mode.",
    )


class MjcfQuery(_Request):
    """Query of ``GET /v1/design/mjcf``: a design by its lengths (absent: the service's default
    robot's), with the default inertia, gravity and keyframe (``POST /v1/design/mjcf`` takes
    the whole design with ``inertia``). Query strings are text: numbers are parsed (lax)."""

    model_config = ConfigDict(extra="forbid", strict=False)

    L0: Length | None = Field(None, description="|AB|, m.")
    L1: LinkLength | None = Field(None, description="|AC| = |BD|, m.")
    L2: LinkLength | None = Field(None, description="|CP| = |DP|, m.")
    link_radius: Length | None = Field(None, description="Radius of the links, m.")
    assembly_mode: AssemblyModeLabel = Field("+", description="Assembly mode of the keyframe.")

    def design_fields(self) -> dict[str, float]:
        """The design fields given in the query."""
        return {
            k: v for k in ("L0", "L1", "L2", "link_radius") if (v := getattr(self, k)) is not None
        }


def mjcf_answer(
    request: MjcfRequest,
    design_loc: tuple[str | int, ...] = ("body", "design"),
    loc: tuple[str | int, ...] = ("body",),
) -> str:
    """The MJCF text of a request (:func:`planner.dynamics.mjcf.to_mjcf`); a design the core
    refuses is an error located under ``design_loc``, a ``home`` that does not assemble at
    ``loc + ("home",)``."""
    from planner.dynamics.mjcf import to_mjcf

    with located(*design_loc):
        design = design_to_core(request.design)
        inertia = inertia_to_core(request.design)
    with located(*loc):
        return to_mjcf(
            design,
            inertia,
            gravity=request.gravity,
            home=request.home,
            assembly_mode=request.assembly_mode,
        )
