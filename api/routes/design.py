"""POST /v1/design/check: what a design's geometry allows (parallel singularities, operative
working modes, workspace volume and conditioning); /v1/design/optimize: the best link lengths;
/v1/design/regions: the region map. Each computed in a worker."""

from __future__ import annotations

from fastapi import APIRouter, Response

from planner.wire import (
    DesignCheckRequest,
    DesignCheckResponse,
    DesignOptimizeRequest,
    DesignOptimizeResponse,
    RegionsRequest,
    RegionsResponse,
)
from planner_api import compute, compute_analysis
from planner_api.deps import Deadline, Pool, SettingsDep
from planner_api.routes._common import run_job

__all__ = ["design_check", "design_optimize", "design_regions", "router"]

router = APIRouter(prefix="/v1/design", tags=["design"])


@router.post("/check", response_model=DesignCheckResponse)
async def design_check(
    body: DesignCheckRequest, pool: Pool, deadline: Deadline, settings: SettingsDep
) -> Response:
    """Check a design: which parallel singularities can occur and why, which working modes are
    operative, the closed-form and sampled workspace volumes, the well-conditioned fraction."""
    return await run_job(
        pool, compute.design_check, body, deadline, design_defaults=settings.design_defaults
    )


@router.post("/optimize", response_model=DesignOptimizeResponse)
async def design_optimize(
    body: DesignOptimizeRequest, pool: Pool, deadline: Deadline, settings: SettingsDep
) -> Response:
    """Maximise the workspace volume, the well-conditioned volume or the global conditioning
    index over the link lengths (fixed ``reach = L1 + L2``, or bounds on each length). The
    budget is bounded by ``n_samples`` and ``maxiter`` (both capped)."""
    return await run_job(
        pool,
        compute_analysis.optimize_design,
        body,
        deadline,
        design_defaults=settings.design_defaults,
    )


@router.post("/regions", response_model=RegionsResponse)
async def design_regions(
    body: RegionsRequest, pool: Pool, deadline: Deadline, settings: SettingsDep
) -> Response:
    """The region map of a design: the connected regions of each working mode and assembly
    mode in the (theta2, theta3) grid (cells surely valid or undecided under ``margins``), and
    the transits joining regions across serial surfaces. ``resolution`` (cells per axis,
    16 .. 512) bounds the work: time and memory grow as its square."""
    return await run_job(
        pool, compute_analysis.regions, body, deadline, design_defaults=settings.design_defaults
    )
