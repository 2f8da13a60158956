"""Helpers of the viewer's browser tests: Debian's chromium driven by Playwright against a real
service process (the ``live_server`` fixture), what a page logged and requested, the page's
ready states, pixel counts of its canvases.

Without chromium (``/usr/bin/chromium``, or ``PLANNER_CHROMIUM``) or the ``playwright``
package the tests are skipped, except in CI (``CI=true``), where they fail: CI installs
chromium (``.ci/run``). Screenshots go to the test's temporary folder, or to
``PLANNER_VIEWER_SHOTS`` when that names a folder.
"""

from __future__ import annotations

import io
import os
import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = Path(os.environ.get("PLANNER_CHROMIUM", "/usr/bin/chromium"))
ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
#: Generous waits (ms): a plan takes well under a second, a cold worker a few.
WAIT_MS = 30_000
STATUS_PENDING = re.compile(r"^(not planned|planning…)$")


def _unavailable(reason: str) -> None:
    if os.environ.get("CI") == "true":
        pytest.fail(f"{reason}: CI must run the browser tests (.ci/run installs chromium)")
    pytest.skip(reason)


@contextmanager
def launch() -> Iterator[object]:
    """One headless chromium (skips the test without one)."""
    if not CHROMIUM.exists():
        _unavailable(f"no chromium at {CHROMIUM} (apt-get install chromium)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:  # pragma: no cover - the test extra installs it
        _unavailable("the playwright package is not installed (pip install -e '.[test]')")
    from playwright.sync_api import expect

    expect.set_options(timeout=WAIT_MS)
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            yield b
        finally:
            b.close()


@contextmanager
def watched_page(url: str, browser, **context: object) -> Iterator[object]:
    """One page on the service at ``url`` for a module's tests: on the session's ``browser``
    (the session fixture ``browser`` of tests/conftest.py), one context with the ``context`` options (viewport,
    downloads), the suite's wait, and a :class:`Watch` of its console and requests as
    ``page.watch``."""
    ctx = browser.new_context(**context)
    pg = ctx.new_page()
    pg.set_default_timeout(WAIT_MS)
    pg.watch = Watch(pg, url)
    try:
        yield pg
    finally:
        ctx.close()


class Watch:
    """What a page logged and requested (``reset()`` between tests on one page)."""

    def __init__(self, page, origin: str) -> None:
        self.origin = origin
        self.reset()
        page.on("console", lambda m: self.errors.append(m.text) if m.type == "error" else None)
        page.on("pageerror", lambda e: self.errors.append(f"page error: {e}"))
        page.on("requestfailed", self._failed)
        page.on("request", self._request)

    def reset(self) -> None:
        self.errors: list[str] = []
        self.failed: list[str] = []
        self.foreign: list[str] = []
        self.posted: list[str] = []
        self.started: set[object] = set()
        self.left: set[object] = set()

    def leaving(self) -> None:
        """The page is about to be navigated away (``page.goto``): the requests it started so
        far (e.g. the analysis of an earlier design, still in flight though its answer is no
        longer wanted) are cut by the browser, which is no failure of the page."""
        self.left |= self.started

    def _failed(self, request) -> None:
        if request in self.left and request.failure == "net::ERR_ABORTED":
            return
        self.failed.append(f"{request.url}: {request.failure}")

    def _request(self, request) -> None:
        self.started.add(request)
        url = request.url
        if request.method == "POST":
            self.posted.append(url.removeprefix(self.origin))
        if not (
            url.startswith((self.origin + "/", f"blob:{self.origin}/")) or url.startswith("data:")
        ):
            self.foreign.append(url)

    def check(self, allowed_errors: re.Pattern[str] | None = None) -> None:
        errors = [e for e in self.errors if not (allowed_errors and allowed_errors.search(e))]
        assert errors == [], errors
        assert self.failed == [], self.failed
        assert self.foreign == [], self.foreign


def shots_dir(tmp_path: Path) -> Path:
    """Where screenshots go: ``PLANNER_VIEWER_SHOTS`` if set, else the test's folder."""
    folder = os.environ.get("PLANNER_VIEWER_SHOTS")
    out = Path(folder) if folder else tmp_path
    out.mkdir(parents=True, exist_ok=True)
    return out


def open_viewer(page, url: str) -> None:
    """The page as a new user first sees it, ready (its presets, schema checks, workspace
    section and region map arrived): loaded, or, when it is already open, started over with
    its own "start over" button (every field as first loaded; no reload, so the analysis of
    the default design is not asked for again)."""
    from playwright.sync_api import expect

    if page.url.startswith(url + "/") and page.locator("#start-over").count():
        page.locator("#start-over").click()
    else:
        page.goto(url + "/")
    expect(page.locator("#preset")).to_have_value("default")
    expect(page.locator("#request-form")).to_have_attribute("data-checks", "loaded")
    expect(page.locator("#section-box")).to_have_attribute("data-state", "loaded")
    expect(page.locator("#regions-box")).to_have_attribute("data-state", "loaded")


def plan(page, endpoint: str = "/v1/plan") -> dict:
    """Click Plan; the service's answer, once the page shows its status."""
    from playwright.sync_api import expect

    with page.expect_response(lambda r: r.url.endswith(endpoint)) as answer:
        page.get_by_test_id("plan-button").click()
    expect(page.get_by_test_id("status")).not_to_have_text(STATUS_PENDING)
    return answer.value.json()


def rgb_of(page, selector: str) -> np.ndarray:
    """An element's screenshot as an array (H, W, 3) of floats."""
    from PIL import Image

    image = Image.open(io.BytesIO(page.locator(selector).screenshot())).convert("RGB")
    return np.asarray(image, dtype=float)


def pixels(page, selector: str, like) -> int:
    """How many pixels of an element's screenshot have a colour ``like(r, g, b)``."""
    rgb = rgb_of(page, selector)
    return int(np.count_nonzero(like(rgb[..., 0], rgb[..., 1], rgb[..., 2])))


def orange(r, g, b):  # links CP, DP (#ff7f0e, shaded)
    return (r > 150) & (g > 40) & (g < 150) & (b < 60) & (r > 1.6 * g)


def blue(r, g, b):  # legs AC, BD (#1f77b4, shaded)
    return (b > 100) & (r < 70) & (g > 60) & (g < 150) & (b > 1.3 * g)
