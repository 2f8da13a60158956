"""The viewer's page and files as the service serves them (no browser: see
``test_viewer_browser.py``), and as the package ships them."""

from __future__ import annotations

import base64
import fnmatch
import hashlib
import json
import re
import tomllib
from pathlib import Path

import pytest

from planner.viewer import STATIC_DIR, content_security_policy

ROOT = Path(__file__).resolve().parents[2]
TEST_IDS = (
    "plan-button",
    "status",
    "scene",
    "timeline",
    "mode",
    "kappa-plot",
    "joint-plot",
    "cartesian-mode",
    "regions-view",
    "torque-plot",
    "sequence-list",
    "blend-list",
    "blend-unit",
    "belt-view",
    "cloud-file",
    "cloud-radius",
    "scene-picker",
    "scene-name",
    "scene-save",
    "scene-delete",
    "sim-plot",
    "calibration-residuals",
)
#: The page's own code (not the vendored libraries).
OWN_FILES = sorted(p for p in STATIC_DIR.iterdir() if p.is_file())


@pytest.fixture(scope="module")
def page(api) -> tuple[str, dict[str, str]]:
    r = api.get("/")
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/html")
    return r.text, dict(r.headers)


def test_the_page_has_every_test_hook(page):
    html, _ = page
    for tid in TEST_IDS:
        assert f'data-testid="{tid}"' in html, tid
    assert re.search(r'<input type="range"[^>]*data-testid="timeline"', html)
    assert re.search(r'<canvas[^>]*data-testid="scene"', html)


def test_content_security_policy_allows_only_the_page_origin(page):
    html, headers = page
    csp = headers["content-security-policy"]
    assert csp == content_security_policy()
    directives = dict(d.strip().split(" ", 1) for d in csp.split(";"))
    assert directives["default-src"] == "'self'"
    assert directives["connect-src"] == "'self'"
    # the one inline script, the import map, is allowed by its hash and nothing else
    (importmap,) = re.findall(r'<script type="importmap">(.*?)</script>', html, re.DOTALL)
    digest = base64.b64encode(hashlib.sha256(importmap.encode()).digest()).decode()
    assert directives["script-src"] == f"'self' 'sha256-{digest}'"
    assert "unsafe" not in csp


def test_every_file_the_page_loads_is_served(api, page):
    html, _ = page
    (importmap,) = re.findall(r'<script type="importmap">(.*?)</script>', html, re.DOTALL)
    urls = set(json.loads(importmap)["imports"].values())
    urls |= set(re.findall(r'(?:src|href)="(/viewer/[^"]+)"', html))
    # the modules the page's modules import
    for own in STATIC_DIR.glob("*.js"):
        urls |= {"/viewer/" + m for m in re.findall(r"from '\./([\w.]+)'", own.read_text())}
    assert "/viewer/app.js" in urls and "/viewer/vendor/three/three.module.min.js" in urls
    for url in sorted(urls):
        r = api.get(url)
        assert r.status_code == 200, url
        if url.endswith(".js"):
            assert "javascript" in r.headers["content-type"], url
    assert api.get("/viewer/no-such-file.js").status_code == 404


def test_no_outside_host_in_the_page_or_its_code():
    for path in OWN_FILES:
        text = path.read_text()
        assert not re.search(r"https?://|//cdn|\bcdn\.", text), path.name
    html = (STATIC_DIR / "index.html").read_text()
    assert set(re.findall(r'(?:src|href)="([^"]+)"', html)) <= {
        "data:,",
        *re.findall(r'"(/viewer/[^"]+)"', html),
    }


def test_the_page_is_not_behind_the_api_key(client_factory):
    with client_factory(api_key="s3cret", warm=False) as c:  # the key is the gate's: no job
        assert c.get("/").status_code == 200
        assert c.get("/viewer/app.js").status_code == 200
        assert c.get("/v1/designs").status_code == 401
        assert c.get("/v1/designs", headers={"X-API-Key": "s3cret"}).status_code == 200


def test_package_data_ships_every_static_file():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    patterns = config["tool"]["setuptools"]["package-data"]["planner.viewer"]
    base = STATIC_DIR.parent
    files = [p.relative_to(base).as_posix() for p in STATIC_DIR.rglob("*") if p.is_file()]
    missing = [f for f in files if not any(fnmatch.fnmatchcase(f, pat) for pat in patterns)]
    assert missing == []


def test_vendored_libraries_have_their_licences_and_sums():
    vendor = STATIC_DIR / "vendor"
    readme = (vendor / "README.md").read_text()
    for lib in ("three", "uplot"):
        assert (vendor / lib / "LICENSE").read_text().startswith("The MIT License")
    listed = dict(
        (name, digest) for digest, name in re.findall(r"^([0-9a-f]{64})  (\S+)$", readme, re.M)
    )
    files = {p.relative_to(vendor).as_posix() for p in vendor.rglob("*") if p.parent != vendor}
    assert set(listed) == files
    for name, digest in listed.items():
        assert hashlib.sha256((vendor / name).read_bytes()).hexdigest() == digest, name


def test_the_region_map_the_viewer_draws_names_each_cells_region(api):
    """``cell_regions`` (asked by the viewer): the region of each cell centre's posture, checked
    against the map's own layers (the cell is in that region's label set) and the region's
    working mode against the closed-form signs of the posture (docs/conventions.md)."""
    import numpy as np

    from planner.analysis.regions import region_map
    from planner.design import Design
    from planner.kinematics import WORKING_MODES as modes
    from planner.validity import Margins

    n = 48
    r = api.post("/v1/design/regions", json={"resolution": n, "cell_regions": True})
    assert r.status_code == 200, r.text
    body = r.json()
    cells = np.asarray(body["cell_regions"])
    assert cells.shape == (2, n, n)
    assert api.post("/v1/design/regions", json={"resolution": n}).json()["cell_regions"] is None
    by_id = {reg["id"]: reg for reg in body["regions"]}
    rmap = region_map(Design.default(), Margins(), n)
    d = Design.default()
    theta2, theta3 = rmap.theta2, rmap.theta3
    checked = 0
    for ai, asm in enumerate("+-"):
        for k3 in range(0, n, 3):
            for k2 in range(0, n, 3):
                rid = int(cells[ai, k3, k2])
                if rid < 0:
                    continue
                reg = by_id[rid]
                assert reg["assembly_mode"] == asm
                mi = modes.index(reg["working_mode"])
                assert rmap.labels[ai, mi, k3, k2] > 0
                assert rmap.region_index[ai, mi, rmap.labels[ai, mi, k3, k2]] == rid
                # the closed form: C, D, then P on the side of the assembly mode
                q2, q3 = theta2[k2], theta3[k3]
                c = np.array([-d.L0 / 2 + d.L1 * np.cos(q2), d.L1 * np.sin(q2)])
                e = np.array([d.L0 / 2 + d.L1 * np.cos(q3), d.L1 * np.sin(q3)]) - c
                h = np.sqrt(d.L2**2 - e @ e / 4) / np.sqrt(e @ e) * (1 if asm == "+" else -1)
                p = c + e / 2 + h * np.array([-e[1], e[0]])
                t4 = np.arctan2(*(p - c)[::-1])
                t5 = np.arctan2(*(p - c - e)[::-1])
                signs = (p[1], np.sin(t4 - q2), np.sin(t5 - q3))
                assert reg["working_mode"] == "".join("+" if v > 0 else "-" for v in signs)
                checked += 1
    assert checked > 50
