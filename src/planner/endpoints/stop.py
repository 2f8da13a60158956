"""The endpoint of ``/v1/stop``: the braking trajectory to rest from a running state."""

from __future__ import annotations

import numpy as np

from planner.endpoints import UNBOUNDED, JobBudget
from planner.exceptions import InputError
from planner.wire import (
    MarginsModel,
    design_to_core,
    joint_limits_to_core,
    located,
    margins_to_core,
    obstacles_to_core,
    points_from_arrays,
)
from planner.wire.execution import StopRequest, StopResponse, running_trajectory

__all__ = ["stop"]


def stop(request: StopRequest, budget: JobBudget = UNBOUNDED) -> StopResponse:
    """``POST /v1/stop``: convert (the running trajectory read as a controller reads it,
    :class:`planner.timing.running.RunningTrajectory`; a malformed one is a 422 naming its
    field, an ``at`` outside it a 422 at ``at``), stop
    (:func:`planner.timing.braking.stop_trajectory`: along the running path where the
    limits allow, else a Ruckig brake; the path's postures re-checked against the request's
    non-serial rules, a brake off it against every rule of the working mode at ``at``),
    respond (times on the running clock)."""
    from planner.kinematics import WORKING_MODES, forward_batch, mode_label
    from planner.timing.braking import stop_trajectory
    from planner.validity import ValidityChecker

    design = design_to_core(request.design)
    running = running_trajectory(request.trajectory, ("body",))
    with located("body"):
        at = running.check_time(request.at, "at")
    limits = joint_limits_to_core(request.limits)
    margins = margins_to_core(request.margins or MarginsModel())
    obstacles = obstacles_to_core(request.obstacles)
    asm = request.assembly_mode
    free = ValidityChecker(design, margins, obstacles, asm, "+++", serial_rules=False)
    q0 = running.state_at(at)[0]
    fb = forward_batch(design, q0[None], asm)
    mode = mode_label(fb.working_mode_signs[0]) if fb.ok[0] else ""
    brake = free.with_mode(mode, serial_rules=True) if mode in WORKING_MODES else free
    result = stop_trajectory(
        running,
        at,
        design=design,
        assembly_mode=asm,
        limits=limits,
        path_rules=free.is_valid,
        brake_rules=brake.is_valid,
        jerk_limited=request.method == "ruckig",
        sample_rate_hz=request.sample_rate_hz,
    )
    if budget.max_samples is not None and result.t.shape[0] > budget.max_samples:
        with located("body"):
            raise InputError(
                f"sample_rate_hz = {request.sample_rate_hz:g} Hz gives {result.t.shape[0]} "
                f"samples over the {result.stop_time:.4g} s stop, more than the service's "
                f"{budget.max_samples}: lower the rate",
                field="sample_rate_hz",
            )
    trajectory = None
    if result.status == "solved":
        arrays = {
            "duration": result.stop_time,
            "t": result.t.tolist(),
            "q": result.q.tolist(),
            "qd": result.qd.tolist(),
            "qdd": result.qdd.tolist(),
            "method": request.method,
        }
        if request.format == "points":
            points = points_from_arrays(result.t, result.q, result.qd, result.qdd)
            trajectory = {**points, "duration": result.stop_time, "method": request.method}
        else:
            trajectory = arrays
    return StopResponse.model_validate(
        {
            "status": result.status,
            "message": result.message,
            "trajectory": trajectory,
            "along_path": result.along_path,
            "stop_time": result.stop_time if result.status == "solved" else None,
            "computation_time_s": float(np.float64(result.computation_time_s)),
        }
    )
