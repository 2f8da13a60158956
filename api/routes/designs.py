"""GET /v1/designs: the preset designs."""

from __future__ import annotations

from fastapi import APIRouter

from planner.design import Design
from planner.wire import DesignModel, DesignPreset, DesignsResponse

__all__ = ["designs", "presets", "router"]

router = APIRouter(prefix="/v1", tags=["designs"])


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


@router.get("/designs", response_model=DesignsResponse)
def designs() -> DesignsResponse:
    """The preset designs, each usable as the ``design`` of any request."""
    return presets()
