"""POST /v1/workspace (volumes and sections) and GET /v1/figures/{name}.png|svg, computed in
a worker."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Query, Response

from planner.endpoints import workspace as jobs
from planner.wire import ErrorResponse, FigureQuery, WorkspaceRequest, WorkspaceResponse
from planner_api.deps import Deadline, Pool, SettingsDep
from planner_api.errors import error_response
from planner_api.exceptions import LimitExceededError
from planner_api.routes._common import run_job

__all__ = ["figure", "router", "workspace"]

router = APIRouter(prefix="/v1", tags=["workspace"])

#: Names of the figures and their media types (kept here so the event loop never imports
#: matplotlib; a test checks them against :data:`planner.plotting.NAMED_FIGURES`).
FIGURE_NAMES: tuple[str, ...] = (
    "cartesian_section",
    "inertia_map",
    "isoconditioning",
    "joint_section",
    "parallel_c_equals_d",
    "parallel_cd_stretched",
    "region_images",
    "region_map",
    "regions_convex_mode",
    "regions_nonconvex_mode",
    "serial_singularity",
    "working_mode_and_parallel_singularity",
    "working_modes",
    "workspace_convex_mode",
    "workspace_nonconvex_mode",
)
MEDIA_TYPES = {"png": "image/png", "svg": "image/svg+xml"}


def _cap(resolution: int, cap: int, loc: tuple[str, ...]) -> None:
    if resolution > cap:
        raise LimitExceededError(
            f"resolution must be at most the service's max_section_resolution {cap}, "
            f"got {resolution}",
            loc,
        )


@router.post("/workspace", response_model=WorkspaceResponse)
async def workspace(
    body: WorkspaceRequest, pool: Pool, deadline: Deadline, settings: SettingsDep
) -> Response:
    """Workspace of a design: the closed-form volume without joint limits, the sampled volume
    (with its standard error) per working mode and well-conditioned, the global conditioning
    index, and the Cartesian (u, w) and joint (theta2, theta3) sections as grids."""
    _cap(
        body.sections.resolution,
        settings.max_section_resolution,
        ("body", "sections", "resolution"),
    )
    return await run_job(
        pool,
        jobs.workspace,
        body,
        deadline,
        design_defaults=settings.design_defaults,
    )


@router.get(
    "/figures/{filename}",
    response_class=Response,
    responses={
        200: {"content": {t: {} for t in MEDIA_TYPES.values()}, "description": "The image."},
        404: {
            "model": ErrorResponse,
            "description": "Unknown figure name or format (the answer lists the names).",
        },
    },
)
async def figure(
    filename: Annotated[
        str,
        Path(
            description="``{name}.png`` or ``{name}.svg``",
            json_schema_extra={"enum": [f"{n}.{f}" for n in FIGURE_NAMES for f in MEDIA_TYPES]},
        ),
    ],
    query: Annotated[FigureQuery, Query()],
    pool: Pool,
    deadline: Deadline,
    settings: SettingsDep,
) -> Response:
    """A figure of the design given by the query parameters (``L0``, ``L1``, ``L2``; absent:
    the service's default robot, ``PLANNER_DEFAULT_DESIGN``), as ``{name}.png`` or ``{name}.svg``. Names: ``working_modes``,
    ``parallel_cd_stretched``, ``parallel_c_equals_d``, ``serial_singularity``,
    ``cartesian_section``, ``joint_section``, ``working_mode_and_parallel_singularity``,
    ``workspace_convex_mode``, ``workspace_nonconvex_mode``, ``isoconditioning``. A figure
    of a singularity the design does not have is a 422."""
    name, _, fmt = filename.rpartition(".")
    if name not in FIGURE_NAMES or fmt not in MEDIA_TYPES:
        return error_response(
            404,
            f"no figure {filename!r}: names are {', '.join(FIGURE_NAMES)}; formats are "
            f"{', '.join(MEDIA_TYPES)} (e.g. /v1/figures/cartesian_section.png?L0=0.5)",
            "not_found",
            ("path", "filename"),
        )
    _cap(query.resolution, settings.max_section_resolution, ("query", "resolution"))
    absent = {"L0", "L1", "L2"} - query.model_fields_set
    if absent:  # absent lengths: the configured default robot's
        defaults = settings.design_defaults
        query = query.model_copy(update={k: getattr(defaults, k) for k in absent})
    content = await pool.run(jobs.figure, (name, fmt, query), deadline=deadline)
    return Response(content=content, media_type=MEDIA_TYPES[fmt])
