"""The simulated robot and calibration on the page, in a real browser (helpers:
``viewer_browser.py``), one page for the module at 1440 x 900 and 800 x 600, taking a user's
steps and asserting what the eye sees: after a plan or a sequence, **Simulate** sends the
answer's own trajectory to ``POST /v1/simulate`` and ``sim-plot`` draws both P curves
(planned and realised: pixels of each colour) and the tracking error, the summary's numbers
being the answer's; a measurements file or a pasted body goes to ``POST /v1/calibrate`` and
``calibration-residuals`` has one bar per measurement, each as long as its residual. Every
test checks that the page logged no console error, that no request failed and that none left
the service's origin."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterator

import numpy as np
import pytest
from viewer_browser import open_viewer, plan, rgb_of, shots_dir, watched_page

WIDE = {"width": 1440, "height": 900}
NARROW = {"width": 800, "height": 600}
SEQUENCE = "Sequence: pick and place (cycle)"
#: simulation.js's colours: realised P (x, y, z), planned P (their tints), the P error
REALISED = [(31, 119, 180), (255, 127, 14), (44, 160, 44)]
PLANNED = [(174, 199, 232), (255, 187, 120), (152, 223, 138)]
ERROR = (148, 103, 189)
#: docs/calibration.md's example: a machine with L1 0.2 mm long, L2 0.5 mm short and small
#: zero errors, measured at eight postures (1 um rounding)
MEASUREMENTS = [
    {"q": [0.0, 2.0, 1.0], "p": [0.665835, 0.022438, -0.001332]},
    {"q": [0.3, 2.2, 1.1], "p": [0.624851, -0.02458, -0.194659]},
    {"q": [-0.4, 1.8, 0.9], "p": [0.620283, 0.068276, 0.26079]},
    {"q": [0.6, 2.4, 1.3], "p": [0.534752, -0.086856, -0.367416]},
    {"q": [-0.2, 2.1, 0.7], "p": [0.604309, 0.053557, 0.121242]},
    {"q": [0.1, 1.9, 1.2], "p": [0.693299, 0.006506, -0.070963]},
    {"q": [0.5, 1.7, 0.8], "p": [0.585843, 0.098471, -0.321571]},
    {"q": [-0.6, 2.3, 1.4], "p": [0.55414, -0.085376, 0.377483]},
]


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


def near(rgb: np.ndarray, colour: tuple[int, int, int], tol: float = 24.0) -> int:
    """How many pixels are within ``tol`` of ``colour`` in every channel."""
    return int(np.count_nonzero(np.all(np.abs(rgb - np.asarray(colour, float)) <= tol, axis=-1)))


def simulate(page, controller: str) -> tuple[dict, dict]:
    """Choose the controller and click Simulate: (the body sent, the service's answer)."""
    page.get_by_test_id("sim-controller").select_option(controller)
    with page.expect_response(lambda r: r.url.endswith("/v1/simulate")) as answer:
        page.get_by_test_id("sim-run").click()
    assert answer.value.status == 200, answer.value.text()
    expect()(page.get_by_test_id("sim-summary")).to_be_visible()
    return json.loads(answer.value.request.post_data), answer.value.json()


def check_simulation(page, request: dict, answer: dict, body: dict, sim: dict, tmp_path, name):
    """The body is the answer's trajectory on the request's robot; the summary shows the
    simulation's numbers; the plot draws both P curves and the error curve."""
    traj = answer["trajectory"]
    assert body["trajectory"] == {k: traj[k] for k in ("t", "q", "qd", "qdd")}
    assert body["design"] == request["design"]
    assert body["assembly_mode"] == request["start"]["assembly_mode"]
    assert sim["planned_duration"] == pytest.approx(traj["t"][-1] - traj["t"][0])
    shown = {
        tid: json.loads(page.get_by_test_id(tid).get_attribute("data-value"))
        for tid in ("sim-p-max", "sim-p-rms", "sim-planned", "sim-realised", "sim-settle")
    }
    assert shown == {
        "sim-p-max": sim["tracking"]["p_max_mm"],
        "sim-p-rms": sim["tracking"]["p_rms_mm"],
        "sim-planned": sim["planned_duration"],
        "sim-realised": sim["realised_duration"],
        "sim-settle": sim["settle_times"],
    }
    assert page.get_by_test_id("sim-p-max").inner_text() == f"{sim['tracking']['p_max_mm']:.4f} mm"
    assert len(sim["settle_times"]) == len(sim["stops"])
    # the answer's own max and RMS over its samples (an oracle apart from the summary)
    err = np.asarray(sim["p_error_mm"])
    assert sim["tracking"]["p_max_mm"] == pytest.approx(err.max(), rel=1e-9)
    assert sim["tracking"]["p_rms_mm"] == pytest.approx(math.sqrt(np.mean(err**2)), rel=1e-9)
    plot = page.get_by_test_id("sim-plot")
    expect()(plot.locator("canvas")).to_have_count(2)
    assert plot.get_attribute("data-samples") == str(len(sim["t"]))
    plot.scroll_into_view_if_needed()
    p_chart = rgb_of(page, "[data-testid=sim-plot] > div:nth-child(1) canvas")
    e_chart = rgb_of(page, "[data-testid=sim-plot] > div:nth-child(2) canvas")
    for k in range(3):  # each coordinate's planned band and realised line
        assert near(p_chart, PLANNED[k]) > 150, ("planned", k)
        assert near(p_chart, REALISED[k]) > 80, ("realised", k)
    assert near(e_chart, ERROR) > 80
    assert near(p_chart, ERROR) == 0  # the error is on its own chart
    page.screenshot(path=shots_dir(tmp_path) / f"{name}.png", full_page=True)


def test_a_plan_is_simulated_under_computed_torque(page, tmp_path):
    """At 1440 px: plan the first example, Simulate: the planned and realised P and the
    tracking error drawn, the summary the answer's; a new plan takes the simulation off."""
    expect()(page.get_by_test_id("sim-view")).to_be_hidden()
    with page.expect_request(lambda r: r.url.endswith("/v1/plan")) as sent:
        answer = plan(page)
    assert answer["status"] == "solved", answer["message"]
    expect()(page.get_by_test_id("sim-view")).to_be_visible()
    expect()(page.get_by_test_id("sim-plot")).to_be_hidden()
    request = json.loads(sent.value.post_data)
    body, sim = simulate(page, "computed_torque")
    assert body["controller"] == {"kind": "computed_torque"}
    assert sim["controller"] == "computed_torque"
    assert sim["tracking"]["p_max_mm"] < 0.5  # docs/simulation.md's goal for computed torque
    assert sim["realised_duration"] is not None
    check_simulation(page, request, answer, body, sim, tmp_path, "simulated-plan")
    assert (
        page.get_by_test_id("sim-realised")
        .inner_text()
        .startswith(f"{sim['realised_duration']:.4f} s")
    )
    plan(page)  # another answer: its simulation is not this one's
    expect()(page.get_by_test_id("sim-plot")).to_be_hidden()
    expect()(page.get_by_test_id("sim-summary")).to_be_hidden()
    page.watch.check()


def test_a_sequence_is_simulated_under_pd_at_800_px(page, tmp_path):
    """At 800 x 600: the pick-and-place sequence under PD; both P curves apart and drawn,
    one settle time per stop, and the page scrolls only downwards."""
    page.set_viewport_size(NARROW)
    page.locator("#example").select_option(label=SEQUENCE)
    with page.expect_request(lambda r: r.url.endswith("/v1/sequence")) as sent:
        answer = plan(page, "/v1/sequence")
    assert answer["status"] == "solved", answer["message"]
    body, sim = simulate(page, "pd")
    assert body["controller"] == {"kind": "pd"} and sim["controller"] == "pd"
    assert sim["tracking"]["p_max_mm"] > 0.5  # no model: PD lags visibly
    check_simulation(page, json.loads(sent.value.post_data), answer, body, sim, tmp_path, "pd")
    settle = page.get_by_test_id("sim-settle").inner_text().split(", ")
    assert len(settle) == len(sim["settle_times"])
    assert page.evaluate("document.documentElement.scrollWidth") <= NARROW["width"]
    view = page.get_by_test_id("sim-view")
    assert view.evaluate("(el) => el.scrollWidth <= el.clientWidth + 1")
    box = view.bounding_box()
    assert box["x"] >= 0 and box["x"] + box["width"] <= NARROW["width"]
    page.watch.check()


def residual_bars(page) -> list[tuple[float, float]]:
    """Each bar's (data-mm, drawn width in px), in order."""
    bars = page.get_by_test_id("residual-bar")
    return [
        (float(bars.nth(k).get_attribute("data-mm")), bars.nth(k).bounding_box()["width"])
        for k in range(bars.count())
    ]


@pytest.mark.parametrize("viewport", [NARROW, WIDE], ids=["800", "1440"])
def test_a_measurements_file_is_calibrated_with_one_bar_per_measurement(page, tmp_path, viewport):
    """Load the docs' measurements from a file, Calibrate: the identified lengths and offsets
    are the answer's; one residual bar per measurement, its length its residual."""
    page.set_viewport_size(viewport)
    width = viewport["width"]
    file = tmp_path / "measurements.json"
    body = {"identify": ["lengths", "offsets"], "measurements": MEASUREMENTS}
    file.write_text(json.dumps(body))
    page.get_by_test_id("calibration-file").set_input_files(str(file))
    expect()(page.get_by_test_id("calibration-body")).not_to_have_value("")
    assert json.loads(page.get_by_test_id("calibration-body").input_value()) == body
    with page.expect_response(lambda r: r.url.endswith("/v1/calibrate")) as got:
        page.get_by_test_id("calibration-run").click()
    answer = got.value.json()
    assert json.loads(got.value.request.post_data) == body
    expect()(page.get_by_test_id("calibration-result")).to_be_visible()
    # the docs' machine: L1 0.2 mm long, L2 0.5 mm short, to the measurements' rounding
    assert answer["design"]["L1"] == pytest.approx(0.2012, abs=2e-5)
    assert answer["design"]["L2"] == pytest.approx(0.5995, abs=2e-5)
    rows = page.get_by_test_id("calibration-parameters").locator("tbody tr")
    values = {
        rows.nth(k).get_attribute("data-name"): float(rows.nth(k).get_attribute("data-value"))
        for k in range(rows.count())
    }
    assert values["L1"] == answer["design"]["L1"]
    assert values["L2"] == answer["design"]["L2"]
    assert [values[f"offsets[{k}]"] for k in range(3)] == answer["offsets"]
    assert values["frame.position[0]"] == answer["frame"]["position"][0]
    assert page.get_by_test_id("calibration-unidentified").inner_text() == "none"
    res = page.get_by_test_id("calibration-residuals")
    res.scroll_into_view_if_needed()
    bars = residual_bars(page)
    assert len(bars) == len(MEASUREMENTS) == len(answer["residuals_m"])
    assert [mm for mm, _ in bars] == [1000 * r for r in answer["residuals_m"]]
    widest = max(w for _, w in bars)
    top = max(mm for mm, _ in bars)
    for mm, w in bars:  # each bar's length is its residual on the largest's scale
        assert w == pytest.approx(widest * mm / top, abs=1.5)
    assert widest > 100  # on the largest's scale, across most of the panel
    rms = math.sqrt(np.mean(np.square(answer["residuals_m"])))
    assert answer["residual_rms_m"] == pytest.approx(rms, rel=1e-9)
    assert float(res.get_attribute("data-rms-mm")) == 1000 * answer["residual_rms_m"]
    assert float(res.get_attribute("data-max-mm")) == 1000 * answer["residual_max_m"]
    shot = rgb_of(page, "#calibration-bars")
    assert near(shot, REALISED[0], tol=10) > 20 * len(MEASUREMENTS)  # the bars are drawn
    assert page.evaluate("document.documentElement.scrollWidth") <= width
    panel = page.get_by_test_id("calibration-view")
    assert panel.evaluate("(el) => el.scrollWidth <= el.clientWidth + 1")
    page.screenshot(path=shots_dir(tmp_path) / f"calibration-{width}.png", full_page=True)
    page.watch.check()


def test_a_pasted_body_names_the_unidentified_and_bad_input_is_said(page):
    """Pasted with the frame free (the default identify): theta1's zero is named
    unidentified and marked; a body that is not JSON, and one the service refuses, are said
    next to the box, with the field; "use this design" puts the identified lengths into the
    form."""
    box = page.get_by_test_id("calibration-body")
    box.fill("{measurements: ")
    page.get_by_test_id("calibration-run").click()
    expect()(page.get_by_test_id("calibration-error")).to_contain_text("not JSON")
    box.fill(json.dumps({"measurements": MEASUREMENTS[:2]}))
    with page.expect_response(lambda r: r.url.endswith("/v1/calibrate")) as got:
        page.get_by_test_id("calibration-run").click()
    assert got.value.status == 422
    expect()(page.get_by_test_id("calibration-error")).to_contain_text("measurements")
    expect()(page.get_by_test_id("calibration-result")).to_be_hidden()
    box.fill(json.dumps({"measurements": MEASUREMENTS}))
    with page.expect_response(lambda r: r.url.endswith("/v1/calibrate")) as got:
        page.get_by_test_id("calibration-run").click()
    answer = got.value.json()
    assert "offsets[0]" in answer["unidentified"]
    expect()(page.get_by_test_id("calibration-error")).to_be_hidden()
    shown = page.get_by_test_id("calibration-unidentified")
    assert json.loads(shown.get_attribute("data-value")) == answer["unidentified"]
    row = page.locator("[data-testid=calibration-parameters] tr[data-name='offsets[0]']")
    expect()(row).to_have_class("unidentified")
    expect()(row).to_contain_text("unidentified")
    assert len(residual_bars(page)) == len(MEASUREMENTS)
    page.get_by_test_id("calibration-use").click()  # the identified lengths into the form
    for k in ("L0", "L1", "L2"):
        assert float(page.locator(f"input[name='design.{k}']").input_value()) == answer["design"][k]
    expect()(page.locator("#preset")).to_have_value("")  # no preset's: a design of its own
    page.watch.check(allowed_errors=re.compile(r"status of 422"))  # chromium logs a 422
