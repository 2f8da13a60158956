"""The service's jobs: one module-level function per endpoint, request model in, response
model out, run in a worker process (:mod:`planner_api.workers`). No FastAPI here: the same functions
serve the CLI.

The wire <-> library conversions are those of :mod:`planner.wire`; a library error raised
while converting one field is located there (:func:`planner.wire.located`), so
:mod:`planner_api.errors` can name the field in its 422 answer.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from pydantic import BaseModel

from planner.constants import ANSWER_RESERVE_S, KAPPA_SOLVABLE
from planner.exceptions import AssemblyError, InputError
from planner.kinematics import SERIAL_KINDS, Manipulator
from planner.wire import (
    AnalyzeRequest,
    AnalyzeResponse,
    CartesianRequest,
    CartesianResponse,
    DesignCheckRequest,
    DesignCheckResponse,
    DesignModel,
    FKRequest,
    FKResponse,
    IKRequest,
    IKResponse,
    PlanRequest,
    PlanResponse,
    SerialMargins,
    cartesian_inputs,
    cartesian_response,
    located,
    plan_inputs,
    plan_response,
    posture_model,
    sampled_value,
)

__all__ = [
    "BYTES_PER_SAMPLE",
    "UNBOUNDED",
    "Job",
    "JobBudget",
    "analyze",
    "answer_sample_limit",
    "as_json",
    "cartesian",
    "design_check",
    "fk",
    "ik",
    "plan",
]


@dataclass(frozen=True, slots=True)
class JobBudget:
    """What one job may spend, handed to it as a parameter (every job is
    ``job(request, budget)``).

    Attributes
    ----------
    deadline : float or None
        The request's deadline, a :func:`time.monotonic` value (one clock for every process
        of the machine); None: no deadline (e.g. the CLI).
    max_samples : int or None
        The most trajectory samples the answer may carry (from the service's settings, see
        :func:`answer_sample_limit`); None: the library's cap.
    """

    deadline: float | None = None
    max_samples: int | None = None


#: No deadline, the library's sample cap: the budget of a job called in-process.
UNBOUNDED = JobBudget()
#: A bound on the JSON bytes of one trajectory sample (t, q, qd, qdd, jerk, p, |dP/dt|: 17
#: numbers of at most ~22 characters each, with brackets and commas).
BYTES_PER_SAMPLE = 400


def answer_sample_limit(max_samples: int, max_response_bytes: int, answers: int = 1) -> int:
    """The most trajectory samples per answer when ``answers`` answers share one response
    of at most ``max_response_bytes`` and no answer may carry more than ``max_samples``."""
    return max(2, min(max_samples, max_response_bytes // (BYTES_PER_SAMPLE * max(answers, 1))))


#: A job: request model and budget in, response model out.
Job = Callable[[Any, JobBudget], BaseModel]


def as_json(job: Job, request: Any, budget: JobBudget = UNBOUNDED) -> bytes:
    """``job(request, budget)`` serialised to JSON bytes, in the worker: the event loop then
    only forwards bytes (no re-validation, no pickling of large response models). The
    budget's deadline is the request's, for jobs that can stop early (planning, timing); its
    ``max_samples`` bounds the trajectory samples of the answer (a 422 naming
    ``timing.sample_rate_hz`` beyond it, decided before any sample is computed)."""
    return job(request, budget).model_dump_json().encode()


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


def _finite_or_none(x: float) -> float | None:
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


def design_check(request: DesignCheckRequest, budget: JobBudget = UNBOUNDED) -> DesignCheckResponse:
    """``POST /v1/design/check``: which parallel singularities the design allows and why, its
    operative working modes, closed-form and sampled volumes, well-conditioned fraction."""
    from planner.analysis.design_check import check_design

    with located("body", "design"):
        design = request.design.to_design()
    deadline = budget.deadline
    check = check_design(
        design,
        kappa_max=request.kappa_max,
        rel_se=request.rel_se,
        seed=request.seed,
        # the sampled volume refines while the request's budget lasts (less a reserve for
        # the answer), then answers with the standard error it reached: never a 504
        deadline=None if deadline is None else deadline - 4 * ANSWER_RESERVE_S,
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


def plan(request: PlanRequest, budget: JobBudget = UNBOUNDED) -> PlanResponse:
    """``POST /v1/plan``: convert (:func:`planner.wire.plan_inputs`, once), solve
    (:func:`planner.solve`: the plan with the goal options ``prefer`` and ``tolerance``, then
    the timing of its path under the path's own rules, re-checked densely; one deadline
    policy, the library's), respond (:func:`planner.wire.plan_response`, built once).

    A library error is a 422 naming the field it came from. Timing outcomes: the request's
    deadline passing gives status ``timeout``; a path the timing cannot turn into a checked
    trajectory (no profile, or the dense re-check fails after the repairs) gives ``no_path``
    with the reason, the path kept and ``diagnostics.timing_error`` naming the failed rule.
    """
    from planner.solver import solve

    inputs = plan_inputs(request)
    timing = replace(inputs.timing, max_samples=budget.max_samples)
    kwargs = {**inputs.solve_kwargs(), "timing": timing}
    # an error of the timing step names its field under ``timing.`` (the default location of a
    # library error is the body, :mod:`planner_api.errors`)
    solution = solve(inputs.design, inputs.start, inputs.goal, deadline=budget.deadline, **kwargs)
    return plan_response(solution, format=request.timing.format)


def cartesian(request: CartesianRequest, budget: JobBudget = UNBOUNDED) -> CartesianResponse:
    """``POST /v1/cartesian``: the request's library objects
    (:func:`planner.wire.cartesian_inputs`), :func:`planner.planning.cartesian.plan_cartesian`
    (the straight path, certified, and its timing), and one response built once
    (:func:`planner.wire.cartesian_response`).

    The answer's samples are bounded by ``budget.max_samples`` (a 422 naming
    ``timing.sample_rate_hz`` beyond it, checked once the trajectory is known).
    ``plan_cartesian`` takes no deadline: the worker pool's deadline (504) bounds it.
    """
    from planner.planning.cartesian import plan_cartesian

    inputs = cartesian_inputs(request)
    try:
        result = plan_cartesian(
            inputs.design,
            inputs.start,
            inputs.waypoints,
            obstacles=inputs.obstacles,
            margins=inputs.margins,
            limits=inputs.limits,
            **inputs.options,
        )
    except InputError as exc:  # the sample bound names sample_rate_hz, a field of timing
        where = ("body", "timing") if exc.field == "sample_rate_hz" else ("body",)
        with located(*where):
            raise
    traj = result.trajectory
    if traj is not None and budget.max_samples is not None and len(traj.t) > budget.max_samples:
        rate = request.timing.sample_rate_hz
        with located("body", "timing"):
            raise InputError(
                f"sample_rate_hz = {rate:g} Hz gives {len(traj.t)} samples over the "
                f"trajectory's {traj.duration:.4g} s, more than the limit of "
                f"{budget.max_samples}: lower the rate",
                field="sample_rate_hz",
            )
    return cartesian_response(result, format=request.timing.format)
