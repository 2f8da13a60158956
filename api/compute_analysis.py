"""Jobs of the analysis and timing endpoints (``/v1/workspace``, ``/v1/figures``,
``/v1/design/optimize``, ``/v1/design/regions``, ``/v1/timing``): request model in, response model (or bytes) out, run
in a worker process like the jobs of :mod:`planner_api.compute`. No FastAPI here.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from planner.exceptions import AssemblyError, InputError
from planner.kinematics import WORKING_MODES, forward_batch, mode_label
from planner.wire import (
    DesignModel,
    DesignOptimizeRequest,
    DesignOptimizeResponse,
    Diagnostics,
    FigureQuery,
    RegionsRequest,
    RegionsResponse,
    SectionGrid,
    TimingErrorInfo,
    TimingRequest,
    TimingResponse,
    WorkspaceRequest,
    WorkspaceResponse,
    joint_limits_to_core,
    located,
    margins_to_core,
    obstacles_to_core,
    regions_model,
    sampled_value,
    timing_error,
    trajectory_model,
)
from planner_api.compute import UNBOUNDED, JobBudget

__all__ = ["figure", "optimize_design", "regions", "section_grid", "timing", "workspace"]


def _bits(mask: np.ndarray) -> list[list[int]]:
    """(ny, nx, K) bool -> (ny, nx) int bit masks, bit k for slot k."""
    weights = 1 << np.arange(mask.shape[-1], dtype=np.int64)
    return (mask.astype(np.int64) * weights).sum(axis=-1).tolist()


def section_grid(section: Any) -> SectionGrid:
    """The wire form of a :class:`planner.analysis.sections.Section`."""
    best = section.best_kappa
    best_list = [[float(v) if math.isfinite(v) else None for v in row] for row in best]
    working_mode = None
    if section.kind == "joint":
        wm = section.working_mode
        working_mode = [
            [
                [mode_label(wm[j, i, k]) if section.reached[j, i, k] else None for k in range(2)]
                for i in range(wm.shape[1])
            ]
            for j in range(wm.shape[0])
        ]
    return SectionGrid(
        kind=section.kind,
        x=section.x.tolist(),
        y=section.y.tolist(),
        theta1=section.theta1,
        labels=list(section.labels),
        reached=_bits(section.reached),
        singular=_bits(section.singular),
        best_kappa=best_list,
        working_mode=working_mode,
    )


def workspace(request: WorkspaceRequest, budget: JobBudget = UNBOUNDED) -> WorkspaceResponse:
    """``POST /v1/workspace``: closed-form and sampled volumes (per working mode, well
    conditioned, GCI) and the Cartesian and joint sections as grids."""
    from planner.analysis.sections import cartesian_section, joint_section
    from planner.analysis.workspace import closed_form_volume, sample_workspace

    with located("body", "design"):
        design = request.design.to_design()
    deadline = budget.deadline
    sample = sample_workspace(
        design,
        rel_se=request.rel_se,
        kappa_max=request.kappa_max,
        working_modes=request.working_modes,
        joint_limits=request.joint_limits,
        seed=request.seed,
        # half of what is left of the request's budget (the sections come next)
        deadline=None if deadline is None else (time.monotonic() + deadline) / 2,
    )
    opts = request.sections
    cart = joint = None
    with located("body", "sections"):
        if opts.cartesian:
            cart = section_grid(
                cartesian_section(
                    design, opts.resolution, theta1=opts.theta1, joint_limits=request.joint_limits
                )
            )
        if opts.joint:
            joint = section_grid(
                joint_section(
                    design, opts.resolution, theta1=opts.theta1, joint_limits=request.joint_limits
                )
            )
    return WorkspaceResponse(
        design=DesignModel.from_design(design),
        volume=closed_form_volume(design),
        sampled_volume=sampled_value(sample.volume),
        per_mode={label: sampled_value(e) for label, e in sample.per_mode.items()},
        kappa_max=request.kappa_max,
        well_conditioned_volume=sampled_value(sample.well_conditioned),
        well_conditioned_fraction=sampled_value(sample.well_conditioned_fraction),
        gci=sampled_value(sample.gci),
        cartesian_section=cart,
        joint_section=joint,
    )


def figure(args: tuple[str, str, FigureQuery]) -> bytes:
    """``GET /v1/figures/{name}.{fmt}``: the image bytes (``args`` = name, format, query)."""
    from planner.plotting import render_figure

    name, fmt, query = args
    with located("query"):
        return render_figure(name, query.design(), n=query.resolution, fmt=fmt, dpi=query.dpi)


def _check_bounds(request: DesignOptimizeRequest) -> None:
    """The rules of the bounds that the schema cannot state (each error names its field)."""
    if request.reach is None:
        for name in ("L1_bounds", "L2_bounds"):
            if getattr(request, name) is None:
                raise InputError(f"{name} is required when reach is null", field=name)
    if request.reach is not None and request.L1_bounds is not None:
        lo, hi = request.L1_bounds
        if max(lo, 1e-6) > min(hi, request.reach - 1e-6):
            raise InputError(
                f"L1_bounds {request.L1_bounds} leave no room below reach", field="L1_bounds"
            )


def optimize_design(
    request: DesignOptimizeRequest, budget: JobBudget = UNBOUNDED
) -> DesignOptimizeResponse:
    """``POST /v1/design/optimize``: :func:`planner.analysis.optimize.optimize_design` with the
    request's (bounded) sample size and generations."""
    from planner.analysis.optimize import optimize_design as optimize
    from planner.analysis.workspace import closed_form_volume

    with located("body"):
        _check_bounds(request)
    with located("body", "design"):
        template = request.design.to_design()

    def bounds(b: list[float] | None) -> tuple[float, float] | None:
        return None if b is None else (b[0], b[1])

    with located("body"):
        best = optimize(
            request.objective,
            reach=request.reach,
            L0_bounds=bounds(request.L0_bounds),
            L1_bounds=bounds(request.L1_bounds),
            L2_bounds=bounds(request.L2_bounds),
            template=template,
            kappa_max=request.kappa_max,
            n_samples=request.n_samples,
            maxiter=request.maxiter,
            seed=request.seed,
        )
    return DesignOptimizeResponse(
        design=DesignModel.from_design(best.design),
        objective=best.objective,
        value=best.value,
        volume=closed_form_volume(best.design),
        success=best.success,
        message=best.message,
        evaluations=best.evaluations,
    )


def regions(request: RegionsRequest, budget: JobBudget = UNBOUNDED) -> RegionsResponse:
    """``POST /v1/design/regions``: :func:`planner.analysis.regions.region_map` of the design
    under its margins at the request's resolution (cached per worker process, so a second
    request for the same map answers at once)."""
    from planner.analysis.regions import region_map

    with located("body", "design"):
        design = request.design.to_design()
    margins = margins_to_core(request.margins)
    t0 = time.perf_counter()
    with located("body", "resolution"):
        rmap = region_map(design, margins, request.resolution)
    return regions_model(rmap, computation_time_s=time.perf_counter() - t0)


# ---------------------------------------------------------------------------- timing
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
    from planner.wire import Margins as WireMargins

    obstacles = obstacles_to_core(request.obstacles)
    margins = margins_to_core(request.margins or WireMargins())
    working_mode = request.working_mode
    if working_mode is None:
        working_mode = mode_label(forward_batch(design, q0[None], request.assembly_mode)
                                  .working_mode_signs[0])  # fmt: skip
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
            diagnostics = Diagnostics(
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
                **options,
            )
    except TimingDeadlineError as exc:
        return TimingResponse(status="timeout", message=f"timing ran out of time: {exc}")
    except TimingInfeasibleError as exc:
        return TimingResponse(status="infeasible", message=f"no time profile found: {exc}")
    except TrajectoryCheckError as exc:
        diagnostics = Diagnostics(timing_error=timing_error(exc))
        return TimingResponse(
            status="invalid_path", message=f"the path breaks a rule: {exc}", diagnostics=diagnostics
        )
    trajectory = trajectory_model(traj, request.format)
    diagnostics = Diagnostics(timing_time_s=traj.computation_time_s, timing_repairs=traj.repairs)
    return TimingResponse(status="solved", trajectory=trajectory, diagnostics=diagnostics)
