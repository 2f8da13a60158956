"""Service settings, read from environment variables prefixed ``PLANNER_``."""

from __future__ import annotations

from functools import lru_cache

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict


class Settings(BaseSettings):
    """Settings of one service process (environment variables ``PLANNER_<NAME>``)."""

    model_config = SettingsConfigDict(env_prefix="PLANNER_", extra="ignore")

    host: str = Field("127.0.0.1", description="Interface to bind.")
    port: int = Field(8000, ge=1, le=65535, description="TCP port.")


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The process's settings, read once (inject with ``Depends(get_settings)``)."""
    return Settings()
