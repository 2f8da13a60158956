"""The job of ``/v1/timing``: a client's joint path timed and checked densely."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from planner.endpoints import UNBOUNDED, JobBudget
from planner.exceptions import AssemblyError, InputError
from planner.kinematics import WORKING_MODES, forward_batch, mode_label

if TYPE_CHECKING:
    from planner.timing import Trajectory

from planner.wire import (
    DiagnosticsModel,
    TimingErrorInfo,
    TimingRequest,
    TimingResponse,
    inertia_to_core,
    joint_limits_to_core,
    located,
    margins_to_core,
    obstacles_to_core,
    timing_error,
    trajectory_model,
    triple_to_core,
)

__all__ = ["timing"]


def _check_waypoints(design: Any, q: np.ndarray, assembly_mode: str) -> None:
    """Each waypoint inside the literal joint limits and assembling in ``assembly_mode``
    (a 422 naming ``waypoints[i]`` otherwise)."""
    lo, hi = np.asarray(design.joint_min), np.asarray(design.joint_max)
    outside = np.nonzero(np.any((q < lo) | (q > hi), axis=1))[0]
    if outside.size:
        i = int(outside[0])
        j = int(np.argmax((q[i] < lo) | (q[i] > hi)))
        raise InputError(
            f"waypoints[{i}] is outside the joint limits: theta{j + 1} = {q[i, j]:.6g} rad not "
            f"in [{lo[j]:.6g}, {hi[j]:.6g}]",
            field=("waypoints", i, j),
        )
    batch = forward_batch(design, q, assembly_mode)
    bad = np.nonzero(~batch.ok | (batch.assembly_mode_signs == 0))[0]
    if bad.size:
        i = int(bad[0])
        raise AssemblyError(
            f"waypoints[{i}] = {q[i].tolist()} does not assemble in assembly mode "
            f"{assembly_mode!r} (the loop does not close, or it is a parallel singularity)",
            field=("waypoints", i),
        )


def _validity_check(request: TimingRequest, design: Any, q0: np.ndarray) -> Any:
    """The planner's validity rules as a ``check_states`` callable, or None when the request
    asks for none (no margins, no obstacles)."""
    if request.margins is None and not request.obstacles:
        return None
    from planner.validity import ValidityChecker
    from planner.wire import MarginsModel

    obstacles = obstacles_to_core(request.obstacles)
    margins = margins_to_core(request.margins or MarginsModel())
    working_mode: str | None = request.working_mode
    if working_mode is None:
        working_mode = mode_label(
            forward_batch(design, q0[None], request.assembly_mode).working_mode_signs[0]
        )
        if working_mode not in WORKING_MODES:  # the first waypoint sits on a serial singularity
            with located("body", "waypoints", 0):
                raise InputError(
                    f"the first waypoint is on a serial singularity (working mode "
                    f"{working_mode!r}): give working_mode explicitly"
                )
    with located("body", "working_mode"):
        checker = ValidityChecker(design, margins, obstacles, request.assembly_mode, working_mode)

    def check(q: np.ndarray) -> np.ndarray:
        return checker.is_valid(q)

    check.explain = checker.explain  # type: ignore[attr-defined]
    return check


def _start_state(request: TimingRequest, q0: np.ndarray, limits: Any) -> Any:
    """The moving start of the request (None: at rest), its rules checked (a 422 at
    ``start.qd`` / ``start.qdd``: beyond the limits, or with limits the lead-in does not
    bound)."""
    from planner.timing.lead_in import StartState, check_start_rates

    state = StartState.of(q0, request.start.qd, request.start.qdd)
    if not state.moving:
        return None
    with located("body"):
        if request.limits.torque is not None or request.limits.cartesian_speed is not None:
            raise InputError(
                "a moving start needs no limits.torque and no limits.cartesian_speed (the "
                "lead-in bounds neither)",
                field="start.qd",
            )
        check_start_rates(state, limits, jerk_limited=request.method == "ruckig")
    return state


def _with_moving_start(
    request: TimingRequest, traj: Any, state: Any, design: Any, limits: Any, check: Any
) -> Any:
    """``traj`` beginning in the moving ``state``: a lead-in onto it
    (:func:`planner.timing.lead_in.with_moving_start`); unchanged at rest."""
    from planner.timing import DEFAULT_CHECK_RESOLUTION, DEFAULT_MAX_DEVIATION
    from planner.timing.lead_in import with_moving_start

    if state is None:
        return traj
    q = np.asarray(request.waypoints, dtype=float)
    near = DEFAULT_MAX_DEVIATION if request.max_deviation is None else request.max_deviation
    return with_moving_start(
        traj,
        state,
        design=design,
        assembly_mode=request.assembly_mode,
        limits=limits,
        check_states=check,
        resolution=DEFAULT_CHECK_RESOLUTION,
        sample_rate_hz=request.sample_rate_hz,
        first_segment=q[:2],
        near=near,
    )


def _unkept(request: TimingRequest, state: Any, design: Any, limits: Any, check: Any) -> str:
    """Why a moving start cannot be kept valid ("" when it can, or at rest)."""
    from planner.timing import DEFAULT_CHECK_RESOLUTION
    from planner.timing.lead_in import braking_failure

    if state is None:
        return ""
    why = braking_failure(
        design,
        state,
        request.assembly_mode,
        limits,
        check,
        DEFAULT_CHECK_RESOLUTION,
        jerk_limited=request.method == "ruckig",
    )
    return why or ""


def timing(request: TimingRequest, budget: JobBudget = UNBOUNDED) -> TimingResponse:
    """``POST /v1/timing``: :func:`planner.timing.time_path` on the client's joint path,
    checked densely (joint limits, assembly, and the planner's rules when asked).

    Bad input (a waypoint outside the joint limits or not assembling, bad limits) is a 422
    naming the field; an outcome of the timing itself is a 200 with a ``status``."""
    from planner.exceptions import (
        TimingDeadlineError,
        TimingInfeasibleError,
        TrajectoryCheckError,
    )
    from planner.timing import time_path

    with located("body", "design"):
        design = request.design.to_design()
    q = np.asarray(request.waypoints, dtype=float)
    with located("body"):
        _check_waypoints(design, q, request.assembly_mode)
    check = _validity_check(request, design, q[0])
    if check is not None:
        bad = np.nonzero(~check(q))[0]
        if bad.size:
            i = int(bad[0])
            diagnostics = DiagnosticsModel(
                timing_error=TimingErrorInfo(
                    type="InvalidWaypoint", rule="validity", q=q[i].tolist(), index=i
                )
            )
            return TimingResponse(
                status="invalid_path",
                message=f"waypoints[{i}] breaks a validity rule: {check.explain(q[i])}",
                diagnostics=diagnostics,
            )
    limits = joint_limits_to_core(request.limits)
    state = _start_state(request, q[0], limits)
    unkept = _unkept(request, state, design, limits, check)
    if unkept:
        return TimingResponse(status="invalid_start", message=unkept)
    options: dict[str, Any] = {}
    if request.max_deviation is not None:
        options["max_deviation"] = request.max_deviation
    try:
        with located("body"):  # an input error names its field (sample_rate_hz, stop_at...)
            traj = time_path(
                design,
                q,
                limits,
                method=request.method,
                assembly_mode=request.assembly_mode,
                sample_rate_hz=request.sample_rate_hz,
                max_cartesian_speed=request.limits.cartesian_speed,
                stop_at=request.stop_at,
                check_states=check,
                deadline=budget.deadline,
                max_samples=budget.max_samples,
                inertia=inertia_to_core(request.design),
                gravity=triple_to_core(request.gravity),
                **options,
            )
            traj = _with_moving_start(request, traj, state, design, limits, check)
    except TimingDeadlineError as exc:
        return TimingResponse(status="timeout", message=f"timing ran out of time: {exc}")
    except TimingInfeasibleError as exc:
        return TimingResponse(status="infeasible", message=f"no time profile found: {exc}")
    except TrajectoryCheckError as exc:
        diagnostics = DiagnosticsModel(timing_error=timing_error(exc))
        return TimingResponse(
            status="invalid_path", message=f"the path breaks a rule: {exc}", diagnostics=diagnostics
        )
    trajectory = trajectory_model(traj, request.format)
    diagnostics = DiagnosticsModel(
        timing_time_s=traj.computation_time_s,
        timing_repairs=traj.repairs,
        max_torque_ratio=traj.max_torque_ratio,
    )
    return TimingResponse(
        status="solved",
        message=_solved_message(request.method, len(q), traj),
        trajectory=trajectory,
        diagnostics=diagnostics,
    )


def _solved_message(method: str, waypoints: int, traj: Trajectory) -> str:
    """What a solved timing did, in one line (as a solved plan says its mode and route)."""
    message = (
        f"timed with {method}: {waypoints} waypoints in {traj.duration:.6g} s, "
        f"{len(traj.t)} samples"
    )
    if traj.repairs:
        message += f", {traj.repairs} repair round(s) after the dense re-check"
    if traj.max_torque_ratio is not None:
        message += f", max |tau|/limit {traj.max_torque_ratio:.4g}"
    return message
