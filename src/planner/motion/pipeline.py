"""One pipeline for every kind of motion: validate -> plan -> time -> dense check -> result.

A kind of motion (:class:`Motion`: a goal reached by a search, a straight tool path, a task
sequence) supplies only its own planning step and the shape of its answer; :func:`run` does
the rest the same way for all of them:

1. **validate** what no planning step can mend: a start where gravity alone needs more than a
   joint's torque limit (with ``limits.torque`` and timing asked) is ``invalid_start``, naming
   the joint and the torque, before any search; so is a moving start (``start_qd``,
   ``start_qdd``) whose quickest braking already leaves the valid set of the start's working
   mode (:func:`planner.timing.lead_in.braking_failure`: no trajectory can keep it valid);
2. **plan**: ``motion.plan(problem)`` under the problem's :class:`~planner.motion.Budget` (the
   searches until its search deadline); a step that runs past the deadline itself (a straight
   path's certification checks it between rounds) ends as ``timeout``;
3. **time and check densely** (unless ``timing.method`` is "none" or the plan gave nothing to
   time): :func:`planner.timing.time_path` on the plan's :class:`TimingRequest` with the
   problem's limits, rate, tool speed, torques and the one sample bound
   ``timing.max_samples``, checked *before* any sample is computed (an
   :class:`~planner.exceptions.InputError` naming ``timing.sample_rate_hz``); the dense
   re-check of the trajectory against the plan's own rules is the timing's last step. When
   Ruckig cannot time a path whose rules leave it no room (its moves between through-states
   stray farther than a tight allowance), the request may name TOPPRA as a fallback
   (``TimingRequest.fallback``) and the answer says so. A moving start then gets its lead-in
   onto the timed trajectory (:func:`planner.timing.lead_in.with_moving_start`, checked
   densely against the same rules);
4. **result**: ``motion.answer(problem, planned, timed)``. One timeout answer: a deadline
   passing during the timing (or a planning step past the deadline) is status ``timeout`` for
   every kind, the path kept where there is one.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Generic, Protocol, TypeVar

import numpy as np

from planner.exceptions import DeadlineError, InputError, TimingDeadlineError, TimingError
from planner.motion.problem import MotionProblem
from planner.planning.result import PlanPath, PlanStatus
from planner.timing.checks import StateChecker
from planner.timing.trajectory import Trajectory

__all__ = ["Motion", "Planned", "Timed", "TimingRequest", "path_timing", "run", "time_planned"]

R = TypeVar("R", covariant=True)
D = TypeVar("D")


@dataclass(frozen=True, slots=True, eq=False)
class TimingRequest:
    """How the pipeline times a planned joint path.

    Attributes
    ----------
    waypoints : (N, 3) rad, the joint path.
    assembly_mode : '+' | '-'.
    check_states : the path's own validity rules for the dense re-check, Q (M, 3) -> (M,) bool.
    max_deviation : the corner allowance, rad, one number or one per waypoint.
    stop_at : waypoint indices where the trajectory comes to rest.
    via_at : waypoints passed as free via states within their allowance.
    via_radius : each via's ball, rad, one per waypoint (None: its ``max_deviation``; 0: the
        via passes the waypoint exactly, its moves within ``max_deviation`` of the path).
    check_resolution : the dense re-check's step, rad (None: the timing's default).
    fallback : methods tried, in order, when the asked method cannot time the path.
    grid_refine : toppra's grid refinement (None: the timing's default; see
        :func:`planner.timing.time_path`).
    """

    waypoints: np.ndarray
    assembly_mode: str
    check_states: StateChecker
    max_deviation: float | np.ndarray
    stop_at: tuple[int, ...] = ()
    via_at: tuple[int, ...] = ()
    via_radius: np.ndarray | None = None
    check_resolution: float | None = None
    fallback: tuple[str, ...] = ()
    grid_refine: float | None = None


@dataclass(frozen=True, slots=True, eq=False)
class Planned(Generic[D]):
    """What a kind's planning step gives the pipeline: a status and message (``solved``, or
    why nothing can be timed), the kind's own detail (its plan, its straight path, its legs;
    None when the pipeline stopped before planning) and how to time it (None: nothing to
    time)."""

    status: PlanStatus
    message: str
    detail: D | None = None
    timing: TimingRequest | None = None


@dataclass(frozen=True, slots=True, eq=False)
class Timed:
    """The timing step's outcome: the checked trajectory, or the error that stopped it (a
    passed deadline: :class:`~planner.exceptions.TimingDeadlineError`), or neither (not
    asked). ``note`` says when a fallback method timed it; ``time_s`` is the step's time."""

    trajectory: Trajectory | None = None
    error: TimingError | None = None
    note: str = ""
    time_s: float = 0.0
    failures: tuple[str, ...] = ()

    @property
    def late(self) -> bool:
        """The deadline passed during the timing."""
        return isinstance(self.error, TimingDeadlineError)

    @property
    def reason(self) -> str:
        """Why the timing failed: the error's text, or every method's when several failed."""
        if len(self.failures) > 1:
            return "; ".join(self.failures)
        return "" if self.error is None else str(self.error)


class Motion(Protocol[R]):
    """One kind of motion: its planning step and its answer (see the module docstring)."""

    def plan(self, problem: MotionProblem) -> Planned[Any]:
        """Plan under ``problem`` (its budget's search deadline bounds the searches)."""
        ...

    def answer(self, problem: MotionProblem, planned: Planned[Any], timed: Timed) -> R:
        """The kind's answer of a plan and its timing (``planned.detail`` is None when the
        pipeline stopped before planning: ``invalid_start`` or ``timeout``)."""
        ...


def run(problem: MotionProblem, motion: Motion[R]) -> R:
    """The answer of ``motion`` under ``problem``: validate, plan, time and check densely,
    answer (see the module docstring)."""
    held = _held_by_gravity(problem) or _unkept_start(problem)
    if held is not None:
        return motion.answer(problem, Planned(PlanStatus.INVALID_START, held), Timed())
    try:
        planned = motion.plan(problem)
    except DeadlineError as exc:
        return motion.answer(problem, Planned(PlanStatus.TIMEOUT, f"timeout: {exc}"), Timed())
    if planned.timing is None or problem.timing.method == "none":
        return motion.answer(problem, planned, Timed())
    return motion.answer(problem, planned, time_planned(problem, planned.timing))


def _held_by_gravity(problem: MotionProblem) -> str | None:
    """The ``invalid_start`` message when gravity alone overloads a joint at the start."""
    if problem.timing.method == "none" or problem.limits.torque is None:
        return None
    from planner.timing.torque import gravity_at_start

    start = problem.start
    return gravity_at_start(
        problem.design,
        start.q,
        start.assembly_mode,
        problem.limits,
        problem.inertia,
        problem.gravity,
    )


def _unkept_start(problem: MotionProblem) -> str | None:
    """The ``invalid_start`` message of a moving start that cannot be kept valid (its
    quickest braking leaves the valid set of the start's working mode); None when it can, or
    when the start posture itself breaks a rule (the planning step names that rule)."""
    if not problem.moving_start:
        return None
    from planner.kinematics import forward_batch, mode_label
    from planner.timing import DEFAULT_CHECK_RESOLUTION
    from planner.timing.lead_in import braking_failure
    from planner.validity import ValidityChecker

    start = problem.start
    fb = forward_batch(problem.design, start.q[None], start.assembly_mode)
    if not fb.ok[0]:
        return None
    mode = mode_label(fb.working_mode_signs[0])
    checker = ValidityChecker(
        problem.design, problem.margins, problem.obstacles, start.assembly_mode, mode
    )
    if not checker.is_valid(start.q[None])[0]:
        return None
    return braking_failure(
        problem.design,
        problem.start_state,
        start.assembly_mode,
        problem.limits,
        checker.is_valid,
        DEFAULT_CHECK_RESOLUTION,
        jerk_limited=problem.timing.method == "ruckig",
    )


def time_planned(problem: MotionProblem, request: TimingRequest) -> Timed:
    """Step 3 of :func:`run`: the checked trajectory of ``request`` under ``problem`` (its
    limits, timing options, torques and deadline), the fallback methods tried in turn. An
    :class:`~planner.exceptions.InputError` of the timing (the sample bound) is raised with
    its field under ``timing.``."""
    t0 = time.monotonic()
    methods = (problem.timing.method, *(m for m in request.fallback if m != problem.timing.method))
    failures: list[tuple[str, str]] = []
    for method in methods:
        try:
            trajectory = _time_path(problem, request, method)
        except TimingDeadlineError as exc:
            return Timed(error=exc, time_s=time.monotonic() - t0)
        except TimingError as exc:
            failures.append((method, str(exc)))
            if method == methods[-1]:
                said = tuple(f"{m}: {why}" for m, why in failures)
                return Timed(error=exc, time_s=time.monotonic() - t0, failures=said)
            continue
        note = ""
        if failures:
            first, why = failures[0]
            note = f"{first} failed ({why}); timed with {method} instead"
        return Timed(trajectory, note=note, time_s=time.monotonic() - t0)
    raise AssertionError("unreachable: at least one method is tried")


def _time_path(problem: MotionProblem, request: TimingRequest, method: str) -> Trajectory:
    """The trajectory of ``request`` by ``method``, with its lead-in from a moving start."""
    trajectory = _rest_to_rest(problem, request, method)
    if not problem.moving_start:
        return trajectory
    from planner.timing import DEFAULT_CHECK_RESOLUTION
    from planner.timing.lead_in import with_moving_start
    from planner.timing.torque import TorqueModel

    torques = None
    if trajectory.tau is not None:
        model = TorqueModel(problem.design, problem.inertia, problem.gravity, request.assembly_mode)
        torques = model.torques
    waypoints = np.asarray(request.waypoints, dtype=float)
    corner = np.broadcast_to(np.asarray(request.max_deviation, dtype=float), (len(waypoints),))
    return with_moving_start(
        trajectory,
        problem.start_state,
        design=problem.design,
        assembly_mode=request.assembly_mode,
        limits=problem.limits,
        check_states=request.check_states,
        resolution=request.check_resolution or DEFAULT_CHECK_RESOLUTION,
        sample_rate_hz=problem.timing.sample_rate_hz,
        first_segment=waypoints[:2] if len(waypoints) > 1 else None,
        near=float(corner[1]) if len(waypoints) > 1 else 0.0,
        torques=torques,
    )


def _rest_to_rest(problem: MotionProblem, request: TimingRequest, method: str) -> Trajectory:
    from planner.timing import DEFAULT_CHECK_RESOLUTION, time_path

    timing = problem.timing
    try:
        return time_path(
            problem.design,
            np.asarray(request.waypoints, dtype=float),
            problem.limits,
            method=method,  # type: ignore[arg-type]
            assembly_mode=request.assembly_mode,
            sample_rate_hz=timing.sample_rate_hz,
            max_cartesian_speed=timing.max_cartesian_speed,
            max_deviation=request.max_deviation,
            stop_at=request.stop_at,
            check_states=request.check_states,
            check_resolution=request.check_resolution or DEFAULT_CHECK_RESOLUTION,
            deadline=problem.budget.deadline,
            max_samples=timing.max_samples,
            inertia=problem.inertia,
            gravity=problem.gravity,
            via_at=request.via_at,
            via_radius=request.via_radius,
            grid_refine=request.grid_refine,
        )
    except InputError as exc:
        if exc.field is not None and exc.field_path[:1] != ("timing",):
            exc.field = ("timing", *exc.field_path)
        raise


def path_timing(
    problem: MotionProblem,
    path: PlanPath,
    *,
    max_deviation: float | np.ndarray | None = None,
    stop_at: Sequence[int] = (),
    via_at: Sequence[int] = (),
    via_radius: np.ndarray | None = None,
) -> TimingRequest:
    """The timing of a planned path under its own rules per piece
    (:func:`planner.planning.path_state_checker`: each segment's working mode, serial rules off
    next to a transit, within the corner allowance of the path), coming to rest at the
    transits when ``options.stop_at_transits`` or ``timing.stop_at_transits`` asks, and at
    ``stop_at``; ``max_deviation`` (one per waypoint, rad) defaults to
    ``timing.max_deviation`` everywhere; ``via_at`` and ``via_radius`` as
    :class:`TimingRequest`'s."""
    from planner.planning import path_state_checker

    timing = problem.timing
    check = path_state_checker(
        problem.design, problem.margins, problem.obstacles, path, near=timing.max_deviation
    )
    stop = problem.options.stop_at_transits or timing.stop_at_transits
    rests = sorted({*(t.index for t in path.transits if stop), *(int(i) for i in stop_at)})
    return TimingRequest(
        np.asarray(path.waypoints, dtype=float),
        path.segments[0].assembly_mode if path.segments else "+",
        check,
        timing.max_deviation if max_deviation is None else max_deviation,
        tuple(rests),
        tuple(int(i) for i in via_at),
        via_radius,
    )
