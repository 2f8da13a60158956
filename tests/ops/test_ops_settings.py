"""Operations settings: the documented table of docs/operations.md lists every field of the
Settings model with its default, the new settings are validated, and ``planner serve``
refuses a bad option by naming it."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from pydantic import ValidationError
from typer.testing import CliRunner

from planner_api.server import job_grace_s
from planner_api.settings import Settings
from planner_cli import app as cli

DOC = Path(__file__).resolve().parents[2] / "docs" / "operations.md"


def _doc_rows() -> dict[str, str]:
    rows = {}
    for line in DOC.read_text().splitlines():
        m = re.match(r"\| `PLANNER_([A-Z_]+)` \| ([^|]+) \|", line)
        if m:
            rows[m.group(1).lower()] = m.group(2).strip()
    return rows


def test_every_setting_is_documented_with_its_default():
    rows = _doc_rows()
    assert set(Settings.model_fields) <= set(rows), set(Settings.model_fields) - set(rows)
    for name, field in Settings.model_fields.items():
        default = field.default
        if field.default_factory is not None or default is None:
            continue  # computed defaults are described in words
        shown = (
            str(default).lower()
            if isinstance(default, bool)
            else f"{default:g}"
            if (isinstance(default, float))
            else str(default)
        )
        assert f"`{shown}`" in rows[name], (name, rows[name])


def test_operations_settings_from_environment(monkeypatch):
    monkeypatch.setenv("PLANNER_LOG_LEVEL", "warning")
    monkeypatch.setenv("PLANNER_LOG_FORMAT", "text")
    monkeypatch.setenv("PLANNER_SHUTDOWN_TIMEOUT_S", "12.5")
    monkeypatch.setenv("PLANNER_METRICS", "false")
    s = Settings()
    assert (s.log_level, s.log_format, s.shutdown_timeout_s, s.metrics) == (
        "warning",
        "text",
        12.5,
        False,
    )
    for name, bad in [
        ("LOG_LEVEL", "loud"),
        ("LOG_FORMAT", "xml"),
        ("SHUTDOWN_TIMEOUT_S", "-1"),
        ("SHUTDOWN_TIMEOUT_S", "inf"),
    ]:
        monkeypatch.setenv(f"PLANNER_{name}", bad)
        with pytest.raises(ValidationError, match=name.lower()):
            Settings()
        monkeypatch.delenv(f"PLANNER_{name}")


def test_job_grace_keeps_time_to_answer():
    assert job_grace_s(30.0) == 29.0  # 1 s kept (10 % capped at 1 s)
    assert job_grace_s(5.0) == 4.5
    assert job_grace_s(0.0) == 0.0


def test_serve_refuses_bad_options_by_name():
    result = CliRunner().invoke(cli, ["serve", "--log-format", "xml"])
    assert result.exit_code == 2
    assert "log_format" in result.output
    result = CliRunner().invoke(cli, ["serve", "--shutdown-timeout", "-3"])
    assert result.exit_code == 2


def test_the_cache_budget_stays_below_the_worker_memory_bound(monkeypatch):
    from planner.caching import DEFAULT_BUDGET_MB

    assert Settings().cache_mb == DEFAULT_BUDGET_MB < Settings().worker_max_rss_mb
    monkeypatch.setenv("PLANNER_CACHE_MB", "300")
    assert Settings().cache_mb == 300.0
    monkeypatch.setenv("PLANNER_WORKER_MAX_RSS_MB", "300")
    with pytest.raises(
        ValidationError, match=r"PLANNER_CACHE_MB \(300\) must be below PLANNER_WORKER_MAX_RSS_MB"
    ):
        Settings()
    monkeypatch.setenv("PLANNER_WORKER_MAX_RSS_MB", "0")  # never recycled: any budget
    assert Settings().cache_mb == 300.0
    monkeypatch.setenv("PLANNER_CACHE_MB", "-1")
    with pytest.raises(ValidationError, match="cache_mb"):
        Settings()
