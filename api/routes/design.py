"""POST /v1/design/check: what a design's geometry allows (parallel singularities, operative
working modes, workspace volume and conditioning), computed in a worker."""

from __future__ import annotations

from fastapi import APIRouter, Response

from api import compute
from api.deps import Deadline, Pool
from api.routes._common import run_job
from planner.schemas import DesignCheckRequest, DesignCheckResponse

router = APIRouter(prefix="/v1/design", tags=["design"])


@router.post("/check", response_model=DesignCheckResponse)
async def design_check(body: DesignCheckRequest, pool: Pool, deadline: Deadline) -> Response:
    """Check a design: which parallel singularities can occur and why, which working modes are
    operative, the closed-form and sampled workspace volumes, the well-conditioned fraction."""
    return await run_job(pool, compute.design_check, body, deadline)
