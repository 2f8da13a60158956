"""Structured logs: one JSON object per line, each carrying the request id.

The request id comes from the client's ``X-Request-ID`` header when it is a sane token (at
most 128 characters of ``[A-Za-z0-9._:-]``), else a new UUID4 hex is made. The middleware of
:mod:`planner_api.metrics` sets it for the request (:data:`REQUEST_ID`, a context variable, so it
follows the request's task) and echoes it in the ``X-Request-ID`` response header; jobs sent
to the worker processes carry it along and set it there too, so a library log line written in
a worker names the request as well.

A line (``PLANNER_LOG_FORMAT=json``, the default)::

    {"ts": "2026-11-26T05:30:00.123Z", "level": "info", "logger": "api.access",
     "message": "POST /v1/plan 200", "request_id": "4f1c...", "pid": 7, "method": "POST",
     "route": "/v1/plan", "status": 200, "duration_ms": 4.1}

Fields passed with ``extra=`` (JSON-serialisable values) are added to the object;
``request_id`` is null for lines outside any request (start-up, shutdown).
``PLANNER_LOG_FORMAT=text`` gives one human-readable line with the id in brackets.
"""

from __future__ import annotations

import json
import logging
import os
import re
import sys
import time
from contextvars import ContextVar
from typing import Any, Literal

__all__ = [
    "REQUEST_ID",
    "REQUEST_ID_HEADER",
    "JsonFormatter",
    "RequestIdFilter",
    "configure_logging",
    "new_request_id",
    "request_id_from",
    "uvicorn_log_config",
]

#: The id of the request being served (None outside a request).
REQUEST_ID: ContextVar[str | None] = ContextVar("request_id", default=None)
#: The header that carries the id, in and out.
REQUEST_ID_HEADER = "X-Request-ID"

LogFormat = Literal["json", "text"]

_VALID_ID = re.compile(r"[A-Za-z0-9._:\-]{1,128}")
#: Attributes every LogRecord has; anything else on a record came from ``extra=``.
_STANDARD = frozenset(
    vars(logging.LogRecord("", 0, "", 0, "", (), None)).keys()
    | {"message", "asctime", "request_id", "color_message", "taskName"}
)


def new_request_id() -> str:
    """A fresh request id (32 hex characters, 128 random bits: what ``uuid4().hex`` gives
    without building a UUID, which cost every request ~1.5 us more)."""
    return os.urandom(16).hex()


def request_id_from(header: str | bytes | None) -> str:
    """The client's id when it is a sane token, else a new one (never echo arbitrary bytes
    into logs and headers)."""
    if isinstance(header, bytes):
        header = header.decode("latin-1")
    if header is not None and _VALID_ID.fullmatch(header):
        return header
    return new_request_id()


class RequestIdFilter(logging.Filter):
    """Stamp ``record.request_id`` from :data:`REQUEST_ID` (a handler filter: every record
    that reaches the handler gets it, whichever logger wrote it)."""

    def filter(self, record: logging.LogRecord) -> bool:
        if getattr(record, "request_id", None) is None:
            record.request_id = REQUEST_ID.get()
        return True


def _jsonable(value: Any) -> Any:
    if isinstance(value, str | int | float | bool) or value is None:
        return value
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    return str(value)


class JsonFormatter(logging.Formatter):
    """One JSON object per record: ``ts`` (UTC, ISO 8601, ms), ``level``, ``logger``,
    ``message``, ``request_id``, ``pid``, the ``extra=`` fields, and ``exc_info`` as text."""

    def format(self, record: logging.LogRecord) -> str:
        ts = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(record.created))
        out: dict[str, Any] = {
            "ts": f"{ts}.{int(record.msecs):03d}Z",
            "level": record.levelname.lower(),
            "logger": record.name,
            "message": record.getMessage(),
            "request_id": getattr(record, "request_id", None),
            "pid": record.process,
        }
        for key, value in vars(record).items():
            if key not in _STANDARD and not key.startswith("_"):
                out[key] = _jsonable(value)
        if record.exc_info:
            out["exc_info"] = self.formatException(record.exc_info)
        if record.stack_info:
            out["stack_info"] = self.formatStack(record.stack_info)
        return json.dumps(out, ensure_ascii=False)


_TEXT_FORMAT = "%(asctime)s %(levelname)s %(name)s [%(request_id)s] %(message)s"


def _formatter(log_format: LogFormat) -> logging.Formatter:
    if log_format == "json":
        return JsonFormatter()
    return logging.Formatter(_TEXT_FORMAT)


def configure_logging(level: str = "info", log_format: LogFormat = "json") -> None:
    """Send every log record of the process to stderr in ``log_format``, at ``level``.

    Replaces the root logger's handlers (idempotent); uvicorn's loggers propagate to the root
    so that their lines share the format and the request id. Called by :func:`planner_api.server.run`
    and by each worker process at start-up.
    """
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_formatter(log_format))
    handler.addFilter(RequestIdFilter())
    root = logging.getLogger()
    for old in list(root.handlers):
        root.removeHandler(old)
    root.addHandler(handler)
    root.setLevel(level.upper())
    for name in ("uvicorn", "uvicorn.error", "uvicorn.access"):
        lg = logging.getLogger(name)
        lg.handlers.clear()
        lg.propagate = True
    # Python warnings (numpy's, matplotlib's ...) become log records of ``py.warnings``, so
    # that every line of the log has the log's format (a JSON log stays parseable)
    logging.captureWarnings(True)


def uvicorn_log_config(level: str = "info", log_format: LogFormat = "json") -> dict[str, Any]:
    """A ``logging.config.dictConfig`` for ``uvicorn.run(log_config=...)`` that sets up the
    same handler as :func:`configure_logging` (uvicorn applies its log config itself)."""
    formatter: dict[str, Any] = (
        {"()": "planner_api.logging.JsonFormatter"}
        if log_format == "json"
        else {"format": _TEXT_FORMAT}
    )
    return {
        "version": 1,
        "disable_existing_loggers": False,
        "filters": {"request_id": {"()": "planner_api.logging.RequestIdFilter"}},
        "formatters": {"default": formatter},
        "handlers": {
            "default": {
                "class": "logging.StreamHandler",
                "stream": "ext://sys.stderr",
                "formatter": "default",
                "filters": ["request_id"],
            }
        },
        "root": {"handlers": ["default"], "level": level.upper()},
        "loggers": {
            name: {"handlers": [], "propagate": True}
            for name in ("uvicorn", "uvicorn.error", "uvicorn.access")
        },
    }
