"""Liveness and version."""

from __future__ import annotations

from fastapi import APIRouter

import planner
from planner.schemas import Health, VersionInfo

router = APIRouter(prefix="/v1", tags=["meta"])


@router.get("/health", response_model=Health)
def health() -> Health:
    """Liveness: the process answers."""
    return Health(status="ok")


@router.get("/version", response_model=VersionInfo)
def version() -> VersionInfo:
    """Versions of the service and of the libraries that shape its answers."""
    from importlib.metadata import version as dist_version

    return VersionInfo(
        version=planner.__version__,
        libraries={name: dist_version(name) for name in ("ompl", "toppra", "ruckig", "numpy")},
    )
