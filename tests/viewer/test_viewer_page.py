"""The viewer's second round in a real browser (helpers: ``viewer_browser.py``), one page for
the module: every example sets every field it implies, one CSV format (the library's
writer's, byte for byte), loading states, fields checked as typed in the service's words,
exports that follow the form, no horizontal overflow from 800 px up with the whole arm in
the 3-D canvas, straight tool paths (``cartesian-mode``) and the region map
(``regions-view``). Every test checks that the page logged no console error, that no
request failed and that none left the service's origin."""

from __future__ import annotations

import io
import json
import re
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest
from viewer_browser import (
    blue,
    open_viewer,
    orange,
    plan,
    rgb_of,
    shots_dir,
    watched_page,
)

from planner.timing.export import read_csv, write_csv

WIDE = {"width": 1400, "height": 900}
NARROW = {"width": 800, "height": 900}
README_POINT = ["0.3", "0.1", "-0.5"]
#: A design whose joint limits cut the region map of assembly mode '-' in two, and a start and
#: a goal on either side (tests/planning_factories.py: CUT and cut_ends(128)).
CUT_DESIGN = {"L0": 0.3, "L1": 0.3, "L2": 0.4, "link_radius": 0.02}
CUT_MIN, CUT_MAX = [-3.14, -0.49, -2.81], [3.14, 0.51, -1.72]
CUT_START, CUT_GOAL = [0.3, 0.13890625, -2.4395703125], [0.3, 0.20921875, -1.7923828125]


@pytest.fixture(scope="module")
def page_(browser, live_server) -> Iterator[object]:
    with watched_page(live_server, browser, viewport=WIDE, accept_downloads=True) as pg:
        yield pg


@pytest.fixture
def page(page_, live_server):
    """The module's page, at 1400 x 900, as a new user first sees it, ready."""
    page_.set_viewport_size(WIDE)
    page_.watch.reset()
    open_viewer(page_, live_server)
    return page_


def expect():
    from playwright.sync_api import expect as e

    return e


def field_error(page, loc: str):
    return page.locator(f"[data-testid=field-error][data-loc='{loc}']")


# ---------------------------------------------------------------------------- examples
def test_an_example_sets_every_field_so_the_readme_point_plans(page, live_server):
    e = expect()
    page.locator("input[name='design.L1']").fill("0.25")  # a design the examples do not use
    page.locator("#example").select_option(label="Mode change: +-+ to ++- (two transits)")
    e(page.locator("select[name='goal.working_mode']")).to_have_value("++-")
    page.locator("#example").select_option(label="Around a sphere (default)")
    # the example's design is the default again, and the hidden Cartesian fields are its
    # goal's: P of the goal posture, any working mode
    e(page.locator("#preset")).to_have_value("default")
    e(page.locator("select[name='goal.working_mode']")).to_have_value("any")
    page.locator("input[name=goal-kind][value=p]").check()
    for i, x in enumerate(README_POINT):
        page.locator(f"input[name='goal.p.{i}']").fill(x)
    with page.expect_request(lambda r: r.url.endswith("/v1/plan")) as sent:
        answer = plan(page)
    body = sent.value.post_data_json
    assert body["goal"] == {"p": [0.3, 0.1, -0.5], "working_mode": "any"}
    assert body["design"]["L1"] == 0.2
    assert answer["status"] == "solved", answer["message"]
    # the point is the README's: the service answers the same for the README's request
    readme = httpx.post(
        f"{live_server}/v1/plan",
        json={"start": body["start"], "goal": body["goal"]},
        timeout=60,
    ).json()
    assert readme["status"] == "solved"
    page.watch.check()


# ---------------------------------------------------------------------------- CSV
def _library_csv(trajectory: dict) -> str:
    buf = io.StringIO()
    jerk = trajectory.get("jerk")
    write_csv(buf, trajectory["t"], trajectory["q"], trajectory["qd"], trajectory["qdd"], jerk=jerk)
    return buf.getvalue()


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_the_csv_download_is_the_library_writers_format(page, method):
    page.locator("select[name='timing.method']").select_option(method)
    answer = plan(page)
    assert answer["status"] == "solved", answer["message"]
    assert (answer["trajectory"].get("jerk") is not None) == (method == "ruckig")
    with page.expect_download() as download:
        page.locator("#download-csv").click()
    text = Path(download.value.path()).read_text()
    # byte for byte the library's writer (units line, theta names, 17 significant digits)
    assert text == _library_csv(answer["trajectory"])
    assert text.startswith("# units") and text.splitlines()[1].startswith("t,theta1,")
    back = read_csv(io.StringIO(text))
    np.testing.assert_array_equal(back.q, np.asarray(answer["trajectory"]["q"]))
    page.watch.check()


#: Numbers whose 17-digit forms take every branch of Python's "g" format: zero and its sign,
#: the exponent's thresholds (1e-4, 1e16, 1e17), rounding up to a new power of ten, the
#: smallest and largest floats.
AWKWARD = [
    0.0,
    -0.0,
    0.1,
    -1 / 3,
    1e-4,
    9.99999999999999e-5,
    1e-5,
    1.5e-300,
    5e-324,
    1e16,
    1e17,
    123456789012345678.0,
    0.99999999999999999,
    2.0**-30,
    1.7976931348623157e308,
    -2.5,
    100.0,
    6.02214076e23,
]


def test_the_pages_number_format_is_pythons(page):
    got = page.evaluate(
        "async (xs) => { const m = await import('/viewer/export.js'); return xs.map(m.g17); }",
        AWKWARD,
    )
    assert got == [f"{x:.17g}" for x in AWKWARD]


# ---------------------------------------------------------------------------- loading states
class Held:
    """Requests to the given paths kept waiting until ``release()``."""

    def __init__(self, page, *paths: str) -> None:
        self.page, self.routes, self.paths = page, [], paths
        for p in paths:
            page.route(f"**{p}", lambda route: self.routes.append(route))

    def release(self) -> None:
        for r in self.routes:
            r.continue_()
        for p in self.paths:
            self.page.unroute(f"**{p}")


def test_panels_show_that_they_load_then_a_figure_drawn_for_their_size(page, live_server):
    e = expect()
    # on load: both analysis panels say they are loading until their answers arrive
    held = Held(page, "/v1/workspace", "/v1/design/regions")
    page.watch.leaving()
    page.goto(live_server + "/")
    e(page.get_by_test_id("section-loading")).to_be_visible()
    e(page.locator("#regions-box .loading")).to_be_visible()
    held.release()
    e(page.locator("#section-box")).to_have_attribute("data-state", "loaded")
    e(page.get_by_test_id("section-loading")).to_be_hidden()
    # a preset: the old design's section is dimmed under the notice at once
    held = Held(page, "/v1/workspace")
    page.locator("#preset").select_option("paper-optimum")
    e(page.get_by_test_id("section-loading")).to_be_visible()
    opacity = page.locator("#section").evaluate("el => getComputedStyle(el).opacity")
    assert float(opacity) < 0.5
    held.release()
    e(page.locator("#section-box")).to_have_attribute("data-state", "loaded")
    # the page's own map, drawn for the box it is shown in (not a picture scaled down)
    size = page.locator("#section canvas").first.evaluate(
        "c => [c.width, c.getBoundingClientRect().width, devicePixelRatio,"
        " c.parentElement.closest('#section').clientWidth]"
    )
    width, shown, dpr, box = size
    assert abs(shown - box) <= 2 and abs(width - shown * dpr) <= 2
    # its text is the page's: the band legend in HTML, at the page's font size
    e(page.locator("#kappa-bands span")).to_have_count(7)
    # the service's figure, when asked for: a loading sign, then shown fitted to its column
    # (its own size when that fits), its own size a click away
    page.locator("#iso-details summary").click()
    e(page.locator("#iso-box")).to_have_attribute("data-state", "loaded")
    natural, displayed, column = page.locator("#iso-figure").evaluate(
        "i => [i.naturalWidth, i.offsetWidth, i.closest('.figure-box').clientWidth]"
    )
    assert natural > 0 and abs(displayed - min(natural, column)) <= 2  # its border
    src = page.locator("#iso-figure").get_attribute("src")
    e(page.locator("#iso-open")).to_have_attribute("href", src)
    e(page.locator("#iso-figure")).to_have_attribute("alt", re.compile(r"L0 = 0\b"))
    page.watch.check()


# ---------------------------------------------------------------------------- typed checks
def test_fields_are_checked_as_typed_in_the_services_words(page, live_server):
    e = expect()
    posted = len(page.watch.posted)
    page.locator("input[name='design.L1']").fill("-0.1")
    error = field_error(page, "design.L1")
    e(error).to_have_count(1)
    assert not any(p == "/v1/plan" for p in page.watch.posted[posted:])  # before any Plan
    # the same words as the service's own 422 for that value
    service = httpx.post(
        f"{live_server}/v1/plan",
        json={
            "design": {"L1": -0.1},
            "start": {"q": [0, 2, 1], "assembly_mode": "+"},
            "goal": {"q": [0, 2, 1], "assembly_mode": "+"},
        },
        timeout=60,
    ).json()
    (msg,) = [d["msg"] for d in service["detail"] if d["loc"][-1] == "L1"]
    e(error).to_have_text(f"design.L1: {msg}")
    e(page.locator("input[name='design.L1']")).to_have_attribute("aria-invalid", "true")
    # readable: on one or two lines across the form's width, not a word per line
    box = error.bounding_box()
    line = float(error.evaluate("el => parseFloat(getComputedStyle(el).lineHeight)"))
    assert box["width"] > 250 and box["height"] <= 2.2 * line, (box, line)
    # fixed as typed: the message goes
    page.locator("input[name='design.L1']").fill("0.2")
    e(error).to_have_count(0)
    e(page.locator("input[name='design.L1']")).not_to_have_attribute("aria-invalid", "true")
    # a service message after Plan is readable too (the budget's bound)
    page.locator("input[name='planner.time_budget_s']").fill("1000")
    plan(page)
    budget = field_error(page, "planner.time_budget_s")
    e(budget).to_contain_text("less than or equal to 600")
    assert budget.bounding_box()["width"] > 250
    page.watch.check(allowed_errors=re.compile(r"status of 422"))


# ---------------------------------------------------------------------------- exports
def test_the_export_box_follows_the_current_request(page):
    e = expect()
    page.locator("#copy-curl").click()
    area = page.get_by_test_id("export-text")

    def body() -> dict:
        return json.loads(re.search(r"-d '(.*)'$", area.input_value(), re.DOTALL).group(1))

    assert body()["design"]["L1"] == 0.2
    page.locator("input[name='design.L1']").fill("0.25")
    e(area).to_have_value(re.compile(r'"L1":0\.25'))
    page.locator("#preset").select_option("paper-optimum")
    e(area).to_have_value(re.compile(r'"L0":0[,}]'))
    page.locator("#example").select_option(label="Mode change: +-+ to +++ (one transit)")
    e(area).to_have_value(re.compile(r'"working_mode":"\+\+\+"'))
    # what it says is what Plan sends
    with page.expect_request(lambda r: r.url.endswith("/v1/plan")) as sent:
        plan(page)
    assert body() == sent.value.post_data_json
    page.watch.check()


# ---------------------------------------------------------------------------- window sizes
def _arm_margin(page) -> int:
    """Least distance (px) from the arm's drawn pixels (legs and links) to the canvas edge."""
    rgb = rgb_of(page, "[data-testid=scene]")
    arm = orange(rgb[..., 0], rgb[..., 1], rgb[..., 2]) | blue(
        rgb[..., 0], rgb[..., 1], rgb[..., 2]
    )
    ys, xs = np.nonzero(arm)
    assert len(xs) > 100
    h, w = arm.shape
    return int(min(xs.min(), ys.min(), w - 1 - xs.max(), h - 1 - ys.max()))


@pytest.mark.parametrize("viewport", [NARROW, WIDE], ids=["800px", "1400px"])
def test_no_horizontal_overflow_and_the_whole_arm_in_view(page, live_server, viewport, tmp_path):
    e = expect()
    page.set_viewport_size(viewport)
    width = viewport["width"]
    page.locator("#example").select_option(label="Mode change: +-+ to ++- (two transits)")
    answer = plan(page)
    assert answer["status"] == "solved", answer["message"]
    page.locator("#play").click()  # pause
    page.get_by_test_id("timeline").fill("0")
    assert page.evaluate("document.documentElement.scrollWidth") <= width
    # every panel inside the window, the header across it
    for sel in ("header", "form", ".view", ".analysis", ".plots", ".regions"):
        box = page.locator(sel).bounding_box()
        assert box["x"] >= 0 and box["x"] + box["width"] <= width + 0.5, (sel, box)
    assert page.locator("header").bounding_box()["width"] >= width - 1
    # the arm is drawn whole, at every sample shown: start, a transit, the end
    timeline = page.get_by_test_id("timeline")
    for value in ("0", str(int(timeline.get_attribute("max")) // 2), timeline.get_attribute("max")):
        timeline.fill(value)
        assert _arm_margin(page) >= 3
    out = shots_dir(tmp_path)
    page.screenshot(path=out / f"viewer_{width}px.png", full_page=True)
    e(page.get_by_test_id("status")).to_have_text("solved")
    page.watch.check()


# ---------------------------------------------------------------------------- straight paths
def test_a_straight_tool_path_shows_its_fraction_and_the_rest(page, live_server, tmp_path):
    e = expect()
    page.locator("#example").select_option(label="Straight path: a square, then out of reach")
    e(page.get_by_test_id("cartesian-mode")).to_be_checked()
    with page.expect_request(lambda r: r.url.endswith("/v1/cartesian")) as sent:
        answer = plan(page, "/v1/cartesian")
    body = sent.value.post_data_json
    assert len(body["waypoints"]) == 4 and "goal" not in body
    assert answer["status"] == "no_path" and 0 < answer["fraction"] < 1
    e(page.get_by_test_id("fraction")).to_have_text(f"{100 * answer['fraction']:.1f} %")
    e(page.get_by_test_id("stop-rule")).to_contain_text(answer["stop"]["rule"])
    e(page.get_by_test_id("message")).to_have_text(answer["message"])
    # the achieved part is animated; the rest (stop point, then the waypoint not reached) dashed
    assert page.get_by_test_id("scene").get_attribute("data-rest") == "2"
    assert float(page.get_by_test_id("scene").get_attribute("data-fk-error")) < 1e-9
    page.screenshot(path=shots_dir(tmp_path) / "viewer_straight_path.png", full_page=True)
    # the reachable part alone: fraction 1, solved, no rest
    area = page.locator("textarea[name=waypoints]")
    area.fill("\n".join(area.input_value().splitlines()[:3]))
    answer = plan(page, "/v1/cartesian")
    assert answer["status"] == "solved" and answer["fraction"] == 1
    e(page.get_by_test_id("fraction")).to_have_text("100.0 %")
    e(page.get_by_test_id("stop-rule")).to_have_text("")
    assert page.get_by_test_id("scene").get_attribute("data-rest") == "0"
    # a bad waypoint line is flagged as typed
    area.fill("0.5 0.1\n0.5 0.1 -0.1")
    e(field_error(page, "waypoints")).to_contain_text("line 1: three numbers")
    page.watch.check()


def test_waypoints_are_picked_on_the_workspace_section(page, live_server):
    e = expect()
    page.watch.leaving()
    with page.expect_response(lambda r: r.url.endswith("/v1/workspace")) as ws:
        page.goto(live_server + "/")
    grid = ws.value.json()["cartesian_section"]
    e(page.locator("#section-box")).to_have_attribute("data-state", "loaded")
    page.get_by_test_id("cartesian-mode").check()
    page.locator("textarea[name=waypoints]").fill("")
    page.locator("input[name='start.q.0']").fill("0.4")  # the start's theta1: a turned plane
    over = page.locator("#section .u-over").bounding_box()
    (x0, x1), (y0, y1) = (grid["x"][0], grid["x"][-1]), (grid["y"][0], grid["y"][-1])
    u, w = 0.1, 0.5
    page.mouse.click(
        over["x"] + (u - x0) / (x1 - x0) * over["width"],
        over["y"] + (1 - (w - y0) / (y1 - y0)) * over["height"],
    )
    e(page.locator("textarea[name=waypoints]")).not_to_have_value("")
    p = [float(v) for v in page.locator("textarea[name=waypoints]").input_value().split()]
    t1 = 0.4  # P = (w cos t1, u, -w sin t1) (docs/conventions.md)
    cell = max((x1 - x0) / over["width"], (y1 - y0) / over["height"]) * 2
    np.testing.assert_allclose(p, [w * np.cos(t1), u, -w * np.sin(t1)], atol=cell)
    page.watch.check()


# ---------------------------------------------------------------------------- region map
def test_the_region_map_and_the_paths_trace(page, live_server, tmp_path):
    e = expect()
    view = page.get_by_test_id("regions-view")
    e(view).to_be_visible()
    with page.expect_response(lambda r: r.url.endswith("/v1/design/regions")) as got:
        page.locator("input[name='design.L2']").fill("0.55")
    rmap = got.value.json()
    e(page.locator("#regions-box")).to_have_attribute("data-state", "loaded")
    design = rmap["design"]
    n = rmap["resolution"]
    cells = np.asarray(rmap["cell_regions"])  # checked against the map: test_viewer_static.py
    lo, hi = np.asarray(design["joint_min"]), np.asarray(design["joint_max"])
    # the page lists the regions of the assembly mode shown, and the transits
    plus = [r for r in rmap["regions"] if r["assembly_mode"] == "+"]
    e(page.locator("#regions-list li")).to_have_count(len(plus))
    assert page.locator("#regions-transits li").count() >= 1
    # a plan: its trace on the map, its start in the region the map gives its cell
    page.locator("#example").select_option(label="Mode change: +-+ to ++- (two transits)")
    answer = plan(page)
    assert answer["status"] == "solved"
    start = answer["path"]["waypoints"][0]
    k2 = int((start[1] - lo[1]) / (hi[1] - lo[1]) * n)
    k3 = int((start[2] - lo[2]) / (hi[2] - lo[2]) * n)
    note = page.get_by_test_id("regions-note")
    e(note).to_have_attribute("data-start-region", str(cells[0, k3, k2]))
    rgb = rgb_of(page, "[data-testid=regions-canvas]")
    dark = (rgb.max(axis=-1) < 40).sum()  # the trace (#111) and the axis text
    page.locator("#regions-assembly").select_option("-")  # the trace is of mode '+'
    rgb_minus = rgb_of(page, "[data-testid=regions-canvas]")
    assert dark > (rgb_minus.max(axis=-1) < 40).sum() + 50
    page.screenshot(path=shots_dir(tmp_path) / "viewer_regions.png", full_page=True)
    page.watch.check()


def test_a_proven_infeasible_answer_shows_the_regions_apart(page, tmp_path):
    e = expect()
    for k, v in CUT_DESIGN.items():
        page.locator(f"input[name='design.{k}']").fill(str(v))
    for i in range(3):
        page.locator(f"input[name='design.joint_min.{i}']").fill(str(CUT_MIN[i]))
        page.locator(f"input[name='design.joint_max.{i}']").fill(str(CUT_MAX[i]))
        page.locator(f"input[name='start.q.{i}']").fill(str(CUT_START[i]))
        page.locator(f"input[name='goal.q.{i}']").fill(str(CUT_GOAL[i]))
    page.locator("select[name='start.assembly_mode']").select_option("-")
    page.locator("select[name='goal.assembly_mode']").select_option("-")
    page.locator("[data-remove='0']").click()  # no obstacle: the proof is the region map's
    e(page.locator("#regions-box")).to_have_attribute("data-state", "loaded")
    answer = plan(page)
    assert answer["status"] == "no_path" and answer["diagnostics"]["proven_infeasible"]
    note = page.get_by_test_id("regions-note")
    e(note).to_have_attribute("data-separated", "true")
    e(page.locator("#regions-assembly")).to_have_value("-")
    # the regions the page names are those of the service's proof
    start_id, goal_id = re.findall(r"lies in region (\d+)", answer["message"])
    e(note).to_contain_text(f"start is in region {start_id}")
    e(note).to_contain_text(f"goal in region {goal_id}")
    rgb = rgb_of(page, "[data-testid=regions-canvas]")
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    green = ((g > 100) & (r < 80) & (b < 80)).sum()  # the start's component
    red = ((r > 170) & (g < 70) & (b < 70)).sum()  # the goal's
    assert green > 200 and red > 200
    page.screenshot(path=shots_dir(tmp_path) / "viewer_proof.png", full_page=True)
    page.watch.check()
