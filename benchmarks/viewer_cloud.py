"""Viewer benchmark: a point cloud in the browser page (Debian's chromium, headless, software
WebGL) against a real ``planner serve`` (one worker, a temporary scene store).

For each cloud size: the time from choosing an ``.xyz`` file to the cloud drawn (three.js's
count of points drawn equals the cloud's), the page's cost of one form edit (an ``input``
event's handler, the preview redraw included) without the cloud, with it, and with the curl
export shown; then, from the page, a plan sending the cloud inline, "save as scene" (the PUT
of the cloud) and plans naming the scene (the first and the median of the next; the page's animation paused, since software WebGL
drawing the cloud at every frame takes CPU from the service). Medians of
``--repeats`` runs side by side in one run. Without chromium or Playwright it says so and
exits.

    PYTHONPATH=src:. python benchmarks/viewer_cloud.py [--sizes 10000 100000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np
from _machine import print_machine
from _server import start_service

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = Path(os.environ.get("PLANNER_CHROMIUM", "/usr/bin/chromium"))
#: one form edit, timed in the page: the handler of an input event (and the work it does)
EDIT = """(sel) => { const t0 = performance.now(); const el = document.querySelector(sel);
  el.value = String(1 + Math.floor(100 * Math.random())); el.dispatchEvent(new Event('input', {bubbles: true}));
  return performance.now() - t0; }"""
SEED = "input[name='planner.seed']"


def _start_server(store: Path) -> tuple[subprocess.Popen[bytes], str]:
    """The service with one worker and its scene store at ``store``."""
    settings = {"PLANNER_WORKERS": "1", "PLANNER_SCENE_STORE": str(store), "PLANNER_DRAIN_S": "0"}
    return start_service(settings)


def _cloud_file(n: int, folder: Path) -> Path:
    """A wall of n points beside the arm, as a depth camera's export (header, x,y,z)."""
    rng = np.random.default_rng(n)
    xyz = np.column_stack(
        [rng.uniform(0.7, 0.9, n), rng.uniform(-0.4, 0.4, n), rng.uniform(-0.4, 0.4, n)]
    )
    path = folder / f"cloud-{n}.xyz"
    path.write_text("x,y,z\n" + "\n".join(f"{x!r},{y!r},{z!r}" for x, y, z in xyz.tolist()))
    return path


def _edits(page, count: int = 15) -> float:
    return statistics.median(page.evaluate(EDIT, SEED) for _ in range(count))


def _plan_s(page) -> tuple[float, str]:
    # the last answer's animation paused: software WebGL drawing the cloud at every frame
    # would take the CPU from the service under test
    if "pause" in page.locator("#play").inner_text():
        page.locator("#play").click()
    t = time.perf_counter()
    with page.expect_response(lambda r: r.url.endswith("/v1/plan"), timeout=300_000) as a:
        page.get_by_test_id("plan-button").click()
    return time.perf_counter() - t, a.value.json().get("status", str(a.value.status))


def _measure(page, url: str, path: Path, n: int, repeats: int) -> dict[str, object]:
    from playwright.sync_api import expect

    row: dict[str, object] = {"points": n}
    drawn = []
    for _ in range(repeats):
        page.locator("#start-over").click()
        expect(page.get_by_test_id("scene")).to_have_attribute("data-points", "0")
        row["edit, no cloud (ms)"] = _edits(page)
        t = time.perf_counter()
        page.get_by_test_id("cloud-file").set_input_files(path)
        expect(page.get_by_test_id("scene")).to_have_attribute("data-rendered-points", str(n))
        drawn.append(time.perf_counter() - t)
    row["file -> drawn (s)"] = statistics.median(drawn)
    row["edit, cloud (ms)"] = _edits(page)
    page.locator("#copy-curl").click()
    row["edit, cloud + export (ms)"] = _edits(page, 5)
    page.locator(SEED).fill("1")
    row["plan inline (s)"], row["status"] = _plan_s(page)
    page.get_by_test_id("scene-name").fill(f"bench-{n}")
    t = time.perf_counter()
    with page.expect_response(lambda r: r.request.method == "PUT", timeout=300_000):
        page.get_by_test_id("scene-save").click()
    expect(page.get_by_test_id("scene-picker")).to_have_attribute("data-state", "loaded")
    row["save as scene (s)"] = time.perf_counter() - t
    row["plan scene, 1st (s)"], _ = _plan_s(page)
    row["plan scene, next (s)"] = statistics.median(_plan_s(page)[0] for _ in range(repeats))
    httpx.delete(f"{url}/v1/scenes/bench-{n}")
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print_machine()
    try:
        from playwright.sync_api import expect, sync_playwright
    except ImportError:
        print("skipped: the playwright package is not installed (pip install -e '.[test]')")
        return
    if not CHROMIUM.exists():
        print(f"skipped: no chromium at {CHROMIUM} (apt-get install chromium)")
        return
    expect.set_options(timeout=300_000)
    with tempfile.TemporaryDirectory(prefix="viewer-bench-") as tmp:
        folder = Path(tmp)
        proc, url = _start_server(folder / "scenes.db")
        rows = []
        try:
            with sync_playwright() as p:
                browser = p.chromium.launch(
                    executable_path=str(CHROMIUM),
                    args=["--headless", "--no-sandbox", "--disable-gpu"],
                )
                page = browser.new_page(viewport={"width": 1400, "height": 900})
                page.goto(url + "/")
                expect(page.locator("#regions-box")).to_have_attribute("data-state", "loaded")
                for n in args.sizes:
                    rows.append(_measure(page, url, _cloud_file(n, folder), n, args.repeats))
                browser.close()
        finally:
            proc.terminate()
            proc.wait(30)
    keys = list(rows[0])
    print(" | ".join(keys))
    for row in rows:
        print(" | ".join(f"{v:.3g}" if isinstance(v, float) else str(v) for v in row.values()))


if __name__ == "__main__":
    main()
