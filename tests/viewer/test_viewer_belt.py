"""The belt view (``belt-view``, docs/conveyor.md) in a real browser (helpers:
``viewer_browser.py``), one page for the module, at 800 x 600 and 1440 x 900: the example "Pick
from a belt" planned, then what the eye sees. The belt and the part are on the view's canvas
(pixels of their colours) and in the 3-D scene; the part's drawn position moves with the
playback along the belt, at p + velocity (t - t0) (the request's own numbers, not the page's);
at the meeting time it is on the tool, at the answer's ``meet_point`` (within 1 mm) and on the
same pixel as P; after its dwell it is held at P, then at rest at the bin; nothing sticks out
of an 800 px window. Every test checks that the page
logged no console error, that no request failed and that none left the service's origin."""

from __future__ import annotations

import json
import re
from collections.abc import Iterator

import numpy as np
import pytest
from viewer_browser import open_viewer, pixels, plan, rgb_of, shots_dir, watched_page

WIDE = {"width": 1440, "height": 900}
NARROW = {"width": 800, "height": 600}
BELT = "Pick from a belt (0.5 m/s), place at a bin"


@pytest.fixture(scope="module")
def page_(browser, live_server) -> Iterator[object]:
    with watched_page(live_server, browser, viewport=WIDE) as pg:
        yield pg


def expect():
    from playwright.sync_api import expect as e

    return e


def amber(r, g, b):  # the belt, #f5b700
    return (r > 215) & (g > 150) & (g < 215) & (b < 60)


def magenta(r, g, b):  # the part, #c000c0
    return (r > 150) & (b > 150) & (g < 60) & (np.abs(r - b) < 40)


def shown_at(page, i: int) -> dict:
    """Seek the timeline to sample i; what the belt view then says it drew."""
    page.get_by_test_id("timeline").fill(str(i))
    view = page.get_by_test_id("belt-view")
    t = page.get_by_test_id("timeline").evaluate("(el) => el.value")
    assert t == str(i)
    return {
        "t": float(view.get_attribute("data-t")),
        "parts": json.loads(view.get_attribute("data-parts")),
        "tool": json.loads(view.get_attribute("data-tool")),
        "tool_px": json.loads(view.get_attribute("data-tool-px")),
    }


@pytest.mark.parametrize("viewport", [NARROW, WIDE], ids=["800", "1440"])
def test_the_belt_the_part_and_the_meeting_are_drawn(page_, live_server, viewport, tmp_path):
    page = page_
    page.set_viewport_size(viewport)
    page.watch.reset()
    open_viewer(page, live_server)
    page.locator("#example").select_option(label=BELT)
    expect()(page.get_by_test_id("field-error")).to_have_count(0)  # the belt line as typed is good
    with page.expect_request(lambda r: r.url.endswith("/v1/sequence")) as sent:
        answer = plan(page, "/v1/sequence")
    assert answer["status"] == "solved", answer["message"]
    if "pause" in page.locator("#play").inner_text():
        page.locator("#play").click()
    request = json.loads(sent.value.post_data)
    part = request["targets"][0]
    goal = part["goal"]
    assert goal["velocity"] == [0.5, 0, 0] and goal["t0"] == 0 and part["dwell"] == 0.1
    p0, v, t0 = np.array(goal["p"]), np.array(goal["velocity"]), goal["t0"]
    leg = answer["legs"][0]
    meet_t, meet_p = leg["meet_time"], np.array(leg["meet_point"])
    view = page.get_by_test_id("belt-view")
    expect()(view).to_be_visible()
    meets = json.loads(view.get_attribute("data-meets"))
    assert meets == [{"target": 0, "t": meet_t, "p": leg["meet_point"]}]
    t = np.array(answer["trajectory"]["t"])
    p = np.array(answer["trajectory"]["p"])

    # the part rides the belt: drawn where the request puts it, and moving as time goes on
    k_meet = int(np.searchsorted(t, meet_t - 1e-9))  # the first sample at or after the meeting
    assert t[k_meet] <= meet_t + part["dwell"]
    seen = []
    for i in (0, k_meet // 2, k_meet):
        s = shown_at(page, i)
        assert s["t"] == t[i]
        (drawn,) = s["parts"]
        assert drawn["where"] == "belt"
        np.testing.assert_allclose(drawn["p"], p0 + v * (t[i] - t0), atol=1e-9)
        np.testing.assert_allclose(s["tool"], p[i], atol=1e-12)
        seen.append(drawn["px"])
    px = np.array(seen)
    assert px[1, 0] - px[0, 0] > 10 and px[2, 0] - px[1, 0] > 10  # to the right, as x grows
    assert np.ptp(px[:, 1]) < 0.5  # along the belt's line

    # at the meeting: the part at the answer's meet_point, on the tool, on P's pixel
    s = shown_at(page, k_meet)
    (drawn,) = s["parts"]
    assert np.linalg.norm(np.array(drawn["p"]) - meet_p) < 1e-3
    assert np.linalg.norm(np.array(drawn["p"]) - p[k_meet]) < 1e-3
    assert np.hypot(*(np.array(drawn["px"]) - s["tool_px"])) < 1.0
    canvas = "[data-testid=belt-canvas]"
    page.wait_for_timeout(50)
    rgb = rgb_of(page, canvas)
    x, y = (round(c) for c in drawn["px"])
    # the part's square (12 px) shows around the tool's dot (7 px): magenta at its corner
    corner = rgb[y - 5, x - 5]
    assert magenta(*corner), corner
    assert pixels(page, canvas, amber) > 400  # the belt's band (10 px wide, ~180 px long)
    assert pixels(page, canvas, magenta) > 60  # the part's square less the dot over it
    page.screenshot(path=shots_dir(tmp_path) / f"belt-{viewport['width']}-meet.png", full_page=True)
    # after the dwell the part is in the gripper (at P), then at rest at the bin with the tool
    picked, placed = meet_t + part["dwell"], answer["legs"][1]["end_time"]
    k_held = int(np.searchsorted(t, (picked + placed) / 2))
    for i, where in ((k_held, "held"), (len(t) - 1, "placed")):
        (drawn,) = shown_at(page, i)["parts"]
        assert drawn["where"] == where
        np.testing.assert_allclose(drawn["p"], p[i], atol=1e-12)
    np.testing.assert_allclose(p[-1], request["targets"][1]["goal"]["p"], atol=1e-6)
    # in the 3-D scene, on its way to the meeting: the belt (a tube) and the part (a cube)
    shown_at(page, k_meet // 2)
    page.wait_for_timeout(50)  # the frame after the seek
    assert pixels(page, "[data-testid=scene]", amber) > 50
    assert pixels(page, "[data-testid=scene]", magenta) > 20
    page.screenshot(path=shots_dir(tmp_path) / f"belt-{viewport['width']}.png", full_page=True)
    assert page.evaluate("document.documentElement.scrollWidth") <= viewport["width"]
    box = view.bounding_box()
    assert box["x"] >= 0 and box["x"] + box["width"] <= viewport["width"]
    page.watch.check()


def test_a_belt_typed_badly_is_said_next_to_the_targets(page_, live_server):
    """A belt line with a word for a number: the typed check says so; a belt faster than the
    service's bound: its 422 (at targets.0.goal.velocity) next to the targets."""
    page = page_
    page.set_viewport_size(WIDE)
    page.watch.reset()
    open_viewer(page, live_server)
    page.locator("#example").select_option(label=BELT)
    targets = page.locator("textarea[name=targets]")
    errors = page.locator("[data-loc=targets] .field-error")
    targets.fill("-0.75 0 -0.45 belt 0.5 fast 0 dwell 0.1\n-0.2 0.25 -0.45")
    expect()(errors).to_have_text(["targets: line 1: belt vx vy vz: three numbers (m/s)"])
    targets.fill("-0.75 0 -0.45 belt 3 0 0 dwell 0.1\n-0.2 0.25 -0.45")
    expect()(errors).to_have_count(0)
    with page.expect_request(lambda r: r.url.endswith("/v1/sequence")) as sent:
        plan(page, "/v1/sequence")
    assert json.loads(sent.value.post_data)["targets"][0]["goal"]["velocity"] == [3, 0, 0]
    expect()(page.get_by_test_id("status")).to_have_text("invalid request")
    expect()(errors).to_have_count(1)
    assert errors.inner_text().startswith("targets.0.goal.velocity: ")
    expect()(page.get_by_test_id("belt-view")).to_be_hidden()
    page.watch.check(allowed_errors=re.compile(r"status of 422"))
