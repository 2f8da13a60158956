"""Point clouds, named scenes and a sequence's transits in the viewer, in a real browser
(helpers: ``viewer_browser.py``), one page for the module.

A cloud read from a file (``cloud-file``: x y z rows or a JSON obstacle) is one item of the
obstacle list with its count, goes out as ``{"type": "points", ...}`` exactly as the file
has it, and is drawn as one ``THREE.Points`` (the scene canvas's ``data-points``, and
``data-rendered-points``: three.js's count of the points drawn in the last frame); a 100,000-
point cloud is not rebuilt while the form is edited. Named scenes: the picker
(``scene-picker``) lists ``GET /v1/scenes``, "save as scene" PUTs the form's obstacles
(``scene-name``, checked as typed by the service's pattern), a chosen scene is drawn and
named by the plan's ``scene``; the service's refusals are shown next to the field in its
words. A sequence through a change of working mode has its legs' transits on the timeline.
The service's scene store is a temporary file (``PLANNER_SCENE_STORE``, set by
tests/conftest.py). Every test checks that the page logged no console error, that no
request failed and that none left the service's origin."""

from __future__ import annotations

import json
import os
import re
import tempfile
import uuid
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest
from viewer_browser import open_viewer, pixels, plan, shots_dir, watched_page

WIDE = {"width": 1400, "height": 900}
NARROW = {"width": 800, "height": 900}
#: the start of the examples, and the goal point of "Mode change: +-+ to ++-"
START = [0.0, 2.0, 1.0]
MODE_CHANGE_P = [-0.25, 0.07, -0.38]


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


def scene_name() -> str:
    """A name of this test run (the live server's store is shared by the session's tests)."""
    return f"viewer-{uuid.uuid4().hex[:12]}"


def xyz_file(points: np.ndarray, name: str = "cloud.xyz") -> dict:
    """A depth camera's export: a comment, a header, x,y,z and an intensity column."""
    rows = [f"{x!r},{y!r},{z!r},0.5" for x, y, z in points.tolist()]
    text = "# exported by a depth camera\nx,y,z,intensity\n" + "\n".join(rows) + "\n"
    return {"name": name, "mimeType": "text/plain", "buffer": text.encode()}


def reds(r, g, b):  # obstacles (#d62728, lit or flat)
    return (r > 150) & (g < 90) & (b < 90) & (r > 2 * g)


def drawn_points(page) -> tuple[int, int]:
    """(points the scene holds, points three.js drew in the last frame)."""
    canvas = page.get_by_test_id("scene")
    return int(canvas.get_attribute("data-points") or 0), int(
        canvas.get_attribute("data-rendered-points") or 0
    )


def test_the_scene_store_of_the_tests_is_a_temporary_file():
    store = Path(os.environ["PLANNER_SCENE_STORE"])
    assert store.is_relative_to(tempfile.gettempdir()), store


def test_a_100000_point_cloud_from_a_file_is_one_item_drawn_as_points(page, tmp_path):
    from playwright.sync_api import expect

    rng = np.random.default_rng(7)
    n = 100_000
    # a wall beside the arm, inside the camera's view: x in [0.7, 0.9], y, z in [-0.4, 0.4]
    cloud = np.column_stack(
        [rng.uniform(0.7, 0.9, n), rng.uniform(-0.4, 0.4, n), rng.uniform(-0.4, 0.4, n)]
    )
    canvas = "[data-testid=scene]"
    before = pixels(page, canvas, reds)
    page.get_by_test_id("cloud-radius").fill("0.004")
    path = tmp_path / "cloud.xyz"  # a file on disk: the browser reads it, no copy over the wire
    path.write_bytes(xyz_file(cloud)["buffer"])
    page.get_by_test_id("cloud-file").set_input_files(path)
    item = page.get_by_test_id("cloud-item")
    expect(item).to_have_count(1)
    expect(item).to_have_attribute("data-count", str(n))
    expect(item).to_contain_text("100,000 points")
    expect(item).to_contain_text("cloud.xyz")
    expect(page.get_by_test_id("scene")).to_have_attribute("data-rendered-points", str(n))
    assert drawn_points(page) == (n, n)
    # one string across (a 100,000-item list would take seconds of the driver's own time)
    body = json.loads(
        page.evaluate("async () => JSON.stringify((await import('/viewer/form.js')).request())")
    )
    sent = body["obstacles"][-1]
    assert set(sent) == {"type", "points", "radius"}
    assert sent["type"] == "points" and sent["radius"] == 0.004
    assert np.array_equal(np.asarray(sent["points"]), cloud)  # the file's numbers, exactly
    assert body["obstacles"][0]["type"] == "sphere"  # the example's own obstacle is kept
    assert pixels(page, canvas, reds) > before + 2_000  # the wall is on the screen
    # the page stays responsive: an edit redraws the scene without rebuilding the cloud
    builds = page.get_by_test_id("scene").get_attribute("data-cloud-builds")
    frames = page.get_by_test_id("scene").get_attribute("data-frames")
    page.locator("input[name='start.q.0']").fill("0.2")
    expect(page.get_by_test_id("scene")).not_to_have_attribute("data-frames", frames)
    assert page.get_by_test_id("scene").get_attribute("data-cloud-builds") == builds
    assert drawn_points(page) == (n, n)
    page.screenshot(path=shots_dir(tmp_path) / "cloud-100k.png", full_page=True)
    item.locator("button[data-remove]").click()
    expect(item).to_have_count(0)
    expect(page.get_by_test_id("scene")).to_have_attribute("data-points", "0")
    page.watch.check()


def test_a_json_cloud_keeps_its_radius_and_a_bad_row_is_named_by_its_line(page):
    from playwright.sync_api import expect

    obstacle = {"type": "points", "points": [[0.5, 0.5, 0.5], [0.6, 0.5, 0.5]], "radius": 0.02}
    page.get_by_test_id("cloud-file").set_input_files(
        {"name": "c.json", "mimeType": "application/json", "buffer": json.dumps(obstacle).encode()}
    )
    expect(page.get_by_test_id("cloud-item")).to_have_attribute("data-count", "2")
    body = page.evaluate("async () => (await import('/viewer/form.js')).request()")
    assert body["obstacles"][-1] == obstacle
    # a list of obstacles: a capsule is edited in place (its ends a, b and radius)
    capsule = {"type": "capsule", "a": [0.4, -0.3, 0.3], "b": [0.4, 0.3, 0.3], "radius": 0.03}
    page.get_by_test_id("cloud-file").set_input_files(
        {
            "name": "more.json",
            "mimeType": "application/json",
            "buffer": json.dumps([capsule]).encode(),
        }
    )
    item = page.locator("#obstacles .obstacle").nth(2)
    expect(item).to_contain_text("3. capsule")
    item.locator("input[data-key=b][data-k='2']").fill("0.25")
    body = page.evaluate("async () => (await import('/viewer/form.js')).request()")
    assert body["obstacles"][2] == {**capsule, "b": [0.4, 0.3, 0.25]}
    item.locator("button[data-remove]").click()
    bad = b"0.1 0.2 0.3\n0.1 0.2\n"
    page.get_by_test_id("cloud-file").set_input_files(
        {"name": "bad.xyz", "mimeType": "text/plain", "buffer": bad}
    )
    error = page.locator("[data-testid=field-error][data-loc='cloud-file']")
    expect(error).to_contain_text("bad.xyz: line 2: three numbers x y z")
    expect(page.get_by_test_id("cloud-item")).to_have_count(1)  # nothing added
    # the service's rule on the radius, checked as typed next to the cloud's radius field
    page.get_by_test_id("cloud-item").locator("input[data-key=radius]").fill("-1")
    radius_error = page.locator("[data-testid=field-error][data-loc='obstacles.1.radius']")
    expect(radius_error).to_contain_text("Input should be greater than 0")
    page.watch.check()


def test_a_scene_is_saved_listed_chosen_drawn_used_by_a_plan_and_deleted(
    page, live_server, tmp_path
):
    from playwright.sync_api import expect

    name = scene_name()
    floor = np.array(
        [[x, y, -0.95] for x in np.linspace(-0.6, 0.6, 40) for y in np.linspace(-0.5, 0.5, 50)]
    )
    page.get_by_test_id("cloud-file").set_input_files(xyz_file(floor, "floor.xyz"))
    expect(page.get_by_test_id("cloud-item")).to_have_count(1)
    own = page.evaluate("async () => (await import('/viewer/form.js')).request().obstacles")
    # a name against the service's rule: said as typed, and in the service's words on save
    box = page.get_by_test_id("scene-name")
    box.fill("bad name!")
    error = page.locator("[data-testid=field-error][data-loc='scene-name']")
    expect(error).to_contain_text("String should match pattern")
    typed = error.inner_text()
    with page.expect_response(lambda r: r.request.method == "PUT") as refused:
        page.get_by_test_id("scene-save").click()
    assert refused.value.status == 422
    (detail,) = refused.value.json()["detail"]
    assert detail["loc"] == ["path", "name"]
    expect(error).to_have_text(f"scene-name: {detail['msg']}")
    assert typed == f"scene-name: {detail['msg']}"  # the typed check said the same
    # saved: listed by the service and the picker, chosen, its obstacles drawn
    box.fill(name)
    expect(error).to_have_count(0)
    with page.expect_request(lambda r: r.method == "PUT") as put:
        page.get_by_test_id("scene-save").click()
    assert put.value.url.endswith(f"/v1/scenes/{name}")
    assert json.loads(put.value.post_data) == {"obstacles": own}
    picker = page.get_by_test_id("scene-picker")
    expect(picker).to_have_value(name)
    expect(picker).to_have_attribute("data-state", "loaded")
    listed = {s["name"]: s for s in httpx.get(f"{live_server}/v1/scenes").json()["scenes"]}
    assert listed[name]["obstacles"] == 2 and listed[name]["points"] == len(floor)
    assert page.locator(f"[data-testid=scene-picker] option[value='{name}']").count() == 1
    stored = httpx.get(f"{live_server}/v1/scenes/{name}").json()["scene"]["obstacles"]
    assert stored == own
    expect(page.get_by_test_id("cloud-item")).to_have_count(0)  # in the scene now
    expect(page.get_by_test_id("scene")).to_have_attribute("data-points", str(len(floor)))
    expect(page.get_by_test_id("scene-info")).to_contain_text("version 1: 2 obstacles")
    # a plan names the scene instead of sending its obstacles
    with page.expect_request(lambda r: r.url.endswith("/v1/plan")) as sent:
        answer = plan(page)
    body = json.loads(sent.value.post_data)
    assert body["scene"] == name and body["obstacles"] == []
    assert answer["status"] == "solved", answer["message"]
    # the service used it: a scene with a ball on the goal makes the same plan fail
    goal_p = page.evaluate(
        "async () => { const f = await import('/viewer/form.js'); const k = await import("
        "'/viewer/kin.js'); const r = f.request(); return k.posture(r.design, r.goal.q, "
        "r.goal.assembly_mode).P; }"
    )
    blocked = scene_name()
    ball = {"type": "sphere", "center": goal_p, "radius": 0.05}
    assert (
        httpx.put(f"{live_server}/v1/scenes/{blocked}", json={"obstacles": [ball]}).status_code
        == 200
    )
    page.evaluate("async () => (await import('/viewer/scenes.js')).refresh()")
    picker.select_option(blocked)
    expect(picker).to_have_attribute("data-state", "loaded")
    failed = plan(page)
    assert failed["status"] != "solved"
    page.screenshot(path=shots_dir(tmp_path) / "scene.png", full_page=True)
    # a scene deleted behind the page's back: the plan's 422 at `scene`, next to the picker
    httpx.delete(f"{live_server}/v1/scenes/{blocked}").raise_for_status()
    with page.expect_response(lambda r: r.url.endswith("/v1/plan")) as gone:
        page.get_by_test_id("plan-button").click()
    assert gone.value.status == 422
    (detail,) = gone.value.json()["detail"]
    assert detail["loc"] == ["body", "scene"]
    expect(page.locator("[data-testid=field-error][data-loc='scene']")).to_have_text(
        f"scene: {detail['msg']}"
    )
    # delete from the page: gone from the service and the picker, nothing drawn
    picker.select_option(name)
    expect(picker).to_have_attribute("data-state", "loaded")
    with page.expect_response(lambda r: r.request.method == "DELETE") as deleted:
        page.get_by_test_id("scene-delete").click()
    assert deleted.value.status == 200 and deleted.value.json()["name"] == name
    expect(picker).to_have_value("")
    assert page.locator(f"[data-testid=scene-picker] option[value='{name}']").count() == 0
    assert httpx.get(f"{live_server}/v1/scenes/{name}").status_code == 404
    expect(page.get_by_test_id("scene")).to_have_attribute("data-points", "0")
    page.watch.check(allowed_errors=_REFUSED)


#: the browser logs each refused request (4xx) as a console error; the tests above ask for them
_REFUSED = re.compile(r"the server responded with a status of 4(22|04)")


def test_a_sequences_transits_are_marked_on_the_timeline(page, live_server):
    from playwright.sync_api import expect

    # a joint posture of working mode ++- (the end of the mode-change example's plan)
    example = {
        "start": {"q": START, "assembly_mode": "+"},
        "goal": {"p": MODE_CHANGE_P, "working_mode": "++-"},
        "timing": {"method": "none"},
    }
    far = httpx.post(f"{live_server}/v1/plan", json=example, timeout=60).json()
    assert far["status"] == "solved", far["message"]
    q_far = far["path"]["waypoints"][-1]
    page.get_by_test_id("sequence-mode").check()
    page.locator("textarea[name='targets']").fill(
        "q " + " ".join(repr(x) for x in q_far) + "\n" + "q " + " ".join(map(str, START))
    )
    answer = plan(page, "/v1/sequence")
    assert answer["status"] == "solved", answer["message"]
    legs = answer["legs"]
    expected = [(k, tr) for k, leg in enumerate(legs) for tr in leg["path"]["transits"]]
    assert len(expected) >= 2  # there and back: at least one transit each way
    assert {k for k, _ in expected} == {0, 1}
    marks = page.locator("[data-testid=transit-mark]")
    expect(marks).to_have_count(len(expected))
    t = np.asarray(answer["trajectory"]["t"])
    q = np.asarray(answer["trajectory"]["q"])
    for i, (k, tr) in enumerate(expected):
        mark = marks.nth(i)
        assert mark.inner_text() == tr["kind"]
        assert mark.get_attribute("data-leg") == str(k)
        tm = float(mark.get_attribute("data-t"))
        assert legs[k]["start_time"] - 1e-9 <= tm <= legs[k]["end_time"] + 1e-9
        j = int(np.flatnonzero(t == tm)[0])  # a sample's time, where the timed motion is
        assert np.linalg.norm(q[j] - tr["q"]) < 0.05  # within a sample of the transit posture
        left = float(mark.evaluate("m => parseFloat(m.style.left)"))
        assert left == pytest.approx(100 * tm / t[-1], abs=1e-3)  # CSS keeps 6 digits
    items = page.get_by_test_id("transits").locator("li")
    expect(items).to_have_count(len(expected))
    assert "leg 0" in items.first.inner_text() and "leg 1" in items.last.inner_text()
    page.watch.check()


def test_scene_and_cloud_fields_fit_an_800_px_window(page):
    from playwright.sync_api import expect

    page.get_by_test_id("cloud-file").set_input_files(
        xyz_file(np.array([[0.5, 0.1, 0.2], [0.5, 0.2, 0.2]]), "a-long-file-name-" * 4 + ".xyz")
    )
    expect(page.get_by_test_id("cloud-item")).to_have_count(1)
    page.get_by_test_id("scene-name").fill("bad name!")
    page.set_viewport_size(NARROW)
    page.wait_for_timeout(200)  # the resize's layout
    assert page.evaluate("document.documentElement.scrollWidth") <= NARROW["width"]
    form = page.locator("form").bounding_box()
    for sel in (
        "#scene-fieldset",
        "[data-testid=cloud-item]",
        "[data-testid=cloud-file]",
        "[data-testid=scene-picker]",
        "[data-loc='scene-name'] .field-error",
    ):
        box = page.locator(sel).first.bounding_box()
        assert (
            box["x"] >= form["x"] - 0.5
            and box["x"] + box["width"] <= form["x"] + form["width"] + 0.5
        ), sel
    page.watch.check()
