"""Jobs of ``/v1/fk``, ``/v1/ik`` and ``/v1/analyze``: the postures of a joint vector, of a
point, and one posture's Jacobians, conditioning and margins."""

from __future__ import annotations

import numpy as np

from planner.constants import KAPPA_SOLVABLE
from planner.endpoints import UNBOUNDED, JobBudget
from planner.exceptions import AssemblyError
from planner.kinematics import SERIAL_KINDS, Manipulator
from planner.wire import (
    AnalyzeRequest,
    AnalyzeResponse,
    FKRequest,
    FKResponse,
    IKRequest,
    IKResponse,
    SerialMargins,
    located,
    posture_model,
)

__all__ = ["analyze", "fk", "ik"]


def fk(request: FKRequest, budget: JobBudget = UNBOUNDED) -> FKResponse:
    """``POST /v1/fk``: the postures of q (one assembly mode, or all)."""
    with located("body", "design"):
        m = Manipulator(request.design.to_design())
    with located("body", "q"):
        if request.assembly_mode is None:
            found = m.forward(np.array(request.q))
        else:
            try:
                found = [m.posture(np.array(request.q), request.assembly_mode)]
            except AssemblyError:
                found = []
    return FKResponse(postures=[posture_model(m, p) for p in found])


def ik(request: IKRequest, budget: JobBudget = UNBOUNDED) -> IKResponse:
    """``POST /v1/ik``: the postures reaching p, one per working mode."""
    with located("body", "design"):
        m = Manipulator(request.design.to_design())
    with located("body", "p"):
        found = m.inverse(np.array(request.p))
    if request.working_mode != "any":
        found = [p for p in found if p.working_mode == request.working_mode]
    return IKResponse(postures=[posture_model(m, p) for p in found])


def _finite_or_none(x: float | np.ndarray) -> float | None:
    return float(x) if np.isfinite(x) else None


def analyze(request: AnalyzeRequest, budget: JobBudget = UNBOUNDED) -> AnalyzeResponse:
    """``POST /v1/analyze``: Jacobians, condition numbers, margins and modes of one posture."""
    with located("body", "design"):
        m = Manipulator(request.design.to_design())
    with located("body", "q"):
        posture = m.posture(np.array(request.q), request.assembly_mode)
    a, b = m.jacobians(posture)
    c = m.conditioning(posture)
    kappa_a = _finite_or_none(c.kappa_A)
    parallel_singular = kappa_a is None or kappa_a > KAPPA_SOLVABLE or posture.assembly_mode == "0"
    pd = None
    if request.qd is not None and not parallel_singular:
        pd = m.cartesian_velocity(posture, np.array(request.qd)).tolist()
    serial = [c.P_on_axis, c.leg_A, c.leg_B]
    return AnalyzeResponse(
        posture=posture_model(m, posture),
        A=a.tolist(),
        B=b.tolist(),
        det_A=float(np.linalg.det(a)),
        det_B=float(np.linalg.det(b)),
        kappa_A=kappa_a,
        kappa_B=_finite_or_none(c.kappa_B),
        serial=SerialMargins(
            P_on_axis=c.P_on_axis,
            leg_A=c.leg_A,
            leg_B=c.leg_B,
            min=min(serial),
            nearest=SERIAL_KINDS[int(np.argmin(serial))],
        ),
        parallel=c.parallel,
        parallel_singular=parallel_singular,
        serial_singular=[
            k for k, s in zip(SERIAL_KINDS, posture.working_mode, strict=True) if s == "0"
        ],
        pd=pd,
    )
