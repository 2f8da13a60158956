"""Every answer of the service carries the security headers (no MIME sniffing, no referrer,
a Content-Security-Policy that no one may frame), HTML, scripts and styles included, not only
the viewer's page; the API documentation pages fetch nothing from outside the origin (Swagger
UI's validator badge is off) and run under their own policy.

The pages are served by an app whose workers are never asked for work (the headers are the
gate's, the pages static): no warm pool is waited for."""

from __future__ import annotations

import re

import pytest

PAGES = ["/", "/viewer/index.html", "/docs", "/redoc"]
ASSETS = [
    "/viewer/app.js",
    "/viewer/style.css",
    "/viewer/vendor/three/three.module.min.js",
    "/static/docs/swagger-ui-bundle.js",
    "/static/docs/swagger-ui.css",
    "/static/docs/redoc.standalone.js",
]
OTHERS = ["/openapi.json", "/v1/health", "/v1/no-such-route"]


@pytest.fixture(scope="module")
def cold(client_factory):
    with client_factory(wait_ready=False) as client:
        yield client


@pytest.mark.parametrize("url", PAGES + ASSETS + OTHERS)
def test_every_answer_has_the_security_headers(cold, url):
    r = cold.get(url)
    assert r.status_code in (200, 404), (url, r.status_code)
    assert r.headers["x-content-type-options"] == "nosniff"
    assert r.headers["referrer-policy"] == "no-referrer"
    policy = r.headers["content-security-policy"]
    assert "frame-ancestors 'none'" in policy, policy
    # the same for the browsers and proxies that read no policy, the pages' own included
    assert r.headers["x-frame-options"] == "DENY"


@pytest.mark.parametrize("url", ["/docs", "/redoc"])
def test_the_docs_pages_load_only_from_the_origin(cold, url):
    r = cold.get(url)
    html = r.text
    policy = r.headers["content-security-policy"]
    assert "default-src 'self'" in policy and "frame-ancestors 'none'" in policy
    # every src and href is a path of this origin, and no script names an outside host
    for ref in re.findall(r'(?:src|href|spec-url)="([^"]+)"', html):
        assert ref.startswith("/") and not ref.startswith("//"), ref
    for script in re.findall(r"<script>(.*?)</script>", html, re.S):
        assert not re.search(r"https?://|//[a-z]", script), script
        # the inline script is allowed by its hash, nothing else inline
        assert "'sha256-" in policy and "'unsafe-inline'" not in policy.split("style-src")[0]


def test_the_viewer_page_has_its_own_policy_at_both_urls(cold):
    """``/`` and ``/viewer/index.html`` are one page with one policy (its import map allowed
    by hash), not the load-nothing default that would break it."""
    a, b = cold.get("/"), cold.get("/viewer/index.html")
    assert a.text == b.text
    assert a.headers["content-security-policy"] == b.headers["content-security-policy"]
    assert "script-src 'self' 'sha256-" in a.headers["content-security-policy"]


def test_swagger_ui_asks_no_outside_validator(cold):
    assert '"validatorUrl": null' in cold.get("/docs").text


def test_the_docs_scripts_load_nothing_from_outside(cold):
    """Nothing the pages run asks for an outside resource, which their policy would block (a
    console violation on every visit): ReDoc's footer logo, from its makers' CDN, is removed
    from the vendored script (``api/static/docs/README.md``); its link stays a link."""
    for url in ["/static/docs/redoc.standalone.js", "/static/docs/swagger-ui-bundle.js"]:
        script = cold.get(url).text
        loads = re.findall(r"""(?:src|srcset|poster)\s*:\s*["'](?:https?:)?//[^"']+""", script)
        assert not loads, (url, loads)
        assert "cdn.redoc.ly" not in script, url
