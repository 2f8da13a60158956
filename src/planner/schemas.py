"""Pydantic models of the HTTP wire vocabulary (``CONVENTIONS.md``), shared by the service
and the client: the one definition of every field name on /v1."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict


class _Wire(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Health(_Wire):
    """Answer of ``GET /v1/health``."""

    status: Literal["ok"]


class VersionInfo(_Wire):
    """Answer of ``GET /v1/version``."""

    version: str
    libraries: dict[str, str]
