"""The stream's live position (``stream-live``, docs/viewer.md, docs/execution.md "Streaming
setpoints") in a real browser (helpers: ``viewer_browser.py``), one page for the module: the
first example streamed over ``/v1/stream`` from the page's own host at 800 x 600, the readout's
time advancing on the page's clock and the drawn posture (its ``data-q``) moving, then ``done``
with the final q the example's goal (1e-6) at rest; at 1440 x 900 **Stop** mid-stream, the
service's ``switched`` shown and the stream done at rest short of the goal. Every test checks
that the page logged no console error, that no request failed and that none left the
service's origin."""

from __future__ import annotations

import json
from collections.abc import Iterator

import httpx
import numpy as np
import pytest
from viewer_browser import open_viewer, watched_page

WIDE = {"width": 1440, "height": 900}
NARROW = {"width": 800, "height": 600}
GOAL = [0.9, 1.7, 0.6]  # form.js's first example (the page's default)


@pytest.fixture(scope="module")
def page_(browser, live_server) -> Iterator[object]:
    with watched_page(live_server, browser, viewport=NARROW) as pg:
        yield pg


def _live(page) -> dict:
    box = page.get_by_test_id("stream-live")
    return {
        "t": float(box.get_attribute("data-t")),
        "q": json.loads(box.get_attribute("data-q")),
        "qd": json.loads(box.get_attribute("data-qd")),
        "chunks": int(box.get_attribute("data-chunks")),
    }


def _past(page, t: float) -> None:
    """Wait (polling: the page's policy forbids a string predicate) until the readout shows
    a time past ``t``."""
    box = page.get_by_test_id("stream-live")
    for _ in range(400):
        shown = box.get_attribute("data-t")
        if shown is not None and float(shown) > t:
            return
        page.wait_for_timeout(25)
    raise AssertionError(f"the readout never passed t = {t}: {shown}")


def _more_chunks(page, chunks: int) -> dict:
    """The readout once more than ``chunks`` chunks have come (polling, 10 s at most): the
    page acknowledges on its own clock and the service answers an acknowledgement with the
    next chunks, which on a loaded machine may come a while after the clock moved on."""
    for _ in range(400):
        live = _live(page)
        if live["chunks"] > chunks:
            return live
        page.wait_for_timeout(25)
    return live


def _start(page, live_server) -> list[dict]:
    """Press Stream; the messages the page sent (the start, then acks), as they come."""
    sent: list[dict] = []
    urls: list[str] = []

    def opened(ws) -> None:  # on the socket's creation, so its first frame is seen too
        urls.append(ws.url)
        ws.on("framesent", lambda payload: sent.append(json.loads(payload)))

    page.once("websocket", opened)
    page.get_by_test_id("stream-run").click()
    _past(page, -1.0)
    assert urls == [live_server.replace("http://", "ws://") + "/v1/stream"]
    return sent


def test_the_first_example_streams_live_to_its_goal(page_, live_server):
    page = page_
    page.watch.reset()
    open_viewer(page, live_server)
    sent = _start(page, live_server)
    first = _live(page)
    _past(page, first["t"] + 0.1)
    later = _more_chunks(page, first["chunks"])
    assert later["t"] > first["t"] and later["chunks"] > first["chunks"]
    assert np.max(np.abs(np.subtract(later["q"], first["q"]))) > 1e-3  # the robot moved
    box = page.get_by_test_id("stream-live")
    from playwright.sync_api import expect

    expect(box).to_have_attribute("data-state", "done", timeout=30_000)
    end = _live(page)
    np.testing.assert_allclose(end["q"], GOAL, atol=1e-6)
    assert end["qd"] == [0, 0, 0]
    assert "done" in page.get_by_test_id("stream-note").inner_text()
    start = sent[0]
    assert start["type"] == "plan" and start["request"]["goal"]["q"] == GOAL
    assert start["rate_hz"] == 250
    acks = [m["t"] for m in sent if m["type"] == "ack"]
    assert len(acks) > 3 and acks == sorted(acks)  # the page's clock, moving on
    page.watch.check()


def test_stop_mid_stream_is_acknowledged_and_ends_at_rest(page_, live_server):
    page = page_
    page.set_viewport_size(WIDE)
    page.watch.reset()
    open_viewer(page, live_server)
    # slow joints (0.1 rad/s: the example's motion takes ~12 s), so that Stop lands mid-
    # motion however slowly a loaded machine's browser clicks it (at 0.3 rad/s, ~4 s, a run
    # pinned to one core beside another process once clicked after the motion's end); the
    # test itself does not wait longer: the stream brakes at the stop
    for j in range(3):
        page.locator(f'input[name="limits.velocity.{j}"]').fill("0.1")
    sent = _start(page, live_server)
    request = sent[0]["request"]
    assert request["limits"]["velocity"] == [0.1, 0.1, 0.1]
    planned = httpx.post(f"{live_server}/v1/plan", json=request, timeout=60).json()
    duration = planned["trajectory"]["duration"]
    assert duration > 2.0
    _past(page, _live(page)["t"] + 0.05)  # early: the stop takes effect a lookahead later
    page.get_by_test_id("stream-stop").click()
    box = page.get_by_test_id("stream-live")
    from playwright.sync_api import expect

    expect(box).to_have_attribute("data-state", "done", timeout=30_000)
    end = _live(page)
    assert end["qd"] == [0, 0, 0]
    note = page.get_by_test_id("stream-note").inner_text()
    switched = float(box.get_attribute("data-switched"))
    assert switched < duration - 0.5  # spliced well before the motion's end
    assert end["t"] >= switched and "at rest" in note and "switched" in note
    assert {"type": "stop"} in sent
    assert np.max(np.abs(np.subtract(end["q"], GOAL))) > 1e-3  # stopped short of the goal
    page.watch.check()
