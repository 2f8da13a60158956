"""GET /v1/designs: the preset designs; POST /v1/design/check: what a design's geometry allows (parallel singularities, operative
working modes, workspace volume and conditioning); /v1/design/optimize: the best link lengths;
/v1/design/regions: the region map; GET|POST /v1/design/mjcf: the robot as an MJCF model for
MuJoCo. Each computed in a worker."""

from __future__ import annotations

from functools import lru_cache
from typing import Annotated, Any

from fastapi import APIRouter, Query, Response
from fastapi.exceptions import RequestValidationError
from pydantic import ValidationError

from planner.design import Design
from planner.endpoints import design as jobs
from planner.wire import (
    MJCF_MEDIA_TYPE,
    DesignCheckRequest,
    DesignCheckResponse,
    DesignModel,
    DesignOptimizeRequest,
    DesignOptimizeResponse,
    DesignPreset,
    DesignsResponse,
    MjcfQuery,
    MjcfRequest,
    RegionsRequest,
    RegionsResponse,
)
from planner_api.deps import Deadline, Pool, SettingsDep
from planner_api.routes._common import json_response, run_job, with_design_defaults

__all__ = [
    "design_check",
    "design_mjcf",
    "design_mjcf_query",
    "design_optimize",
    "design_regions",
    "designs",
    "presets",
    "router",
]

router = APIRouter(prefix="/v1", tags=["design"])


@router.post("/design/check", response_model=DesignCheckResponse)
async def design_check(
    body: DesignCheckRequest, pool: Pool, deadline: Deadline, settings: SettingsDep
) -> Response:
    """Check a design: which parallel singularities can occur and why, which working modes are
    operative, the closed-form and sampled workspace volumes, the well-conditioned fraction."""
    return await run_job(
        pool, jobs.design_check, body, deadline, design_defaults=settings.design_defaults
    )


@router.post("/design/optimize", response_model=DesignOptimizeResponse)
async def design_optimize(
    body: DesignOptimizeRequest, pool: Pool, deadline: Deadline, settings: SettingsDep
) -> Response:
    """Maximise the workspace volume, the well-conditioned volume or the global conditioning
    index over the link lengths (fixed ``reach = L1 + L2``, or bounds on each length). The
    budget is bounded by ``n_samples`` and ``maxiter`` (both capped)."""
    return await run_job(
        pool,
        jobs.optimize_design,
        body,
        deadline,
        design_defaults=settings.design_defaults,
    )


@router.post("/design/regions", response_model=RegionsResponse)
async def design_regions(
    body: RegionsRequest, pool: Pool, deadline: Deadline, settings: SettingsDep
) -> Response:
    """The region map of a design: the connected regions of each working mode and assembly
    mode in the (theta2, theta3) grid (cells surely valid or undecided under ``margins``), and
    the transits joining regions across serial surfaces. ``resolution`` (cells per axis,
    16 .. 512) bounds the work: time and memory grow as its square."""
    return await run_job(
        pool, jobs.regions, body, deadline, design_defaults=settings.design_defaults
    )


_MJCF_RESPONSES: dict[int | str, dict[str, Any]] = {
    200: {"content": {MJCF_MEDIA_TYPE: {}}, "description": "The MJCF model."}
}


@router.post("/design/mjcf", response_class=Response, responses=_MJCF_RESPONSES)
async def design_mjcf(
    body: MjcfRequest, pool: Pool, deadline: Deadline, settings: SettingsDep
) -> Response:
    """The robot as an MJCF model for MuJoCo (``docs/dynamics.md``): two legs from the turning
    base, the loop closed at P by an equality ``connect``, motors on theta1..theta3, the rotor
    inertias as armature, a keyframe ``home`` assembled in ``assembly_mode``. The body's
    ``design`` may carry ``inertia``; a ``home`` that does not assemble is a 422 at
    ``body.home``."""
    body = with_design_defaults(body, settings.design_defaults)
    text = await pool.run(jobs.mjcf, body, deadline=deadline)
    return Response(content=text, media_type=MJCF_MEDIA_TYPE)


@router.get("/design/mjcf", response_class=Response, responses=_MJCF_RESPONSES)
async def design_mjcf_query(
    query: Annotated[MjcfQuery, Query()], pool: Pool, deadline: Deadline, settings: SettingsDep
) -> Response:
    """The MJCF model of the design given by the query (``L0``, ``L1``, ``L2``,
    ``link_radius``; absent: the service's default robot's) with the default inertia,
    gravity and keyframe; ``POST`` the same path for a design with ``inertia``."""
    given = query.design_fields()
    try:
        design = DesignModel.model_validate({**settings.design_defaults.model_dump(), **given})
    except ValidationError as exc:
        raise RequestValidationError(
            [{**e, "loc": ("query", *e["loc"])} for e in exc.errors(include_url=False)]
        ) from exc
    body = MjcfRequest(design=design, assembly_mode=query.assembly_mode)
    text = await pool.run(jobs.mjcf_of_query, body, deadline=deadline)
    return Response(content=text, media_type=MJCF_MEDIA_TYPE)


def presets() -> DesignsResponse:
    """The named designs of ``docs/conventions.md``, ``default`` first."""
    return DesignsResponse(
        presets=[
            DesignPreset(
                name="default",
                description="What a request without a design gets: the singularity-free "
                "design (no parallel singularity anywhere, all eight working modes usable).",
                design=DesignModel.from_design(Design.default()),
            ),
            DesignPreset(
                name="singularity-free",
                description="2 L1 < L0 < 2 (L2 - L1): neither C = D nor a stretched CD can "
                "occur (the paper's figures 10-11).",
                design=DesignModel.from_design(Design.singularity_free()),
            ),
            DesignPreset(
                name="paper-optimum",
                description="L0 = 0, L1 = L2 (reach 0.8 m): the largest workspace for its size, "
                "but only two working modes are operative (figures 8-9).",
                design=DesignModel.from_design(Design.paper_optimum()),
            ),
        ]
    )


@lru_cache(maxsize=1)
def _presets_json() -> bytes:
    return presets().model_dump_json().encode()


@router.get("/designs", response_model=DesignsResponse)
async def designs() -> Response:
    """The preset designs, each usable as the ``design`` of any request."""
    return json_response(_presets_json())  # a constant: serialised once
