"""Jobs of ``/v1/design/check``, ``/v1/design/optimize``, ``/v1/design/regions`` and
``/v1/design/mjcf``: what a design's geometry allows, the best link lengths, the region map,
the robot as an MJCF model."""

from __future__ import annotations

import time

from planner.constants import ANSWER_RESERVE_S
from planner.endpoints import UNBOUNDED, JobBudget
from planner.exceptions import InputError
from planner.wire import (
    DesignCheckRequest,
    DesignCheckResponse,
    DesignModel,
    DesignOptimizeRequest,
    DesignOptimizeResponse,
    MjcfRequest,
    RegionsRequest,
    RegionsResponse,
    located,
    margins_to_core,
    mjcf_answer,
    regions_model,
    sampled_value,
)

__all__ = ["design_check", "mjcf", "mjcf_of_query", "optimize_design", "regions"]


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
    request's (bounded) sample size and generations, stopped at the request's deadline
    (:class:`planner.exceptions.DeadlineError`, 504)."""
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
            deadline=budget.deadline,
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
        rmap = region_map(design, margins, request.resolution, deadline=budget.deadline)
    return regions_model(
        rmap, computation_time_s=time.perf_counter() - t0, with_cells=request.cell_regions
    )


def mjcf(request: MjcfRequest) -> str:
    """``POST /v1/design/mjcf``: the MJCF text (:func:`planner.wire.mjcf_answer`), errors
    located in the body. Text, not a model: the route answers it as ``application/xml``."""
    return mjcf_answer(request)


def mjcf_of_query(request: MjcfRequest) -> str:
    """``GET /v1/design/mjcf``: as :func:`mjcf`, errors located in the query."""
    return mjcf_answer(request, design_loc=("query",), loc=("query",))
