"""POST /v1/design/check: what a design's geometry allows (parallel singularities, operative
working modes, workspace volume and conditioning)."""

from __future__ import annotations

import math
from collections.abc import Callable, Coroutine
from typing import Any

from fastapi import APIRouter, Request, Response
from fastapi.exceptions import RequestValidationError
from fastapi.routing import APIRoute

from planner.analysis.design_check import check_design
from planner.analysis.workspace import Estimate
from planner.schemas import DesignCheckRequest, DesignCheckResponse, DesignModel, SampledValue


def _json_safe(value: Any) -> Any:
    """``value`` with every non-finite float written as a string ('nan', 'inf', '-inf')."""
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value


class _FiniteErrorRoute(APIRoute):
    """A route whose 422 answers can be rendered as JSON even when the rejected input held
    NaN or an infinity (FastAPI echoes the input, and JSON has no NaN)."""

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()

        async def guarded(request: Request) -> Response:
            try:
                return await handler(request)
            except RequestValidationError as exc:
                raise RequestValidationError(_json_safe(list(exc.errors()))) from None

        return guarded


router = APIRouter(prefix="/v1/design", tags=["design"], route_class=_FiniteErrorRoute)


def _sampled(e: Estimate) -> SampledValue:
    return SampledValue(value=e.value, standard_error=e.standard_error, n_samples=e.n_samples)


@router.post("/check", response_model=DesignCheckResponse)
def design_check(request: DesignCheckRequest) -> DesignCheckResponse:
    """Check a design: which parallel singularities can occur and why, which working modes are
    operative, the closed-form and sampled workspace volumes, the well-conditioned fraction."""
    check = check_design(
        request.design.to_design(),
        kappa_max=request.kappa_max,
        rel_se=request.rel_se,
        seed=request.seed,
    )
    return DesignCheckResponse(
        design=DesignModel.from_design(check.design),
        volume=check.volume,
        parallel_singularities=list(check.parallel_singularities),
        singularity_free=check.singularity_free,
        reasons=check.reasons,
        operative_working_modes=list(check.operative_working_modes),
        sampled_volume=_sampled(check.sampled_volume),
        kappa_max=check.kappa_max,
        well_conditioned_fraction=_sampled(check.well_conditioned_fraction),
        gci=_sampled(check.gci),
    )
