"""The browser viewer's static files (``static/``), shipped inside the package.

The service serves ``static/index.html`` at ``GET /`` and the folder at ``/viewer/``
(:mod:`planner_api.routes.viewer`). Everything the page loads is in ``static/``: its own ES modules
and the vendored libraries (``static/vendor/README.md``), so the page works offline.
"""

from __future__ import annotations

import base64
import hashlib
import re
from functools import cache
from pathlib import Path

__all__ = ["STATIC_DIR", "content_security_policy", "index_html", "script_hashes"]

#: The folder of the page and its assets.
STATIC_DIR = Path(__file__).resolve().parent / "static"

_INLINE_SCRIPT = re.compile(r"<script\b[^>]*>(.*?)</script>", re.DOTALL)


def script_hashes(html: str) -> str:
    """The CSP source list (``'sha256-...'`` ...) allowing exactly the inline scripts of
    ``html``."""
    return " ".join(
        "'sha256-" + base64.b64encode(hashlib.sha256(body.encode()).digest()).decode() + "'"
        for body in _INLINE_SCRIPT.findall(html)
        if body.strip()
    )


@cache
def index_html() -> str:
    """The page's HTML."""
    return (STATIC_DIR / "index.html").read_text(encoding="utf-8")


@cache
def content_security_policy() -> str:
    """The page's Content-Security-Policy: everything from the page's own origin only.

    The one inline script is the import map (browsers cannot load an import map from a
    file), allowed by its SHA-256 hash, computed here from the HTML itself so the two cannot
    drift apart.
    """
    hashes = script_hashes(index_html())
    return "; ".join(
        [
            "default-src 'self'",
            f"script-src 'self' {hashes}".strip(),
            "style-src 'self'",
            "img-src 'self' data: blob:",
            "connect-src 'self'",
            "object-src 'none'",
            "base-uri 'none'",
            "form-action 'none'",
            "frame-ancestors 'none'",
        ]
    )
