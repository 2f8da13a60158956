"""GET / (the browser viewer's page) and the static files it loads, under /viewer/.

Not behind the API key: the page itself holds no data. Its calls to /v1 send the key that
the user types into the page's API-key field, when the service has one configured.
"""

from __future__ import annotations

from fastapi import APIRouter, FastAPI
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles

from planner.viewer import STATIC_DIR, content_security_policy, index_html

__all__ = ["install_viewer", "page", "router"]

router = APIRouter(tags=["viewer"])

#: Where the page's modules, styles and vendored libraries are served.
STATIC_PREFIX = "/viewer"


@router.get("/", response_class=HTMLResponse, include_in_schema=False)
@router.get(f"{STATIC_PREFIX}/index.html", response_class=HTMLResponse, include_in_schema=False)
def page() -> HTMLResponse:
    """The viewer: plan, animate and inspect a motion in the browser."""
    return HTMLResponse(
        index_html(),
        headers={
            "Content-Security-Policy": content_security_policy(),
            "X-Content-Type-Options": "nosniff",
            "Referrer-Policy": "no-referrer",
            "Cache-Control": "no-cache",
        },
    )


def install_viewer(app: FastAPI) -> None:
    """Serve the page at ``/`` and its files at ``/viewer/``."""
    app.include_router(router)
    app.mount(STATIC_PREFIX, StaticFiles(directory=STATIC_DIR), name="viewer")
