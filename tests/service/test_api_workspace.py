"""POST /v1/workspace and GET /v1/figures/{name}.png|svg.

Volumes are checked against independent routes: the closed form 4/3 pi ((L1 + L2)^3 -
|L1 - L2|^3) for L0 = 0, and a plain Monte Carlo of the two hollow spheres written here for a
general design; section cells against /v1/ik (Cartesian) and /v1/fk (joint) and kappa(A)
against /v1/analyze.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from planner_api.routes.workspace import FIGURE_NAMES

PAPER_OPTIMUM = {"L0": 0.0, "L1": 0.4, "L2": 0.4}
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _workspace(api, **body):
    r = api.post("/v1/workspace", json=body)
    assert r.status_code == 200, r.text
    return r.json()


def _hollow_spheres_volume(L0: float, L1: float, L2: float, n: int = 400_000) -> float:
    """Monte Carlo volume of {P : |L1 - L2| <= |AP|, |BP| <= L1 + L2} (erratum 5), seeded."""
    rng = np.random.default_rng(12345)
    big, small = L1 + L2, abs(L1 - L2)
    lo = np.array([-big, -L0 / 2 - big, -big])
    hi = np.array([big, L0 / 2 + big, big])
    p = lo + (hi - lo) * rng.random((n, 3))
    da = np.linalg.norm(p - [0, -L0 / 2, 0], axis=1)
    db = np.linalg.norm(p - [0, L0 / 2, 0], axis=1)
    inside = (da >= small) & (da <= big) & (db >= small) & (db <= big)
    return float(np.prod(hi - lo) * inside.mean())


def test_paper_optimum_volume_is_the_sphere_and_the_sample_agrees(api):
    ws = _workspace(
        api, design=PAPER_OPTIMUM, rel_se=0.01, sections={"cartesian": False, "joint": False}
    )
    expected = 4 / 3 * math.pi * 0.8**3
    assert ws["volume"] == pytest.approx(expected, rel=1e-12)
    s = ws["sampled_volume"]
    assert 0 < s["standard_error"] <= 0.011 * s["value"]
    assert abs(s["value"] - expected) < 3.5 * s["standard_error"]
    assert ws["cartesian_section"] is None and ws["joint_section"] is None
    # the modes with s_A = s_B are parallel-singular everywhere here; the others reach
    assert set(ws["per_mode"]) == {"+++", "++-", "+-+", "+--", "-++", "-+-", "--+", "---"}
    assert 0.0 < ws["gci"]["value"] <= 1.0
    assert 0.0 <= ws["well_conditioned_fraction"]["value"] <= 1.0


@pytest.mark.parametrize("design", [(0.5, 0.2, 0.6), (0.6, 0.25, 0.45), (0.3, 0.5, 0.2)])
def test_volume_matches_an_independent_monte_carlo(api, design):
    L0, L1, L2 = design
    ws = _workspace(
        api,
        design={"L0": L0, "L1": L1, "L2": L2},
        rel_se=0.02,
        sections={"cartesian": False, "joint": False},
    )
    mc = _hollow_spheres_volume(L0, L1, L2)
    assert ws["volume"] == pytest.approx(mc, rel=0.02)
    s = ws["sampled_volume"]
    assert abs(s["value"] - ws["volume"]) < 3.5 * s["standard_error"] + 0.005 * ws["volume"]


def test_quarter_turn_of_theta1_halves_the_sampled_volume(api):
    # theta1 in [0, pi/2] sweeps a quarter turn on each side of AB (w > 0 and w < 0)
    design = {"joint_min": [0.0, -math.pi, -math.pi], "joint_max": [math.pi / 2, math.pi, math.pi]}
    ws = _workspace(api, design=design, rel_se=0.01, sections={"cartesian": False, "joint": False})
    s = ws["sampled_volume"]
    assert abs(s["value"] - ws["volume"] / 2) < 3.5 * s["standard_error"] + 0.002 * ws["volume"]
    off = _workspace(
        api,
        design=design,
        joint_limits=False,
        rel_se=0.02,
        sections={"cartesian": False, "joint": False},
    )
    assert off["sampled_volume"]["value"] == pytest.approx(ws["volume"], rel=0.05)


def _bits(mask: int, labels: list[str]) -> set[str]:
    return {label for k, label in enumerate(labels) if mask >> k & 1}


def test_cartesian_section_cells_agree_with_ik_and_analyze(api):
    design = {"L0": 0.6, "L1": 0.25, "L2": 0.45}
    ws = _workspace(api, design=design, rel_se=0.05, sections={"resolution": 12, "joint": False})
    sec = ws["cartesian_section"]
    assert sec["kind"] == "cartesian" and sec["theta1"] == 0.0
    assert len(sec["x"]) == len(sec["y"]) == 12 and len(sec["reached"]) == 12
    rng = np.random.default_rng(3)
    checked_reached = 0
    for j, i in rng.integers(0, 12, size=(25, 2)):
        u, w = sec["x"][i], sec["y"][j]
        ik = api.post("/v1/ik", json={"p": [w, u, 0.0], "design": design}).json()["postures"]
        # in the plane theta1 = 0 a cell is reached in the modes whose s_axis is the sign of w
        mine = [p for p in ik if p["working_mode"][0] == ("+" if w > 0 else "-")]
        assert _bits(sec["reached"][j][i], sec["labels"]) == {p["working_mode"] for p in mine}
        if mine:
            checked_reached += 1
            kappas = [
                api.post(
                    "/v1/analyze",
                    json={"q": p["q"], "assembly_mode": p["assembly_mode"], "design": design},
                ).json()["kappa_A"]
                for p in mine
            ]
            finite = [k for k in kappas if k is not None and k < 1e6]
            if finite and sec["best_kappa"][j][i] is not None:
                assert sec["best_kappa"][j][i] == pytest.approx(min(finite), rel=1e-6)
        else:
            assert sec["best_kappa"][j][i] is None
    assert checked_reached >= 5


def test_joint_section_cells_agree_with_fk(api):
    design = {"L0": 0.6, "L1": 0.25, "L2": 0.45}
    ws = _workspace(
        api,
        design=design,
        rel_se=0.05,
        sections={"resolution": 10, "cartesian": False, "theta1": 0.3},
    )
    sec = ws["joint_section"]
    assert sec["kind"] == "joint" and sec["labels"] == ["+", "-"]
    assert sec["x"][0] == pytest.approx(-math.pi + math.pi / 10)  # cell centres over the limits
    for j in range(0, 10, 3):
        for i in range(10):
            q = [0.3, sec["x"][i], sec["y"][j]]
            fk = api.post("/v1/fk", json={"q": q, "design": design}).json()["postures"]
            modes = {p["assembly_mode"]: p for p in fk if p["assembly_mode"] in "+-"}
            assert _bits(sec["reached"][j][i], sec["labels"]) == set(modes)
            for k, label in enumerate(sec["labels"]):
                got = sec["working_mode"][j][i][k]
                assert got == (modes[label]["working_mode"] if label in modes else None)


@pytest.mark.parametrize(
    ("body", "loc"),
    [
        ({"sections": {"resolution": 1}}, ["body", "sections", "resolution"]),
        ({"sections": {"resolution": 100_000}}, ["body", "sections", "resolution"]),
        ({"sections": {"resolution": 257}}, ["body", "sections", "resolution"]),  # the setting
        ({"sections": {"theta1": "NaN"}}, ["body", "sections", "theta1"]),
        ({"sections": {"colour": True}}, ["body", "sections", "colour"]),
        ({"rel_se": 0.0}, ["body", "rel_se"]),
        ({"kappa_max": 0.5}, ["body", "kappa_max"]),
        ({"working_modes": ["+x+"]}, ["body", "working_modes", 0]),
        ({"working_modes": []}, ["body", "working_modes"]),
        ({"seed": -1}, ["body", "seed"]),
        ({"design": {"L1": -0.2}}, ["body", "design", "L1"]),
        ({"volume": 1}, ["body", "volume"]),
    ],
)
def test_bad_workspace_requests_are_422_naming_the_field(api, body, loc):
    r = api.post("/v1/workspace", json=body)
    assert r.status_code == 422, r.text
    assert loc in [item["loc"] for item in r.json()["detail"]]


def test_resolution_cap_is_a_setting(api_with):
    small = api_with(max_section_resolution=8)  # the session's service, read per request
    r = small.post("/v1/workspace", json={"sections": {"resolution": 9}})
    assert r.status_code == 422
    (item,) = r.json()["detail"]
    assert item["loc"] == ["body", "sections", "resolution"]
    assert item["type"] == "limit_exceeded" and "8" in item["msg"]
    r = small.get("/v1/figures/cartesian_section.png", params={"resolution": 16})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["query", "resolution"]


# ---------------------------------------------------------------------------- figures
def test_figure_names_are_the_plotting_modules():
    from planner.plotting import NAMED_FIGURES

    assert set(FIGURE_NAMES) == set(NAMED_FIGURES)


def test_png_and_svg_of_a_design_given_in_the_query(api):
    query = {"L0": 0.3, "L1": 0.3, "L2": 0.4, "resolution": 24, "dpi": 30}
    r = api.get("/v1/figures/cartesian_section.png", params=query)
    assert r.status_code == 200 and r.headers["content-type"] == "image/png"
    assert r.content.startswith(PNG_MAGIC)
    r2 = api.get("/v1/figures/cartesian_section.png", params={**query, "L0": 0.0})
    assert r2.status_code == 200 and r2.content != r.content
    s = api.get("/v1/figures/joint_section.svg", params=query)
    assert s.status_code == 200 and s.headers["content-type"].startswith("image/svg+xml")
    assert ET.fromstring(s.content).tag.endswith("svg")


@pytest.mark.parametrize(
    "design",
    [
        {"L0": 0.5, "L1": 0.2, "L2": 0.6},
        PAPER_OPTIMUM,
        {"L0": 0.6, "L1": 0.25, "L2": 0.45},
        {"L0": 1.5, "L1": 0.2, "L2": 0.5},
    ],
)
def test_every_figure_is_an_image_or_a_422_for_every_preset(api, design):
    for name in FIGURE_NAMES:
        r = api.get(f"/v1/figures/{name}.png", params={**design, "resolution": 16, "dpi": 20})
        assert r.status_code in (200, 422), (name, design, r.text)
        if r.status_code == 200:
            assert r.content.startswith(PNG_MAGIC)
        else:
            assert r.json()["detail"][0]["type"] == "design_error"


def test_figures_refused_or_drawn_by_the_design_at_hand(api):
    # the singularity-free default robot has no C = D: that figure is refused, with the reason
    r = api.get("/v1/figures/parallel_c_equals_d.png")
    assert r.status_code == 422 and "C and D cannot meet" in r.json()["detail"][0]["msg"]
    # the mode-change design has a stretched CD in its convex mode: drawn
    r = api.get(
        "/v1/figures/working_mode_and_parallel_singularity.png",
        params={"L0": 0.6, "L1": 0.25, "L2": 0.45, "dpi": 20},
    )
    assert r.status_code == 200


@pytest.mark.parametrize(
    "path",
    ["/v1/figures/nope.png", "/v1/figures/cartesian_section.jpg", "/v1/figures/cartesian_section"],
)
def test_unknown_figure_or_format_is_404_listing_the_names(api, path):
    r = api.get(path)
    assert r.status_code == 404
    msg = r.json()["detail"][0]["msg"]
    assert all(name in msg for name in FIGURE_NAMES) and "png" in msg and "svg" in msg


@pytest.mark.parametrize(
    ("query", "loc"),
    [
        ({"L1": -1}, ["query", "L1"]),
        ({"L0": "nan"}, ["query", "L0"]),
        ({"L2": "inf"}, ["query", "L2"]),
        ({"L2": "abc"}, ["query", "L2"]),
        ({"resolution": 1_000_000}, ["query", "resolution"]),
        ({"resolution": 300}, ["query", "resolution"]),  # above the setting (256)
        ({"dpi": 5000}, ["query", "dpi"]),
        ({"colour": "red"}, ["query", "colour"]),
    ],
)
def test_bad_figure_query_is_422_naming_the_parameter(api, query, loc):
    r = api.get("/v1/figures/cartesian_section.png", params=query)
    assert r.status_code == 422, r.text
    assert loc in [item["loc"] for item in r.json()["detail"]]


def test_every_v1_route_but_the_probes_needs_the_api_key(client_factory):
    # the key is the gate's, before any route: with it, a route answered without a job and
    # one run in a worker answer 200 (forward kinematics: its worker, not warmed, pays far
    # fewer imports than a figure's; every figure is drawn by the tests above)
    with client_factory(api_key="s3cret", warm=False, request_timeout_s=300) as c:
        routes = [
            (method.upper(), path)
            for path, operations in c.app.openapi()["paths"].items()
            if path.startswith("/v1/") and path not in ("/v1/health", "/v1/ready")
            for method in operations
        ]
        paths = {p for _, p in routes}
        assert {"/v1/workspace", "/v1/timing", "/v1/design/optimize"} <= paths
        assert "/v1/figures/{filename}" in paths
        for method, path in routes:
            url = path.replace("{filename}", "cartesian_section.png")
            r = c.request(method, url, json={} if method == "POST" else None)
            assert r.status_code == 401, (method, path)
        key = {"X-API-Key": "s3cret"}
        assert c.get("/v1/version", headers=key).status_code == 200
        # past the gate, the figure route itself answers (an unknown name: its 404, no job)
        assert c.get("/v1/figures/nope.png", headers=key).status_code == 404
        fk = {"q": [0.3, 1.0, 2.1], "assembly_mode": "+"}
        r = c.post("/v1/fk", json=fk, headers=key)
        assert r.status_code == 200 and len(r.json()["postures"]) == 1, r.text
