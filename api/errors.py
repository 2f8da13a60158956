"""Every error of the service mapped to an HTTP answer, in one place.

Every error body has FastAPI's shape, ``{"detail": [{"loc": [...], "msg": "...", "type":
"..."}]}`` (:class:`planner.wire.ErrorResponse`), whatever raised it:

=================================  ======  =====================================================
raised                             status  notes
=================================  ======  =====================================================
request validation (pydantic)      422     ``loc`` is the path of the field, e.g. body.design.L1
malformed or too deeply nested     422     ``loc`` = ["body"]
JSON body
LimitExceededError                 422     a setting's size limit (obstacles, batch size)
DesignError, InputError,           422     library errors; ``loc``: where the wire located the
KinematicsError, other PlannerError        error (:func:`planner.wire.located`), else the
                                           table's, followed by the error's own ``field``
AuthenticationError, or no key     401     ``WWW-Authenticate: Bearer`` (no key: answered by
                                           :mod:`planner_api.middleware` before the body is read)
body larger than max_body_bytes    413     (answered by :mod:`planner_api.middleware`)
body not sent within body_timeout  408     (answered by :mod:`planner_api.middleware`)
a POST body that is not JSON       415     (answered by :mod:`planner_api.middleware`)
an integer too long to read        422     ``number_too_long``
WorkerCrashedError                 502
JobCancelledError,                 499     never read: the client is gone (nginx's "client
ClientDisconnectedError                    closed request"; recorded in the metrics and log)
JobNotFoundError                   404     a long job's id unknown or expired
TooManyJobsError                   503     ``Retry-After``; the long-job list is full
TenantJobsError                    429     ``Retry-After``; ``too_many_jobs``: the tenant's
                                           PLANNER_JOBS_PER_TENANT unfinished jobs
StoreUnavailableError              503     ``Retry-After``; ``store_unavailable``: the scene
                                           store's lock wait or connection ran out of time
QuotaExceededError                 422     ``quota_exceeded``: PLANNER_SCENES_MAX (422) or
                                   or 413  PLANNER_SCENE_BYTES_MAX (413) of the tenant
ShuttingDownError                  503     ``Retry-After``; the process is stopping
PoolSaturatedError                 503     ``Retry-After``
PoolNotRunningError                503     the app's lifespan was not started
DeadlineExceededError,             504     the request's budget ran out (a job past its
planner DeadlineError                      deadline stops with DeadlineError, or is killed)
any other exception                500     logged with its traceback; never the answer to any
                                           input (the tests send bad inputs of every kind)
=================================  ======  =====================================================
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from planner.exceptions import (
    AssemblyError,
    DeadlineError,
    DesignError,
    InputError,
    KinematicsError,
    PlannerError,
    SingularPostureError,
)
from planner_api.exceptions import (
    AuthenticationError,
    ClientDisconnectedError,
    DeadlineExceededError,
    JobCancelledError,
    JobNotFoundError,
    LimitExceededError,
    PoolNotRunningError,
    PoolSaturatedError,
    QuotaExceededError,
    ShuttingDownError,
    StoreUnavailableError,
    TenantJobsError,
    TooManyJobsError,
    WorkerCrashedError,
)

__all__ = ["error_answer", "error_response", "install_error_handlers"]

logger = logging.getLogger(__name__)

#: Library errors: (HTTP status, error type, default loc). The most derived class wins.
_LIBRARY_ERRORS: dict[type[PlannerError], tuple[int, str, tuple[str | int, ...]]] = {
    DeadlineError: (504, "deadline_exceeded", ()),
    DesignError: (422, "design_error", ("body", "design")),
    InputError: (422, "input_error", ("body",)),
    AssemblyError: (422, "assembly_error", ("body", "q")),
    SingularPostureError: (422, "singular_posture", ("body",)),
    KinematicsError: (422, "kinematics_error", ("body",)),
    PlannerError: (422, "planner_error", ("body",)),
}

#: Service errors: (HTTP status, error type).
_SERVICE_ERRORS: dict[type[Exception], tuple[int, str]] = {
    AuthenticationError: (401, "unauthorized"),
    WorkerCrashedError: (502, "worker_crashed"),
    ClientDisconnectedError: (499, "client_disconnected"),  # before JobCancelledError
    JobCancelledError: (499, "job_cancelled"),
    JobNotFoundError: (404, "job_not_found"),
    TenantJobsError: (429, "too_many_jobs"),  # before its base class TooManyJobsError
    TooManyJobsError: (503, "too_many_jobs"),  # before PoolSaturatedError
    ShuttingDownError: (503, "shutting_down"),  # before its base class PoolSaturatedError
    PoolSaturatedError: (503, "saturated"),
    PoolNotRunningError: (503, "not_running"),
    StoreUnavailableError: (503, "store_unavailable"),
    DeadlineExceededError: (504, "deadline_exceeded"),
}


def error_response(
    status: int,
    msg: str,
    type_: str,
    loc: Sequence[str | int] = (),
    headers: dict[str, str] | None = None,
) -> JSONResponse:
    """A JSON error answer with one item in FastAPI's ``detail`` format."""
    item = {"loc": list(loc), "msg": msg, "type": type_}
    return JSONResponse({"detail": [item]}, status_code=status, headers=headers)


#: Tags of the wire's tagged unions that name no field: pydantic puts the member's tag in
#: ``loc`` after the union's field (``goal.p.p``); the field's own path is ``goal.p``.
_UNION_TAGS = {"goal": ("p", "q")}


def _clean_loc(loc: Sequence[Any]) -> list[str | int]:
    out: list[str | int] = []
    for i, x in enumerate(loc):
        if i > 0 and x in _UNION_TAGS.get(str(loc[i - 1]), ()) and i + 1 < len(loc):
            continue  # the union member's tag: the next element is the field itself
        out.append(x if isinstance(x, int) else str(x))
    return out


async def _validation(_: Request, exc: RequestValidationError) -> JSONResponse:
    # FastAPI's own handler echoes the input, which may hold NaN (not JSON) or megabytes.
    items = [
        {
            "loc": _clean_loc(e.get("loc", ())),
            "msg": str(e.get("msg", "")),
            "type": str(e.get("type", "value_error")),
        }
        for e in exc.errors()
    ]
    return JSONResponse({"detail": items}, status_code=422)


async def _http(request: Request, exc: StarletteHTTPException) -> JSONResponse:
    if exc.status_code == 400:  # FastAPI's "error parsing the body" (e.g. nesting too deep)
        cause = exc.__cause__
        if isinstance(cause, ValueError) and "integer string conversion" in str(cause):
            # valid JSON, but an integer longer than Python converts (sys.int_info)
            return error_response(
                422,
                f"a number in the body is too long to read ({str(cause).split(';')[0]})",
                "number_too_long",
                ("body",),
            )
        if isinstance(cause, RecursionError):
            return error_response(
                422, "the body is nested too deeply to read", "json_too_deep", ("body",)
            )
        return error_response(
            422, f"the body is not valid JSON: {exc.detail}", "json_invalid", ("body",)
        )
    headers = getattr(exc, "headers", None)
    if exc.status_code == 405 and request is not None:
        headers = dict(headers or {})
        headers["Allow"] = _allowed_methods(request, headers.get("Allow", ""))
    return error_response(exc.status_code, str(exc.detail), "http_error", (), headers=headers)


def _allowed_methods(request: Request, given: str) -> str:
    """Every method the OpenAPI document lists at this request's path template (Starlette's
    405 names only the first matching route's, e.g. GET of ``/v1/jobs/{id}`` without its
    DELETE); ``given`` when the path is not documented."""
    path = getattr(request.scope.get("route"), "path", None)
    operations = request.app.openapi().get("paths", {}).get(path, {}) if path else {}
    methods = sorted(m.upper() for m in operations if m in _HTTP_METHODS)
    return ", ".join(methods) if methods else given


_HTTP_METHODS = frozenset({"get", "put", "post", "delete", "options", "head", "patch", "trace"})


async def _library(_: Request, exc: PlannerError) -> JSONResponse:
    for cls in type(exc).__mro__:
        if cls in _LIBRARY_ERRORS:
            status, type_, loc = _LIBRARY_ERRORS[cls]
            break
    else:  # pragma: no cover - PlannerError is in the table
        status, type_, loc = 422, "planner_error", ("body",)
    located = getattr(exc, "loc", None)
    return error_response(status, str(exc), type_, located or (*loc, *exc.field_path))


async def _service(_: Request, exc: Exception) -> JSONResponse:
    if isinstance(exc, LimitExceededError):
        return error_response(422, exc.message, exc.error_type, exc.loc)
    if isinstance(exc, QuotaExceededError):
        return error_response(exc.status, exc.message, "quota_exceeded", exc.loc)
    status, type_ = next(v for k, v in _SERVICE_ERRORS.items() if isinstance(exc, k))
    headers = None
    if isinstance(exc, PoolSaturatedError | StoreUnavailableError):
        headers = {"Retry-After": str(exc.retry_after_s)}
    elif isinstance(exc, AuthenticationError):
        headers = {"WWW-Authenticate": "Bearer"}
    return error_response(status, str(exc), type_, (), headers=headers)


async def _unexpected(request: Request, exc: Exception) -> JSONResponse:
    logger.exception("unhandled error on %s %s", request.method, request.url.path, exc_info=exc)
    return error_response(500, "internal error (logged on the server)", "internal_error")


async def error_answer(exc: Exception) -> JSONResponse:
    """The answer a route raising ``exc`` gets, outside a request (a long job's error, kept
    for ``GET /v1/jobs/{id}``): the same table as the handlers."""
    if isinstance(exc, RequestValidationError):
        return await _validation(None, exc)  # type: ignore[arg-type]
    if isinstance(exc, PlannerError):
        return await _library(None, exc)  # type: ignore[arg-type]
    if isinstance(exc, LimitExceededError | QuotaExceededError) or any(
        isinstance(exc, k) for k in _SERVICE_ERRORS
    ):
        return await _service(None, exc)  # type: ignore[arg-type]
    logger.error("unhandled error in a long job", exc_info=exc)
    return error_response(500, "internal error (logged on the server)", "internal_error")


def install_error_handlers(app: FastAPI) -> None:
    """Register every handler of this module on ``app``."""
    app.add_exception_handler(RequestValidationError, _validation)  # type: ignore[arg-type]
    app.add_exception_handler(StarletteHTTPException, _http)  # type: ignore[arg-type]
    app.add_exception_handler(PlannerError, _library)  # type: ignore[arg-type]
    app.add_exception_handler(LimitExceededError, _service)
    app.add_exception_handler(QuotaExceededError, _service)
    for cls in _SERVICE_ERRORS:
        app.add_exception_handler(cls, _service)
    app.add_exception_handler(Exception, _unexpected)
