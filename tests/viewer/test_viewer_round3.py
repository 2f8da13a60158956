"""The viewer's third round in a real browser (helpers: ``viewer_browser.py``), one page for
the module, each test taking the steps a new user took and asserting what the eye
sees: a named scene's point cloud drawn (pixels), a leg's row seeking into that leg (the
highlighted row), a header that follows the form (its text), the region map's labels clear
of each other and of the start's marker, a torque plot with ticks to read and signed limits
(its tick count, its legend), panels that fit their column with no gap at 800, 1100 and
1440 px, and the blends of a sequence (``blend-list``). Every test checks that the page
logged no console error, that no request failed and that none left the service's origin."""

from __future__ import annotations

import json
import re
import uuid
from collections.abc import Iterator

import httpx
import numpy as np
import pytest
from viewer_browser import open_viewer, pixels, plan, rgb_of, shots_dir, watched_page

WIDE = {"width": 1440, "height": 900}
MIDDLE = {"width": 1100, "height": 800}
NARROW = {"width": 800, "height": 600}
SEQUENCE = "Sequence: pick and place (cycle)"
STRAIGHT = "Straight path: a square, then out of reach"
#: the torque limit of the report ("-limit = 12")
LIMIT = 12.0


@pytest.fixture(scope="module")
def page_(browser, live_server) -> Iterator[object]:
    with watched_page(live_server, browser, viewport=WIDE) as pg:
        yield pg


@pytest.fixture
def page(page_, live_server):
    page_.set_viewport_size(WIDE)
    page_.watch.reset()
    open_viewer(page_, live_server)
    return page_


def expect():
    from playwright.sync_api import expect as e

    return e


def pause(page) -> None:
    """Stop the animation a plan starts (the play button says "pause" while it plays)."""
    if "pause" in page.locator("#play").inner_text():
        page.locator("#play").click()
    expect()(page.locator("#play")).to_contain_text("play")


def pale_red(r, g, b):  # a named scene's obstacles: #d62728 paled towards white
    return (r > 180) & (g > 80) & (g < 200) & (b > 80) & (b < 200) & (r - g > 40)


def test_a_named_scenes_point_cloud_is_drawn(page, live_server, tmp_path):
    """Finding 1: a scene of 6,600 points chosen, then a plan: the points are on the canvas."""
    rng = np.random.default_rng(44)
    n = 6_600
    table = np.column_stack(
        [rng.uniform(0.2, 0.8, n), rng.uniform(-0.5, 0.5, n), np.full(n, -0.6)]
    ).tolist()
    name = f"table-{uuid.uuid4().hex[:8]}"
    cloud = {"type": "points", "points": table, "radius": 0.005}
    put = httpx.put(f"{live_server}/v1/scenes/{name}", json={"obstacles": [cloud]}, timeout=60)
    put.raise_for_status()
    page.evaluate("async () => (await import('/viewer/scenes.js')).refresh()")
    canvas = "[data-testid=scene]"
    before = pixels(page, canvas, pale_red)
    picker = page.get_by_test_id("scene-picker")
    picker.select_option(name)
    expect()(picker).to_have_attribute("data-state", "loaded")
    answer = plan(page)
    assert answer["status"] == "solved", answer["message"]
    pause(page)
    page.get_by_test_id("timeline").fill("0")  # the start posture, as before the plan
    expect()(page.get_by_test_id("scene")).to_have_attribute("data-rendered-points", str(n))
    page.wait_for_timeout(100)  # the frame after the seek
    after = pixels(page, canvas, pale_red)
    page.locator(canvas).screenshot(path=shots_dir(tmp_path) / "scene-cloud.png")
    assert after > before + 300, (before, after)  # ~550 pale pixels when drawn, 0 when not
    httpx.delete(f"{live_server}/v1/scenes/{name}", timeout=60)
    page.watch.check()


def test_a_legs_row_seeks_into_that_leg_at_800_px(page, tmp_path):
    """Finding 2, and the page usable at 800 x 600: a click on leg k's row shows a sample of
    leg k and highlights row k; nothing sticks out of the window."""
    page.set_viewport_size(NARROW)
    page.locator("#example").select_option(label=SEQUENCE)
    answer = plan(page, "/v1/sequence")
    assert answer["status"] == "solved", answer["message"]
    t = answer["trajectory"]["t"]
    table = page.get_by_test_id("sequence-list")
    rows = table.locator("tbody tr")
    legs = answer["legs"]
    assert any(leg["start_time"] not in t for leg in legs)  # a start between two samples
    for k, leg in enumerate(legs):
        rows.nth(k).click()
        expect()(table).to_have_attribute("data-current", str(k))
        expect()(rows.nth(k)).to_have_class(re.compile(r"\bcurrent\b"))
        assert page.locator(".sequence-list tr.current").count() == 1
        i = int(page.get_by_test_id("timeline").input_value())
        assert leg["start_time"] <= t[i] < leg["end_time"] or (k == len(legs) - 1)
        assert i == 0 or t[i - 1] < leg["start_time"]  # the leg's first sample
    assert page.evaluate("document.documentElement.scrollWidth") <= NARROW["width"]
    outside = page.evaluate(
        """(w) => [...document.querySelectorAll('body *')].filter((el) => {
             const r = el.getBoundingClientRect();
             return r.width > 0 && (r.left < -0.5 || r.right > w + 0.5)
               && !el.closest('.u-legend, canvas, .timeline-marks');
           }).map((el) => el.id || el.className || el.tagName)""",
        NARROW["width"],
    )
    assert outside == []
    for tid in ("plan-button", "sequence-list", "blend-list", "timeline", "regions-view"):
        box = page.get_by_test_id(tid).bounding_box()
        assert box and box["width"] > 0 and box["x"] + box["width"] <= NARROW["width"], tid
    page.screenshot(path=shots_dir(tmp_path) / "sequence-800.png", full_page=True)
    page.watch.check()


def header(page) -> str:
    return page.locator("header").inner_text()


def test_the_header_follows_the_goal_kind_and_the_preset(page, live_server):
    """Finding 3: what the header says of a plan goes when the form asks another question."""
    page.locator("#example").select_option(label=STRAIGHT)
    plan(page, "/v1/cartesian")
    expect()(page.get_by_test_id("fraction")).to_be_visible()
    assert "path achieved" in header(page)
    page.locator("input[name=goal-kind][value=q]").check()
    expect()(page.get_by_test_id("fraction")).to_be_hidden()
    expect()(page.get_by_test_id("status")).to_have_text("not planned")
    assert "path achieved" not in header(page)
    for k, x in enumerate([0.9, 1.7, 0.6]):  # the joint goal (the straight example has none)
        page.locator(f"input[name='goal.q.{k}']").fill(str(x))
    for k in range(3):
        page.locator(f"input[name='limits.torque.{k}']").fill(str(LIMIT))
    answer = plan(page)
    assert answer["status"] == "solved", answer["message"]
    expect()(page.get_by_test_id("torque-ratio")).to_be_visible()
    assert "max |τ| / limit" in header(page)
    other = next(
        p["name"]
        for p in httpx.get(f"{live_server}/v1/designs", timeout=60).json()["presets"]
        if p["name"] != "default"
    )
    page.locator("#preset").select_option(other)
    expect()(page.get_by_test_id("torque-ratio")).to_be_hidden()
    expect()(page.get_by_test_id("status")).to_have_text("not planned")
    assert "max |τ| / limit" not in header(page) and "solved" not in header(page)
    expect()(page.get_by_test_id("sequence-list")).to_be_hidden()
    page.watch.check()


def overlap(a: dict, b: dict) -> bool:
    return not (
        a["x"] + a["w"] <= b["x"]
        or b["x"] + b["w"] <= a["x"]
        or a["y"] + a["h"] <= b["y"]
        or b["y"] + b["h"] <= a["y"]
    )


def test_the_region_maps_labels_and_markers_stay_clear(page, tmp_path):
    """Finding 4: a cycle's start and goal both visible and named whole; no tick label
    overlaps another, every label inside the canvas."""
    page.locator("#example").select_option(label=SEQUENCE)
    answer = plan(page, "/v1/sequence")
    assert answer["status"] == "solved", answer["message"]
    canvas = page.get_by_test_id("regions-canvas")
    for viewport in (WIDE, NARROW):
        page.set_viewport_size(viewport)
        page.wait_for_timeout(300)  # the resize's redraw
        expect()(canvas).to_have_attribute("data-markers", re.compile("start"))
        labels = json.loads(canvas.get_attribute("data-labels"))
        markers = json.loads(canvas.get_attribute("data-markers"))
        w, h = canvas.evaluate("c => [c.clientWidth, c.clientHeight]")
        texts = [b["text"] for b in labels]
        assert "start = goal" in texts, texts  # a cycle ends where it began: one label
        for b in labels:
            assert b["x"] >= 0 and b["x"] + b["w"] <= w and b["y"] >= 0 and b["y"] + b["h"] <= h, b
        for i, a in enumerate(labels):
            for b in labels[i + 1 :]:
                assert not overlap(a, b), (a, b)
        # the start's dot is green on the screen (the goal's ring around it, not over it)
        rgb = rgb_of(page, "[data-testid=regions-canvas]")
        scale = rgb.shape[1] / w
        x, y = markers["start"]["x"] * scale, markers["start"]["y"] * scale
        r, g, b = rgb[round(y), round(x)]
        assert g > r + 40 and g > b + 40, (r, g, b)
        page.get_by_test_id("regions-view").screenshot(
            path=shots_dir(tmp_path) / f"regions-{viewport['width']}.png"
        )
    page.watch.check()


def test_the_torque_plot_has_ticks_and_signed_limits(page, tmp_path):
    """Finding 5: the torque plot of limits 12 N m reads on its own: several y ticks, the
    lower line named with its sign."""
    for k in range(3):
        page.locator(f"input[name='limits.torque.{k}']").fill(str(LIMIT))
    answer = plan(page)
    assert answer["status"] == "solved", answer["message"]
    drawn = page.evaluate("async () => (await import('/viewer/plots.js')).torqueData()")
    lo, hi = drawn["yRange"]
    assert lo <= -LIMIT and hi >= LIMIT  # both limit lines inside the plot
    ticks = [v for v in drawn["yTicks"] if lo <= v <= hi]
    assert len(ticks) >= 3, ticks
    assert 0 in ticks
    plot = page.get_by_test_id("torque-plot")
    expect()(plot).to_have_attribute("data-y-ticks", str(len(drawn["yTicks"])))
    legend = plot.locator(".u-legend").inner_text()
    for k in (1, 2, 3):
        assert f"limit τ{k} = -{LIMIT:g}" in legend and f"limit τ{k} = {LIMIT:g}" in legend
    plot.screenshot(path=shots_dir(tmp_path) / "torques.png")
    page.watch.check()


FITS = """() => {
  const out = [];
  const inside = (el, box) => {
    const a = el.getBoundingClientRect(), b = box.getBoundingClientRect();
    return a.left >= b.left - 0.5 && a.right <= b.right + 0.5;
  };
  const img = document.getElementById('iso-figure');
  const shown = img.getBoundingClientRect().width > 0;  // not when its box is closed
  if (shown && !inside(img, img.closest('.analysis'))) out.push('figure wider than its column');
  for (const el of document.querySelectorAll('.figure-box, .analysis, form, .view, .regions, .calibration')) {
    if (el.scrollWidth > el.clientWidth + 1) out.push(`${el.className || el.tagName} scrolls`);
  }
  for (const el of document.querySelectorAll('input[name^="design.joint_"]')) {
    if (el.scrollWidth > el.clientWidth) out.push(`${el.name} cuts its value`);
  }
  const select = document.getElementById('example');
  const ctx = document.createElement('canvas').getContext('2d');
  const cs = getComputedStyle(select);
  ctx.font = `${cs.fontWeight} ${cs.fontSize} ${cs.fontFamily}`;
  const room = select.clientWidth - parseFloat(cs.paddingLeft) - parseFloat(cs.paddingRight) - 16;
  for (const o of select.options) {
    if (ctx.measureText(o.text).width > room) out.push(`example "${o.text}" cut`);
  }
  return out;
}"""

GAPS = """() => {
  // the largest empty height between two panels that follow each other in one column
  const panels = [...document.querySelectorAll('main > *')]
    .filter((el) => el.getBoundingClientRect().height > 0)
    .map((el) => [el.className || el.tagName, el.getBoundingClientRect()]);
  let worst = [0, ''];
  for (const [name, a] of panels) {
    const below = panels.filter(([, b]) => b.top >= a.bottom - 1 && b.left < a.right - 1 && a.left < b.right - 1);
    if (!below.length) continue;
    const next = Math.min(...below.map(([, b]) => b.top));
    if (next - a.bottom > worst[0]) worst = [next - a.bottom, name];
  }
  return worst;
}"""


def test_every_panel_fits_its_column_without_gaps(page, live_server, tmp_path):
    """Finding 6: at 800, 1100 and 1440 px the service's figure, the joint limits and the
    examples fit; no horizontal scroll; the panels of a column follow each other with no gap
    (at 1100 px also after a preset change)."""
    page.locator("#iso-details summary").click()
    expect()(page.locator("#iso-box")).to_have_attribute("data-state", "loaded")
    for viewport in (WIDE, NARROW, MIDDLE):
        page.set_viewport_size(viewport)
        page.wait_for_timeout(300)  # the resize's layout
        assert page.evaluate("document.documentElement.scrollWidth") <= viewport["width"]
        assert page.evaluate(FITS) == [], viewport
        gap, where = page.evaluate(GAPS)
        assert gap <= 21, (viewport, gap, where)  # the grid's gap, twice at most
        page.screenshot(path=shots_dir(tmp_path) / f"page-{viewport['width']}.png", full_page=True)
    page.locator("#iso-details summary").click()  # closed: the preset's figure is not drawn
    presets = httpx.get(f"{live_server}/v1/designs", timeout=60).json()["presets"]
    page.locator("#preset").select_option(presets[-1]["name"])
    for box in ("#section-box", "#regions-box"):
        expect()(page.locator(box)).to_have_attribute("data-state", "loaded")
    page.wait_for_timeout(300)
    gap, where = page.evaluate(GAPS)
    assert gap <= 21, (gap, where)
    assert page.evaluate(FITS) == []
    page.watch.check()


def test_the_blend_list_shows_asked_and_used_blends_in_mm(page):
    """Issue 39's blends on the page: blend_radius typed in mm goes out in m; each passed
    target's blend is listed as asked and as used (mm), the shrunk ones marked."""
    page.locator("#example").select_option(label=SEQUENCE)
    page.get_by_test_id("blend-unit").select_option("mm")
    page.locator("textarea[name='targets']").fill(
        "0.35 -0.1 -0.4 pass 2\n0.35 0.2 -0.4 pass 1000\n0.35 0.2 -0.45"
    )
    with page.expect_request(lambda r: r.url.endswith("/v1/sequence")) as sent:
        answer = plan(page, "/v1/sequence")
    body = json.loads(sent.value.post_data)
    assert [t.get("blend_radius") for t in body["targets"]] == [0.002, 1.0, None]
    assert all("blend" not in t for t in body["targets"])
    assert answer["status"] == "solved", answer["message"]
    blends = answer["diagnostics"]["blends"]
    assert [b["target_index"] for b in blends] == [0, 1] and {b["unit"] for b in blends} == {"m"}
    assert blends[1]["used"] < blends[1]["asked"] == 1.0  # 1 m does not fit: shrunk
    box = page.get_by_test_id("blend-list")
    expect()(box).to_be_visible()
    rows = box.locator("tbody tr")
    expect()(rows).to_have_count(len(blends))
    for k, b in enumerate(blends):
        cells = rows.nth(k).locator("td").all_inner_texts()
        assert cells[0].startswith(f"{b['target_index']}:")
        assert cells[1] == f"{1000 * b['asked']:.2f} mm"
        assert cells[2].endswith(f"{1000 * b['used']:.2f} mm")
        shrunk = b["used"] < b["asked"]
        assert ("shrunk" in (rows.nth(k).get_attribute("class") or "")) == shrunk
        assert bool(cells[3]) == shrunk
    assert box.get_attribute("data-shrunk") == str(sum(b["used"] < b["asked"] for b in blends))
    # in rad, the form's one blend for every passed target goes out as `blend`
    page.get_by_test_id("blend-unit").select_option("rad")
    page.locator("textarea[name='targets']").fill("0.35 -0.1 -0.4 pass\n0.35 0.2 -0.45")
    page.locator("input[name='blend']").fill("0.03")
    body = page.evaluate("async () => (await import('/viewer/form.js')).request()")
    assert body["targets"][0]["blend"] == 0.03 and "blend_radius" not in body["targets"][0]
    page.watch.check()


def distance_to_polyline(p: np.ndarray, u: np.ndarray, w: np.ndarray) -> float:
    """The distance (m) from the point p (u, w) to a polyline with NaN between its pieces."""
    a = np.column_stack([u[:-1], w[:-1]])
    b = np.column_stack([u[1:], w[1:]])
    keep = np.all(np.isfinite(a), axis=1) & np.all(np.isfinite(b), axis=1)
    a, b = a[keep], b[keep]
    d = b - a
    s = np.clip(np.einsum("ij,ij->i", p - a, d) / np.einsum("ij,ij->i", d, d), 0.0, 1.0)
    return float(np.min(np.linalg.norm(a + s[:, None] * d - p, axis=1)))


def test_section_waypoints_stop_on_the_joint_limit_drawn(page, tmp_path):
    """Finding 7: waypoints clicked on the section across theta2 = +-pi. The section draws
    where theta2 and theta3 stand at their literal limits in the start's working mode, and the
    straight path stops on that line; the message writes the limit with the digits of the
    value (pi as 3.14159265, not 3.14159 beside a theta2 of 3.14159266)."""
    page.get_by_test_id("cartesian-mode").check()
    page.locator("#clear-waypoints").click()
    walls = page.evaluate("async () => (await import('/viewer/section.js')).wallsData()")
    assert walls and {w["joint"] for w in walls} <= {2, 3}
    box = page.locator("#section .u-over").bounding_box()
    for fx, fy in [(0.2, 0.3), (0.8, 0.7), (0.5, 0.9)]:
        page.mouse.click(box["x"] + fx * box["width"], box["y"] + fy * box["height"])
    assert len(page.locator("textarea[name=waypoints]").input_value().splitlines()) == 3
    answer = plan(page, "/v1/cartesian")
    stop = answer["stop"]
    assert stop["rule"] == "joint_limits", answer["message"]
    q0 = page.evaluate("async () => (await import('/viewer/form.js')).request().start.q[0]")
    p = np.asarray(stop["p"])
    uw = np.array([p[1], p[0] * np.cos(q0) - p[2] * np.sin(q0)])
    near = min(
        distance_to_polyline(uw, np.asarray(w["u"], float), np.asarray(w["w"], float))
        for w in walls
    )
    assert near < 2e-3, near  # the stop is on a wall the section drew
    m = re.search(
        r"theta(\d) = (-?[\d.]+) rad ([<>]) joint_(min|max)\[\d\] = (-?[\d.]+) rad",
        answer["message"],
    )
    assert m, answer["message"]
    value, bound = m.group(2), m.group(5)
    assert len(bound.lstrip("-")) >= len(value.lstrip("-")) - 1  # the same digits, or one less
    assert (float(value) > float(bound)) == (m.group(3) == ">")  # the numbers say the rule
    page.get_by_test_id("section").screenshot(path=shots_dir(tmp_path) / "section-walls.png")
    page.watch.check()
