"""The OpenAPI document says everything a route can answer, and the offline API docs.

FastAPI documents the success answer and request validation (422) of each route; the answers
of the request gate (:mod:`planner_api.middleware`: 401 without the key, 408, 413, 415) and of the
worker pool (502, 503, 504) happen around the routes, so :func:`install_openapi` adds them:

- every ``/v1`` operation but the probes ``/v1/health`` and ``/v1/ready``: 400 (a Host not
  allowed) and 401 when a key is configured (and then the
  ``securitySchemes`` ``ApiKey``, header ``X-API-Key``, and ``Bearer``);
- every operation with a body: 408, 413, 415, 422;
- every operation that runs in a worker: 502, 503, 504; the others that can be refused
  while the service stops: 503.

Each operation's id is its route function's name (:func:`operation_id`: ``plan``,
``plan_batch``, ``sequence``, ...; FastAPI's default would be ``plan_v1_plan_post``), so a
generated client has readable methods; a route added later is named the same way, and
tests/service/test_openapi_client.py checks that every id is unique. A non-JSON answer
declared by its media type alone (the figures' PNG and SVG, the MJCF model's XML) gets its
schema (:func:`declare_media`): bytes for an image, a string for XML, so a
generated client returns the image instead of dropping the answer.

``/docs`` (Swagger UI) and ``/redoc`` (ReDoc) load their scripts from ``/static/docs``,
files shipped inside this package (``api/static/docs``, with their licences), never from a
CDN: the docs render on a machine with no internet.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from fastapi import FastAPI
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from fastapi.openapi.utils import get_openapi
from fastapi.responses import HTMLResponse
from fastapi.routing import APIRoute
from fastapi.staticfiles import StaticFiles

from planner.viewer import script_hashes

__all__ = [
    "STATIC_DOCS",
    "declare_media",
    "document_errors",
    "install_docs",
    "install_openapi",
    "limit_obstacles",
    "operation_id",
]

#: The vendored Swagger UI and ReDoc files.
STATIC_DOCS = Path(__file__).parent / "static" / "docs"
_ERROR = {"$ref": "#/components/schemas/ErrorResponse"}
_DESCRIPTIONS = {
    "400": "The Host header names no host the service answers (PLANNER_ALLOWED_HOSTS).",
    "401": "Missing or wrong API key (X-API-Key or Authorization: Bearer).",
    "408": "The request body did not arrive within the body timeout.",
    "413": "The request body is larger than the service's limit.",
    "415": "The request body is not JSON (Content-Type must be application/json).",
    "422": "Invalid input: each detail item's loc names the field.",
    "502": "The worker process running the job died (only this job fails).",
    "503": "Every worker busy and the queue full, or the service is stopping (Retry-After).",
    "504": "The request's time budget ran out before the work finished.",
}
#: Operations answered in the event loop, without a worker job.
_NO_JOB = frozenset({"/v1/health", "/v1/ready", "/v1/version", "/v1/designs"})


def operation_id(route: APIRoute) -> str:
    """The OpenAPI operation id of ``route``: its function's name (``plan``, ``plan_batch``,
    ``get_job``), what a generated client calls the method. Given to the app as its
    ``generate_unique_id_function``; route functions are named verb_noun and uniquely."""
    return route.name


def declare_media(schema: dict[str, Any]) -> dict[str, Any]:
    """Give every non-JSON answer declared by its media type alone a schema (in place): an
    image (``image/*``, SVG too: a file to save) or other binary type a binary string, text
    and XML a string."""
    for item in schema.get("paths", {}).values():
        for operation in item.values():
            for response in operation.get("responses", {}).values():
                for media, body in response.get("content", {}).items():
                    if media.endswith("json") or body.get("schema"):
                        continue
                    text = not media.startswith("image/") and (
                        media.startswith("text/") or media.endswith("xml")
                    )
                    body["schema"] = {"type": "string"} | ({} if text else {"format": "binary"})
    return schema


def _add(operation: dict[str, Any], *codes: str) -> None:
    responses = operation.setdefault("responses", {})
    for code in codes:
        if code not in responses:
            responses[code] = {
                "description": _DESCRIPTIONS[code],
                "content": {"application/json": {"schema": _ERROR}},
            }


def document_errors(schema: dict[str, Any], *, api_key: bool) -> dict[str, Any]:
    """Add the statuses of the gate and the pool to every operation of ``schema`` (in
    place), and the security schemes when ``api_key``."""
    for path, item in schema.get("paths", {}).items():
        if not path.startswith("/v1/"):
            continue
        for method, operation in item.items():
            if path in ("/v1/health", "/v1/ready"):  # probes: any host, no key, own 503
                continue
            _add(operation, "400")
            if api_key:
                _add(operation, "401")
                operation["security"] = [{"ApiKey": []}, {"Bearer": []}]
            if method in ("post", "put", "patch"):
                _add(operation, "408", "413", "415", "422")
            if path not in _NO_JOB:
                _add(operation, "502", "503", "504")
            else:
                _add(operation, "503")  # refused while the service stops
    if api_key:
        schema.setdefault("components", {})["securitySchemes"] = {
            "ApiKey": {"type": "apiKey", "in": "header", "name": "X-API-Key"},
            "Bearer": {"type": "http", "scheme": "bearer"},
        }
    return schema


def limit_obstacles(schema: dict[str, Any], max_obstacles: int) -> dict[str, Any]:
    """Every request schema's ``obstacles`` list (in place) says the service's own limit,
    ``PLANNER_MAX_OBSTACLES``, as its ``maxItems`` where that is below the wire's cap: the
    document then tells a client what this service refuses (issue 36: it said 10000 while
    the service refused 257)."""
    for model in schema.get("components", {}).get("schemas", {}).values():
        prop = model.get("properties", {}).get("obstacles")
        if isinstance(prop, dict) and "items" in prop:  # a list (pydantic writes no "type")
            prop["maxItems"] = min(prop.get("maxItems", max_obstacles), max_obstacles)
    return schema


def install_openapi(app: FastAPI, *, api_key: bool, max_obstacles: int | None = None) -> None:
    """Make ``app.openapi()`` return the document with :func:`document_errors` applied (and
    :func:`limit_obstacles` with the service's ``max_obstacles``)."""

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            schema = get_openapi(
                title=app.title,
                version=app.version,
                description=app.description,
                routes=app.routes,
            )
            schema = document_errors(declare_media(schema), api_key=api_key)
            if max_obstacles is not None:
                schema = limit_obstacles(schema, max_obstacles)
            app.openapi_schema = schema
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]


def install_docs(app: FastAPI) -> None:
    """Serve ``/docs`` and ``/redoc`` from the vendored assets (the app must be built with
    ``docs_url=None, redoc_url=None``)."""
    app.mount("/static/docs", StaticFiles(directory=STATIC_DOCS), name="static-docs")
    title = f"{app.title} API"

    @app.get("/docs", include_in_schema=False)
    def swagger() -> HTMLResponse:
        return _with_policy(
            get_swagger_ui_html(
                openapi_url="/openapi.json",
                title=title,
                swagger_js_url="/static/docs/swagger-ui-bundle.js",
                swagger_css_url="/static/docs/swagger-ui.css",
                swagger_favicon_url="/static/docs/favicon-32x32.png",
                # no badge: Swagger UI would send the schema to an outside validator
                swagger_ui_parameters={"validatorUrl": None},
            )
        )

    @app.get("/redoc", include_in_schema=False)
    def redoc() -> HTMLResponse:
        return _with_policy(
            get_redoc_html(
                openapi_url="/openapi.json",
                title=title,
                redoc_js_url="/static/docs/redoc.standalone.js",
                redoc_favicon_url="/static/docs/favicon-32x32.png",
                with_google_fonts=False,
            )
        )


def _with_policy(page: HTMLResponse) -> HTMLResponse:
    """A documentation page with its Content-Security-Policy: everything from this origin,
    its own inline script by hash, inline styles (Swagger UI and ReDoc style their elements
    from script), images as data URLs, ReDoc's worker from a blob; framed by no one."""
    html = bytes(page.body).decode()
    policy = "; ".join(
        [
            "default-src 'self'",
            f"script-src 'self' {script_hashes(html)}".strip(),
            "style-src 'self' 'unsafe-inline'",
            "img-src 'self' data:",
            "worker-src 'self' blob:",
            "connect-src 'self'",
            "object-src 'none'",
            "base-uri 'none'",
            "form-action 'none'",
            "frame-ancestors 'none'",
        ]
    )
    page.headers["Content-Security-Policy"] = policy
    return page
