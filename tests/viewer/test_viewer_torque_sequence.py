"""The viewer's torques and sequences in a real browser (helpers: ``viewer_browser.py``), one
page for the module: torque limits typed into the form go out as ``limits.torque``; the
answer's ``tau`` is what the ``torque-plot`` draws, with the lines +-limit, and the header
shows the answer's ``diagnostics.max_torque_ratio``. A sequence (``sequence-mode``) goes to
``POST /v1/sequence``; the ``sequence-list`` lists its legs and highlights the one the
timeline is in, and the header shows the answer's ``cycle_time``. Every test checks that the page logged no console error,
that no request failed and that none left the service's origin."""

from __future__ import annotations

import json
import re
from collections.abc import Iterator

import numpy as np
import pytest
from viewer_browser import open_viewer, plan, shots_dir, watched_page

TORQUE = [40.0, 30.0, 20.0]


@pytest.fixture(scope="module")
def page_(browser, live_server) -> Iterator[object]:
    with watched_page(live_server, browser, viewport={"width": 1400, "height": 900}) as pg:
        yield pg


@pytest.fixture
def page(page_, live_server):
    page_.watch.reset()
    open_viewer(page_, live_server)
    return page_


def torque_plot(page) -> dict | None:
    return page.evaluate("async () => (await import('/viewer/plots.js')).torqueData()")


def test_torque_limits_are_sent_and_the_answers_torques_plotted(page, tmp_path):
    from playwright.sync_api import expect

    for k, lim in enumerate(TORQUE):
        page.locator(f"input[name='limits.torque.{k}']").fill(str(lim))
    with page.expect_request(lambda r: r.url.endswith("/v1/plan")) as sent:
        answer = plan(page)
    assert json.loads(sent.value.post_data)["limits"]["torque"] == TORQUE
    assert answer["status"] == "solved", answer["message"]
    tau = np.asarray(answer["trajectory"]["tau"])
    ratio = answer["diagnostics"]["max_torque_ratio"]
    # the oracle: the answer's own tau against the limits sent (the service's ratio is over its
    # denser re-check grid, so at least the samples' and close to it)
    sampled = float(np.max(np.abs(tau) / TORQUE))
    assert sampled - 1e-12 <= ratio <= 1.0
    assert ratio == pytest.approx(sampled, rel=0.02)
    drawn = torque_plot(page)
    assert drawn is not None
    assert drawn["t"] == answer["trajectory"]["t"]
    assert drawn["tau"] == answer["trajectory"]["tau"]
    lines = sorted((ln["joint"], ln["value"]) for ln in drawn["lines"])
    assert lines == sorted([(k, s * v) for k, v in enumerate(TORQUE) for s in (1, -1)])
    plot = page.get_by_test_id("torque-plot")
    expect(plot).to_have_attribute("data-lines", "6")
    expect(plot.locator("canvas")).to_have_count(1)
    assert plot.locator(".u-legend").inner_text().count("limit") == 6
    shown = page.get_by_test_id("torque-ratio")
    expect(shown).to_be_visible()
    assert float(shown.get_attribute("data-value")) == ratio
    assert shown.inner_text() == f"{ratio:.4f}"
    page.screenshot(path=shots_dir(tmp_path) / "torques.png", full_page=True)
    page.watch.check()


def test_without_torque_limits_no_lines_and_no_ratio(page):
    from playwright.sync_api import expect

    answer = plan(page)
    assert answer["status"] == "solved", answer["message"]
    assert answer["diagnostics"].get("max_torque_ratio") is None
    drawn = torque_plot(page)
    tau = answer["trajectory"].get("tau")
    if tau is None:  # no design.inertia and no limits.torque: nothing to plot
        assert drawn is None
        expect(page.get_by_test_id("torque-plot").locator("canvas")).to_have_count(0)
    else:
        assert drawn["tau"] == tau and drawn["lines"] == []
    expect(page.locator("#torque-ratio-wrap")).to_be_hidden()
    page.watch.check()


def test_a_sequence_lists_its_legs_and_highlights_the_current_one(page, tmp_path):
    from playwright.sync_api import expect

    page.locator("#example").select_option(label="Sequence: pick and place (cycle)")
    expect(page.get_by_test_id("sequence-mode")).to_be_checked()
    with page.expect_request(lambda r: r.url.endswith("/v1/sequence")) as sent:
        answer = plan(page, "/v1/sequence")
    body = json.loads(sent.value.post_data)
    assert body["cycle"] is True
    assert [t["goal"]["p"] for t in body["targets"]] == [
        [0.35, -0.1, -0.4],
        [0.35, 0.2, -0.4],
        [0.35, 0.2, -0.45],
    ]
    assert [t["stop"] for t in body["targets"]] == [False, False, True]
    assert [t.get("blend") for t in body["targets"]] == [0.04, 0.04, None]
    assert answer["status"] == "solved", answer["message"]
    page.locator("#copy-curl").click()  # the export follows the goal kind
    curl = page.get_by_test_id("export-text").input_value()
    assert curl.split(" \\\n")[0].endswith("/v1/sequence")
    assert json.loads(re.search(r"-d '(.*)'$", curl, re.DOTALL).group(1)) == body
    legs = answer["legs"]
    assert [leg["target_index"] for leg in legs] == [0, 1, 2, 3]  # the return: index 3
    cycle = page.get_by_test_id("cycle-time")
    expect(cycle).to_be_visible()
    assert float(cycle.get_attribute("data-value")) == answer["cycle_time"]
    assert answer["cycle_time"] == answer["trajectory"]["t"][-1]
    rows = page.get_by_test_id("sequence-list").locator("tbody tr")
    expect(rows).to_have_count(len(legs))
    for k, leg in enumerate(legs):
        cells = rows.nth(k).locator("td").all_inner_texts()
        assert cells[1].startswith(f"{leg['target_index']}:")
        assert cells[3] == leg["working_mode"]
        assert cells[4] == f"{leg['start_time']:.2f}–{leg['end_time']:.2f}"
    t = answer["trajectory"]["t"]
    for k in (1, 2):  # a sample strictly inside leg k, set on the timeline
        leg = legs[k]
        i = next(j for j, tj in enumerate(t) if leg["start_time"] < tj < leg["end_time"])
        page.get_by_test_id("timeline").fill(str(i))
        expect(rows.nth(k)).to_have_class(re.compile(r"\bcurrent\b"))
        assert page.locator(".sequence-list tr.current").count() == 1
        assert page.get_by_test_id("sequence-list").get_attribute("data-current") == str(k)
    page.screenshot(path=shots_dir(tmp_path) / "sequence.png", full_page=True)
    page.watch.check()


def test_sequence_targets_are_read_and_checked_as_typed(page):
    from playwright.sync_api import expect

    page.get_by_test_id("sequence-mode").check()
    box = page.locator("textarea[name='targets']")
    box.fill("q 0.1 2 1 pass\n0.3 0.1 abc")
    error = page.locator("[data-testid=field-error][data-loc='targets']")
    expect(error).to_contain_text("line 2: three numbers")
    box.fill("q 0.1 2 1 pass\n0.3 0.1 -0.5 stop")
    expect(error).to_have_count(0)
    body = page.evaluate("async () => (await import('/viewer/form.js')).request()")
    assert body["targets"] == [
        {"goal": {"q": [0.1, 2, 1], "assembly_mode": "+"}, "stop": False},
        {"goal": {"p": [0.3, 0.1, -0.5], "working_mode": "any"}, "stop": True},
    ]
    assert body["cycle"] is False and "goal" not in body
    page.watch.check()


def test_payload_and_gravity_fields_go_out_and_set_the_torques_drawn(page, live_server):
    """design.inertia.payload.mass and gravity off, as typed; the torques drawn are those of
    the service's inverse dynamics (POST /v1/dynamics, a second route) for that request's
    design and gravity along the answer's own motion."""
    import httpx
    from playwright.sync_api import expect

    for k, lim in enumerate(TORQUE):
        page.locator(f"input[name='limits.torque.{k}']").fill(str(lim))
    page.locator("input[name='design.inertia.payload.mass']").fill("2")
    page.get_by_test_id("gravity").uncheck()
    with page.expect_request(lambda r: r.url.endswith("/v1/plan")) as sent:
        answer = plan(page)
    body = json.loads(sent.value.post_data)
    assert body["design"]["inertia"] == {"payload": {"mass": 2}}
    assert body["gravity"] == [0, 0, 0]
    assert answer["status"] == "solved", answer["message"]
    tr = answer["trajectory"]
    oracle = httpx.post(
        f"{live_server}/v1/dynamics",
        json={
            "design": body["design"],
            "gravity": [0, 0, 0],
            "assembly_mode": "+",
            "q": tr["q"],
            "qd": tr["qd"],
            "qdd": tr["qdd"],
        },
        timeout=60,
    ).json()
    drawn = torque_plot(page)
    assert np.allclose(drawn["tau"], oracle["tau"], rtol=1e-9, atol=1e-9)
    # the same motion with gravity and the default payload needs other torques
    other = httpx.post(
        f"{live_server}/v1/dynamics",
        json={
            "design": {k: v for k, v in body["design"].items() if k != "inertia"},
            "q": tr["q"],
            "qd": tr["qd"],
            "qdd": tr["qdd"],
        },
        timeout=60,
    ).json()
    assert not np.allclose(other["tau"], oracle["tau"], atol=1e-3)
    # a negative mass is said as typed, in the service's words
    page.locator("input[name='design.inertia.payload.mass']").fill("-1")
    error = page.locator("[data-testid=field-error][data-loc='design.inertia.payload.mass']")
    expect(error).to_contain_text("Input should be greater than or equal to 0")
    page.watch.check()
