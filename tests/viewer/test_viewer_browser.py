"""The viewer at ``GET /`` in a real browser: Debian's chromium driven by Playwright against a
real service process (the ``live_server`` fixture).

Every test also checks that the page logged no console error, that no request failed and
that no request left the service's own origin (the page works offline). The helpers (the
browser, what a page logged, the ready states) are in ``viewer_browser.py``; the second
round's rows (examples, CSV, loading states, typed checks, exports, narrow windows, straight
paths, the region map) are tested in ``test_viewer_page.py``.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from viewer_browser import Watch, blue, open_viewer, orange, pixels, plan

VIEWPORT = {"width": 1600, "height": 1000}


@pytest.fixture(scope="module")
def module_page(browser, live_server):
    """One page for the module's tests on the ``live_server`` (each test loads it again)."""
    context = browser.new_context(viewport=VIEWPORT, accept_downloads=True)
    pg = context.new_page()
    pg.set_default_timeout(30_000)
    pg.watch = Watch(pg, live_server)
    yield pg
    context.close()


@pytest.fixture
def page(module_page):
    module_page.watch.reset()
    return module_page


def test_default_request_solves_and_animates(page, live_server, tmp_path):
    from playwright.sync_api import expect

    open_viewer(page, live_server)
    answer = plan(page)
    assert answer["status"] == "solved", answer["message"]
    expect(page.get_by_test_id("status")).to_have_text("solved")
    # the default request holds one obstacle, drawn in the scene
    assert len(answer["path"]["waypoints"]) >= 2
    # the animation plays on its own: the timeline advances
    timeline = page.get_by_test_id("timeline")
    expect(timeline).not_to_have_value("0")
    expect(page.get_by_test_id("mode")).to_have_text(answer["path"]["segments"][0]["working_mode"])
    # the page's kinematics (C, D, P from q) agree with the service's P of every sample
    assert float(page.get_by_test_id("scene").get_attribute("data-fk-error")) < 1e-9
    # the plots are drawn (uPlot canvases) and the scene shows the legs and links
    expect(page.get_by_test_id("kappa-plot").locator("canvas")).to_have_count(2)
    expect(page.get_by_test_id("joint-plot").locator("canvas")).to_have_count(3)
    assert pixels(page, "[data-testid=scene]", orange) > 200
    assert pixels(page, "[data-testid=scene]", blue) > 100
    # scrubbing: the last sample is the goal posture
    timeline.fill(timeline.get_attribute("max"))
    expect(page.locator("#time")).to_have_text(f"{answer['trajectory']['duration']:.2f}")
    # download JSON: the request and the answer as planned
    with page.expect_download() as download:
        page.locator("#download-json").click()
    saved = json.loads(Path(download.value.path()).read_text())
    assert saved["response"] == answer
    assert [o["type"] for o in saved["request"]["obstacles"]] == ["sphere"]
    with page.expect_download() as download:
        page.locator("#download-csv").click()
    rows = Path(download.value.path()).read_text().splitlines()
    assert (
        rows[1].startswith("t,theta1,theta2,theta3")
        and len(rows) == len(answer["trajectory"]["t"]) + 2
    )
    page.screenshot(path=tmp_path / "viewer_default.png", full_page=True)
    page.watch.check()


def test_mode_change_plan_shows_its_transits(page, live_server, tmp_path):
    from playwright.sync_api import expect

    open_viewer(page, live_server)
    page.locator("#example").select_option(label="Mode change: +-+ to ++- (two transits)")
    answer = plan(page)
    assert answer["status"] == "solved", answer["message"]
    kinds = [t["kind"] for t in answer["path"]["transits"]]
    modes = [s["working_mode"] for s in answer["path"]["segments"]]
    assert len(kinds) == 2 and modes[0] != modes[-1]
    # marked on the timeline with their kind, listed with the modes they join
    expect(page.get_by_test_id("transit-mark")).to_have_text(kinds)
    expect(page.get_by_test_id("transits").locator("li")).to_have_count(2)
    expect(page.get_by_test_id("transits").locator("li").first).to_contain_text(
        f"{modes[0]} → {modes[1]}"
    )
    # the working mode shown follows the time: first mode at the start, last at the end
    timeline = page.get_by_test_id("timeline")
    page.locator("#play").click()  # pause
    timeline.fill("0")
    expect(page.get_by_test_id("mode")).to_have_text(modes[0])
    timeline.fill(timeline.get_attribute("max"))
    expect(page.get_by_test_id("mode")).to_have_text(modes[-1])
    # between the transits, the middle mode; then the picture for the README
    page.get_by_test_id("transits").locator("li").first.click()
    middle = int(timeline.input_value()) + 25
    timeline.fill(str(middle))
    expect(page.get_by_test_id("mode")).to_have_text(modes[1])
    page.screenshot(path=tmp_path / "viewer_mode_change.png", full_page=True)
    page.watch.check()


def test_bad_fields_show_their_messages_next_to_them(page, live_server, tmp_path):
    from playwright.sync_api import expect

    open_viewer(page, live_server)
    page.locator("input[name='planner.time_budget_s']").fill("1000")
    page.locator("[data-key=radius]").fill("-0.1")
    answer = plan(page)
    locs = {tuple(d["loc"]) for d in answer["detail"]}
    assert ("body", "planner", "time_budget_s") in locs
    expect(page.get_by_test_id("status")).to_have_text("invalid request")
    budget = page.locator(".field[data-loc='planner.time_budget_s'] [data-testid=field-error]")
    expect(budget).to_contain_text("less than or equal to 600")
    radius = page.locator(".field[data-loc='obstacles.0.radius'] [data-testid=field-error]")
    expect(radius).to_contain_text("greater than 0")
    expect(page.locator("input[name='planner.time_budget_s']")).to_have_attribute(
        "aria-invalid", "true"
    )
    page.screenshot(path=tmp_path / "viewer_bad_fields.png", full_page=True)
    # a corrected request plans, and the messages go away
    page.locator("input[name='planner.time_budget_s']").fill("1")
    page.locator("[data-key=radius]").fill("0.06")
    assert plan(page)["status"] == "solved"
    expect(page.get_by_test_id("field-error")).to_have_count(0)
    # a goal out of reach: a non-solved status with its message, in plain words
    page.locator("input[name=goal-kind][value=p]").check()
    for i, x in enumerate(("3", "0", "0")):
        page.locator(f"input[name='goal.p.{i}']").fill(x)
    answer = plan(page)
    assert answer["status"] == "unreachable"
    expect(page.get_by_test_id("status")).to_have_text("unreachable")
    expect(page.get_by_test_id("message")).to_have_text(answer["message"])
    assert answer["message"]
    # and the solved plan before it is off the screen
    expect(page.get_by_test_id("kappa-plot").locator("canvas")).to_have_count(0)
    expect(page.get_by_test_id("timeline")).to_be_disabled()
    # the browser logs each 422 answer as a failed resource load: expected here, nothing else
    page.watch.check(allowed_errors=re.compile(r"status of 422"))


def test_copied_curl_and_python_call_are_the_request(page, live_server):
    open_viewer(page, live_server)
    with page.expect_request(lambda r: r.url.endswith("/v1/plan")) as sent:
        page.get_by_test_id("plan-button").click()
    body = sent.value.post_data_json
    page.locator("#copy-curl").click()
    curl = page.get_by_test_id("export-text").input_value()
    assert curl.startswith(f"curl -sS -X POST {live_server}/v1/plan")
    payload = re.search(r"-d '(.*)'$", curl, re.DOTALL).group(1)
    assert json.loads(payload) == body
    page.locator("#copy-python").click()
    script = page.get_by_test_id("export-text").input_value()
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=False
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("solved"), out.stdout
    page.watch.check()


KEY = "viewer-test-key"


@pytest.fixture(scope="module")
def keyed_server(serve_factory, tmp_path_factory) -> Iterator[str]:
    """A service that requires an API key (one worker)."""
    log = tmp_path_factory.mktemp("keyed_server") / "server.log"
    with serve_factory(log, PLANNER_API_KEY=KEY, PLANNER_WORKERS="1") as url:
        yield url


def test_api_key_typed_into_the_page_is_sent(browser, keyed_server):
    from playwright.sync_api import expect

    context = browser.new_context(viewport=VIEWPORT)
    try:
        page = context.new_page()
        page.set_default_timeout(30_000)
        watch = Watch(page, keyed_server)
        keys: dict[str, str | None] = {}
        page.on("request", lambda r: keys.setdefault(r.url, r.headers.get("x-api-key")))
        page.goto(keyed_server + "/")  # the page itself needs no key
        expect(page.get_by_test_id("message")).to_contain_text("API key")
        page.locator("#api-key").fill(KEY)
        page.locator("#api-key").press("Tab")  # "change"
        expect(page.locator("#preset")).to_have_value("default")
        answer = plan(page)
        assert answer["status"] == "solved", answer["message"]
        api_calls = {u: k for u, k in keys.items() if "/v1/" in u}
        assert f"{keyed_server}/v1/plan" in api_calls
        assert api_calls[f"{keyed_server}/v1/plan"] == KEY
        # the copied command names the key's variable, never the key
        page.locator("#copy-curl").click()
        curl = page.get_by_test_id("export-text").input_value()
        assert "$PLANNER_API_KEY" in curl and KEY not in curl
        # before the key was typed, the service refused the page's calls (401): nothing else
        watch.check(allowed_errors=re.compile(r"status of 401"))
    finally:
        context.close()
