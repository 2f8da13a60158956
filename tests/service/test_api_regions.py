"""POST /v1/design/regions over HTTP, the client's ``regions`` (sync and async, against a
real uvicorn process) and the ``planner regions`` command: the answer is the library's map,
its transits join modes that differ by the flipped sign only, bad input is a 422 naming the
field."""

from __future__ import annotations

import asyncio
import json

import httpx
import pytest
from typer.testing import CliRunner

from planner.analysis.regions import region_map
from planner.client import AsyncPlannerClient, InvalidRequestError, PlannerClient
from planner.design import Design
from planner.transits import FLIPPED_SIGN
from planner.validity import Margins
from planner.wire import RegionsResponse
from planner_cli import app as cli_app

GENERAL = {"L0": 0.3, "L1": 0.3, "L2": 0.4}
FLIP_INDEX = {"axis": 0, "A": 1, "B": 2}


def _check_transits(body: dict) -> None:
    """Every transit joins two regions of one assembly mode whose working modes differ in
    exactly the flipped sign, with a kind of that sign, inside one union-graph component."""
    regions = body["regions"]
    assert [r["id"] for r in regions] == list(range(len(regions)))
    for t in body["transits"]:
        a, b = regions[t["from"]], regions[t["to"]]
        assert a["assembly_mode"] == b["assembly_mode"]
        diff = [j for j in range(3) if a["working_mode"][j] != b["working_mode"][j]]
        assert diff == [FLIP_INDEX[t["flipped"]]]
        assert a["working_mode"][diff[0]] == "+" and b["working_mode"][diff[0]] == "-"
        assert FLIPPED_SIGN[t["kind"]] == t["flipped"]
        assert a["component"] == b["component"]


def test_regions_answer_the_wire_fields_and_the_library_map(api):
    r = api.post("/v1/design/regions", json={"design": GENERAL, "resolution": 128})
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["resolution"] == 128
    assert {"id", "working_mode", "assembly_mode", "cells"} <= set(body["regions"][0])
    assert {"from", "to", "kind"} <= set(body["transits"][0])
    rmap = region_map(Design(0.3, 0.3, 0.4), Margins(), 128)
    assert [(r["working_mode"], r["assembly_mode"], r["cells"]) for r in body["regions"]] == [
        (r.working_mode, r.assembly_mode, r.cells) for r in rmap.regions
    ]
    pairs = {(t["from"], t["to"], t["kind"]) for t in body["transits"]}
    assert pairs == {(t.a, t.b, k) for t in rmap.transits for k in t.kinds}
    assert body["components"] == len({r.component for r in rmap.regions})
    _check_transits(body)


def test_default_request_is_the_default_robot_at_256(api):
    body = api.post("/v1/design/regions", json={}).json()
    assert body["resolution"] == 256
    assert (body["design"]["L0"], body["design"]["L1"]) == (0.5, 0.2)
    assert body["margins"]["kappa_max"] == 10 and body["margins"]["serial_min"] == 0.05
    # in the default (singularity-free) robot P never reaches the axis AB: every region of
    # assembly mode '+' has s_axis '+', every region of '-' has s_axis '-'
    for r in body["regions"]:
        assert r["working_mode"][0] == ("+" if r["assembly_mode"] == "+" else "-")
    _check_transits(body)


def test_paper_optimum_has_no_region_for_equal_leg_signs(api):
    r = api.post("/v1/design/regions", json={"design": {"L0": 0.0, "L1": 0.4, "L2": 0.4}})
    body = r.json()
    modes = {reg["working_mode"] for reg in body["regions"]}
    assert modes and all(m[1] != m[2] for m in modes)
    _check_transits(body)


def test_margins_change_the_map(api):
    loose = api.post("/v1/design/regions", json={"design": GENERAL, "resolution": 64}).json()
    tight = api.post(
        "/v1/design/regions",
        json={"design": GENERAL, "resolution": 64, "margins": {"serial_min": 0.3}},
    ).json()
    assert tight["margins"]["serial_min"] == 0.3
    assert sum(r["cells"] for r in tight["regions"]) < sum(r["cells"] for r in loose["regions"])


@pytest.mark.parametrize(
    ("body", "loc"),
    [
        ({"resolution": 15}, ["body", "resolution"]),
        ({"resolution": 513}, ["body", "resolution"]),
        ({"resolution": 64.5}, ["body", "resolution"]),
        ({"resolution": "256"}, ["body", "resolution"]),
        ({"margins": {"kappa_max": 1.0}}, ["body", "margins", "kappa_max"]),
        ({"margins": {"serial_min": 1.0}}, ["body", "margins", "serial_min"]),
        ({"design": {"L1": -0.2}}, ["body", "design", "L1"]),
        ({"design": {"joint_min": [0, 0, 0], "joint_max": [1, 0, 1]}}, ["body", "design"]),
        ({"cells": 3}, ["body", "cells"]),
    ],
)
def test_bad_input_is_422_naming_the_field(api, body, loc):
    r = api.post("/v1/design/regions", json=body)
    assert r.status_code == 422, r.text
    locs = [e["loc"] for e in r.json()["detail"]]
    assert any(got[: len(loc)] == loc for got in locs), locs


def test_client_builds_the_request_and_refuses_bad_resolution_locally():
    sent: list[httpx.Request] = []
    answer = {
        "design": GENERAL,
        "margins": {"kappa_max": 10, "serial_min": 0.05},
        "resolution": 64,
        "regions": [],
        "transits": [],
        "components": 0,
        "computation_time_s": 0.0,
    }

    def handler(request: httpx.Request) -> httpx.Response:
        sent.append(request)
        return httpx.Response(200, json=answer)

    with PlannerClient("http://x", transport=httpx.MockTransport(handler)) as c:
        out = c.regions(Design(0.3, 0.3, 0.4), margins=Margins(kappa_max=5.0), resolution=64)
        assert isinstance(out, RegionsResponse)
        with pytest.raises(InvalidRequestError) as info:
            c.regions(resolution=8)
        assert info.value.detail[0]["loc"] == ["resolution"]
    (req,) = sent
    assert req.url.path == "/v1/design/regions"
    body = json.loads(req.content)
    assert body["resolution"] == 64 and body["margins"]["kappa_max"] == 5.0
    assert body["design"]["L0"] == 0.3


def test_live_client_sync_and_async_agree(live_server):
    with PlannerClient(live_server, timeout=60) as c:
        out = c.regions(GENERAL, resolution=96)
    assert out.resolution == 96 and out.transits
    _check_transits(out.model_dump(by_alias=True))

    async def run() -> RegionsResponse:
        async with AsyncPlannerClient(live_server, timeout=60) as c:
            return await c.regions(GENERAL, resolution=96)

    again = asyncio.run(run())
    assert again.regions == out.regions and again.transits == out.transits


def test_cli_prints_the_table_and_the_json():
    runner = CliRunner()
    r = runner.invoke(cli_app, ["regions", "--L0", "0.3", "--L1", "0.3", "--L2", "0.4",
                                "--resolution", "64"])  # fmt: skip
    assert r.exit_code == 0, r.output
    rmap = region_map(Design(0.3, 0.3, 0.4), Margins(), 64)
    assert f"regions: {len(rmap.regions)} in" in r.stdout
    assert "leg_A_folded" in r.stdout or "leg_A_stretched" in r.stdout
    r = runner.invoke(cli_app, ["regions", "--design", "paper-optimum", "--resolution", "64",
                                "--json"])  # fmt: skip
    assert r.exit_code == 0, r.output
    body = json.loads(r.stdout)
    assert body["resolution"] == 64 and body["design"]["L0"] == 0.0
    _check_transits(body)


def test_cli_names_the_bad_field():
    r = CliRunner().invoke(cli_app, ["regions", "--resolution", "4"])
    assert r.exit_code == 2 and "resolution" in r.output


@pytest.mark.parametrize(
    "name", ["region_map", "region_images", "regions_convex_mode", "regions_nonconvex_mode"]
)
def test_region_figures_are_served(api, name):
    r = api.get(
        f"/v1/figures/{name}.png",
        params={"L0": 0.3, "L1": 0.3, "L2": 0.4, "resolution": 32, "dpi": 30},
    )
    assert r.status_code == 200 and r.headers["content-type"] == "image/png"
    assert r.content.startswith(b"\x89PNG\r\n\x1a\n")


def test_cli_writes_named_figures(tmp_path):
    r = CliRunner().invoke(
        cli_app,
        [
            "figures",
            str(tmp_path),
            "--named",
            "region_map",
            "--n",
            "32",
            "--formats",
            "png",
            "--dpi",
            "30",
        ],
    )
    assert r.exit_code == 0, r.output
    assert (tmp_path / "region_map.png").read_bytes().startswith(b"\x89PNG")
    r = CliRunner().invoke(cli_app, ["figures", str(tmp_path), "--named", "no_such_figure"])
    assert r.exit_code == 2 and "no_such_figure" in r.output
