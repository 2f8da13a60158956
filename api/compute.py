"""The service's jobs: one module-level function per endpoint, request model in, response
model out, run in a worker process (:mod:`api.workers`). No FastAPI here: the same functions
serve the CLI.

A library error raised while handling one field gets ``loc`` (the path of that field in the
request body) attached, so :mod:`api.errors` can name the field in its 422 answer.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import replace
from typing import Any

import numpy as np
from pydantic import BaseModel

from planner.constants import KAPPA_SOLVABLE
from planner.exceptions import AssemblyError, PlannerError
from planner.kinematics import SERIAL_KINDS, Manipulator, Posture
from planner.schemas import (
    AnalyzeRequest,
    AnalyzeResponse,
    DesignCheckRequest,
    DesignCheckResponse,
    DesignModel,
    FKRequest,
    FKResponse,
    IKRequest,
    IKResponse,
    PlanRequest,
    PlanResponse,
    PostureModel,
    SampledValue,
    SerialMargins,
    TrajectoryModel,
)

__all__ = [
    "analyze",
    "answer_sample_limit",
    "as_json",
    "design_check",
    "fk",
    "ik",
    "joint_limits",
    "limits_loc",
    "located",
    "plan",
    "posture_model",
    "sampled_value",
    "timing_error",
    "trajectory_model",
]


#: The deadline of the job being run (a :func:`time.monotonic` value, one clock for every
#: process of the machine), set by :func:`as_json`; None: no deadline (e.g. the CLI).
_DEADLINE: ContextVar[float | None] = ContextVar("deadline", default=None)
#: The most trajectory samples one answer may carry (from the service's settings, see
#: :func:`answer_sample_limit`; None: the library's cap), set by :func:`as_json`.
_MAX_SAMPLES: ContextVar[int | None] = ContextVar("max_samples", default=None)
#: A bound on the JSON bytes of one trajectory sample (t, q, qd, qdd, jerk, p, |dP/dt|: 17
#: numbers of at most ~22 characters each, with brackets and commas).
BYTES_PER_SAMPLE = 400


def answer_sample_limit(max_samples: int, max_response_bytes: int, answers: int = 1) -> int:
    """The most trajectory samples per answer when ``answers`` answers share one response
    of at most ``max_response_bytes`` and no answer may carry more than ``max_samples``."""
    return max(2, min(max_samples, max_response_bytes // (BYTES_PER_SAMPLE * max(answers, 1))))


#: Time kept back from a plan's search for timing and answering before the deadline, s.
_ANSWER_RESERVE_S = 0.25


def as_json(
    job: Callable[[Any], BaseModel],
    request: Any,
    *,
    deadline: float | None = None,
    max_samples: int | None = None,
) -> bytes:
    """``job(request)`` serialised to JSON bytes, in the worker: the event loop then only
    forwards bytes (no re-validation, no pickling of large response models). ``deadline`` is
    the request's, for jobs that can stop early (timing); ``max_samples`` bounds the
    trajectory samples of the answer (a 422 naming ``timing.sample_rate_hz`` beyond it,
    decided before any sample is computed)."""
    token = _DEADLINE.set(deadline)
    samples_token = _MAX_SAMPLES.set(max_samples)
    try:
        return job(request).model_dump_json().encode()
    finally:
        _MAX_SAMPLES.reset(samples_token)
        _DEADLINE.reset(token)


@contextmanager
def located(*loc: str | int) -> Iterator[None]:
    """Attach ``loc`` (e.g. ``("body", "q")``) to a :class:`PlannerError` raised inside, unless
    a more precise location is already attached."""
    try:
        yield
    except PlannerError as exc:
        if not hasattr(exc, "loc"):
            field = getattr(exc, "field", None)
            exc.loc = (*loc, field) if field else loc  # type: ignore[attr-defined]
        raise


def _finite_or_none(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def posture_model(manipulator: Manipulator, posture: Posture) -> PostureModel:
    """The wire form of a library posture."""
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


def fk(request: FKRequest) -> FKResponse:
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


def ik(request: IKRequest) -> IKResponse:
    """``POST /v1/ik``: the postures reaching p, one per working mode."""
    with located("body", "design"):
        m = Manipulator(request.design.to_design())
    with located("body", "p"):
        found = m.inverse(np.array(request.p))
    if request.working_mode != "any":
        found = [p for p in found if p.working_mode == request.working_mode]
    return IKResponse(postures=[posture_model(m, p) for p in found])


def analyze(request: AnalyzeRequest) -> AnalyzeResponse:
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


def design_check(request: DesignCheckRequest) -> DesignCheckResponse:
    """``POST /v1/design/check``: which parallel singularities the design allows and why, its
    operative working modes, closed-form and sampled volumes, well-conditioned fraction."""
    from planner.analysis.design_check import check_design

    with located("body", "design"):
        design = request.design.to_design()
    check = check_design(
        design, kappa_max=request.kappa_max, rel_se=request.rel_se, seed=request.seed
    )

    return DesignCheckResponse(
        design=DesignModel.from_design(check.design),
        volume=check.volume,
        parallel_singularities=list(check.parallel_singularities),
        singularity_free=check.singularity_free,
        reasons=check.reasons,
        operative_working_modes=list(check.operative_working_modes),
        sampled_volume=sampled_value(check.sampled_volume),
        kappa_max=check.kappa_max,
        well_conditioned_fraction=sampled_value(check.well_conditioned_fraction),
        gci=sampled_value(check.gci),
    )


def plan(request: PlanRequest) -> PlanResponse:
    """``POST /v1/plan``: plan one request with :func:`planner.planning.plan`, then time the
    path with :func:`planner.timing.time_path` (unless ``timing.method`` is ``"none"``).

    The wire models are turned into the library's objects here; a library error is a 422
    naming the field it came from. Timing outcomes: the request's deadline passing gives
    status ``timeout``; a path the timing cannot turn into a checked trajectory (no profile,
    or the dense re-check fails after the repairs) gives ``no_path`` with the reason, the
    path kept and ``diagnostics.timing_error`` naming the failed rule.
    """
    from planner.geometry import obstacle_from_wire
    from planner.planning import CartesianTarget, JointPosture, PlanOptions, path_state_checker
    from planner.planning import plan as plan_path
    from planner.validity import Margins

    with located("body", "design"):
        design = request.design.to_design()
    with located("body", "start"):
        start = JointPosture(np.array(request.start.q), request.start.assembly_mode)
    with located("body", "goal"):
        g = request.goal
        goal = (
            JointPosture(np.array(g.q), g.assembly_mode)
            if hasattr(g, "q")
            else CartesianTarget(np.array(g.p), g.working_mode)
        )
    obstacles = []
    for i, o in enumerate(request.obstacles):
        with located("body", "obstacles", i):
            obstacles.append(obstacle_from_wire(o.model_dump()))
    with located("body", "margins"):
        margins = Margins(**request.margins.model_dump(exclude_none=True))
    with located("body", "planner"):
        options = PlanOptions(
            **request.planner.model_dump(
                exclude_none=True,
                include={"name", "time_budget_s", "seed", "simplify", "stop_at_transits"},
            )
        )
    deadline = _DEADLINE.get()
    if deadline is not None:
        # the search may not outlive the request: it gets what is left of the request's budget
        # (minus a reserve for timing and the answer), so that it ends as no_path, not a 504
        left = deadline - time.monotonic() - _ANSWER_RESERVE_S
        if left < options.time_budget_s:
            options = replace(options, time_budget_s=max(left, 0.01))
    result = plan_path(design, start, goal, obstacles=obstacles, margins=margins, options=options)
    response = PlanResponse.model_validate(result.as_wire())
    if request.timing.method != "none" and result.path is not None:
        # the planner's rules per piece: each segment's mode, serial rules off near transits
        from planner.timing import DEFAULT_MAX_DEVIATION

        deviation = request.timing.max_deviation
        near = DEFAULT_MAX_DEVIATION if deviation is None else deviation
        check = path_state_checker(design, margins, obstacles, result.path, near=near)
        _add_trajectory(request, response, design, check)
    return response


def limits_loc(exc: Exception) -> tuple[str | int, ...]:
    """Where in the body a limits error belongs: ``body.limits.<field>`` when the message
    names the field."""
    for name in ("velocity", "acceleration", "jerk"):
        if f"limits.{name}" in str(exc):
            return ("body", "limits", name)
    return ("body", "limits")


def joint_limits(wire: Any) -> Any:
    """The request's ``limits`` (absent fields: the library's defaults) as
    :class:`planner.timing.JointLimits`; a bad value raises ``LimitsError`` located at the
    offending ``body.limits.<field>``."""
    from planner.exceptions import LimitsError
    from planner.timing import JointLimits

    default = JointLimits.default()
    try:
        return JointLimits(
            velocity=wire.velocity or default.velocity,
            acceleration=wire.acceleration or default.acceleration,
            jerk=wire.jerk or default.jerk,
        )
    except LimitsError as exc:
        exc.loc = limits_loc(exc)  # type: ignore[attr-defined]
        raise


def _add_trajectory(
    request: PlanRequest, response: PlanResponse, design: Any, check: Any | None
) -> None:
    """Time ``response.path`` in place: fill ``trajectory`` and the timing diagnostics, or
    turn the status into ``timeout`` / ``no_path`` with the reason. ``check`` (Q -> valid,
    :func:`planner.planning.path_state_checker`: each segment's rules, serial rules off near
    transits) supplies the validity rules of the dense re-check; joint limits and assembly
    are always checked."""
    from planner.exceptions import TimingDeadlineError, TimingError
    from planner.timing import time_path

    assert response.path is not None
    path = response.path
    limits = joint_limits(request.limits)
    options: dict[str, Any] = {}
    if request.timing.max_deviation is not None:
        options["max_deviation"] = request.timing.max_deviation
    stop = request.planner.stop_at_transits or request.timing.stop_at_transits
    stop_at = [t.index for t in path.transits] if stop else []
    try:
        with located("body", "timing"):
            traj = time_path(
                design,
                np.array(path.waypoints),
                limits,
                method=request.timing.method,
                assembly_mode=path.segments[0].assembly_mode if path.segments else "+",
                sample_rate_hz=request.timing.sample_rate_hz,
                max_cartesian_speed=request.limits.cartesian_speed,
                stop_at=stop_at,
                check_states=check,
                deadline=_DEADLINE.get(),
                max_samples=_MAX_SAMPLES.get(),
                **options,
            )
    except TimingDeadlineError as exc:
        response.status = "timeout"
        response.message = f"the path was found but timing ran out of time: {exc}"
        return
    except TimingError as exc:  # no profile, or the dense re-check failed after the repairs
        response.status = "no_path"
        response.message = f"the path was found but could not be timed: {exc}"
        response.diagnostics.timing_error = timing_error(exc)
        return
    response.trajectory = trajectory_model(traj)
    response.diagnostics.timing_time_s = traj.computation_time_s
    response.diagnostics.timing_repairs = traj.repairs


def sampled_value(estimate: Any) -> SampledValue:
    """The wire form of an :class:`planner.analysis.workspace.Estimate` (None: zero, no
    samples)."""
    if estimate is None:
        return SampledValue(value=0.0, standard_error=0.0, n_samples=0)
    return SampledValue(
        value=estimate.value, standard_error=estimate.standard_error, n_samples=estimate.n_samples
    )


def trajectory_model(traj: Any) -> TrajectoryModel:
    """The wire form of a :class:`planner.timing.Trajectory`."""
    return TrajectoryModel(
        method=traj.method,
        duration=traj.duration,
        t=traj.t.tolist(),
        q=traj.q.tolist(),
        qd=traj.qd.tolist(),
        qdd=traj.qdd.tolist(),
        jerk=traj.jerk.tolist() if traj.jerk is not None else None,
        p=traj.p.tolist(),
        p_speed=traj.p_speed.tolist(),
        max_deviation_q=traj.max_deviation_q,
        max_deviation_p=traj.max_deviation_p,
    )


def timing_error(exc: Exception) -> dict[str, Any]:
    """``diagnostics.timing_error`` of a failed timing: the error's type, and the rule, time
    and posture of a failed dense re-check."""
    q = getattr(exc, "q", None)
    return {
        "type": type(exc).__name__,
        "rule": getattr(exc, "rule", None),
        "time": getattr(exc, "time", None),
        "q": list(q) if q is not None else None,
    }
