"""GET /v1/designs and the design model on the wire."""

from __future__ import annotations

import math

import pytest

from planner.design import Design
from planner.wire import DesignModel


def test_presets_are_the_documented_designs(api):
    r = api.get("/v1/designs")
    assert r.status_code == 200
    presets = {p["name"]: p["design"] for p in r.json()["presets"]}
    assert list(presets) == ["default", "singularity-free", "paper-optimum"]
    sf = presets["singularity-free"]
    # docs/conventions.md: 2 L1 < L0 < 2 (L2 - L1) removes both parallel singularities
    assert 2 * sf["L1"] < sf["L0"] < 2 * (sf["L2"] - sf["L1"])
    po = presets["paper-optimum"]
    assert po["L0"] == 0 and po["L1"] == po["L2"]
    assert presets["default"] == sf
    for d in presets.values():
        assert d["joint_min"] == [-math.pi] * 3 and d["joint_max"] == [math.pi] * 3


def test_each_preset_is_accepted_back_as_a_design(api):
    for preset in api.get("/v1/designs").json()["presets"]:
        r = api.post("/v1/fk", json={"q": [0.1, 1.0, 2.0], "design": preset["design"]})
        assert r.status_code == 200, preset["name"]


def test_design_model_defaults_and_round_trip():
    assert DesignModel().to_design() == Design.default()
    for design in (Design.paper_optimum(0.6), Design(0.1, 0.3, 0.5, 0.01, (-1, -2, -3), (1, 2, 3))):
        assert DesignModel.from_design(design).to_design() == design
    partial = DesignModel(L1=0.25)
    assert (partial.L0, partial.L1, partial.L2) == (0.5, 0.25, 0.6)


@pytest.mark.parametrize(
    ("fields", "loc"),
    [
        ({"L0": -0.1}, ("L0",)),
        ({"L1": 0.0}, ("L1",)),
        ({"L2": float("inf")}, ("L2",)),
        ({"link_radius": float("nan")}, ("link_radius",)),
        ({"joint_min": [0, 0]}, ("joint_min",)),
        ({"joint_min": [1, 0, 0], "joint_max": [0.5, 1, 1]}, ("joint_max",)),
        ({"L4": 1.0}, ("L4",)),
    ],
)
def test_design_model_rejects_with_the_field(fields, loc):
    from pydantic import ValidationError

    with pytest.raises(ValidationError) as info:
        DesignModel(**fields)
    assert loc in [tuple(e["loc"]) for e in info.value.errors()]


def test_design_check_runs_in_a_worker_and_names_bad_fields(api):
    r = api.post(
        "/v1/design/check", json={"design": {"L0": 0.5, "L1": 0.2, "L2": 0.6}, "rel_se": 0.05}
    )
    assert r.status_code == 200, r.text
    body = r.json()
    # 2 L1 < L0 < 2 (L2 - L1): no parallel singularity (docs/conventions.md, erratum 4)
    assert body["singularity_free"] is True and body["parallel_singularities"] == []
    r = api.post(
        "/v1/design/check",
        content=b'{"design": {"L2": NaN}}',
        headers={"content-type": "application/json"},
    )
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "design", "L2"]
