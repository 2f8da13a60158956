"""Builds the FastAPI application: wiring only, the routes live in ``api.routes``."""

from __future__ import annotations

from fastapi import FastAPI

import planner
from api.routes import design, meta
from api.settings import Settings, get_settings


def create_app(settings: Settings | None = None) -> FastAPI:
    """The service, configured by ``settings`` (default: from the environment)."""
    settings = settings or get_settings()
    app = FastAPI(
        title="hybrid-planner",
        version=planner.__version__,
        description="Motion planning, timing and design analysis for the 3-DOF hybrid "
        "manipulator (five-bar A-C-P-D-B turning about AB).",
    )
    app.state.settings = settings
    app.include_router(meta.router)
    app.include_router(design.router)
    return app
