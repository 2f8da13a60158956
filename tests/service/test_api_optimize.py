"""POST /v1/design/optimize, checked against the closed form: for a fixed reach L1 + L2 the
largest workspace is L0 = 0, L1 = L2 (the paper's claim), of volume 4/3 pi reach^3."""

from __future__ import annotations

import math

import pytest


def _optimize(api, **body):
    r = api.post("/v1/design/optimize", json=body)
    assert r.status_code == 200, r.text
    return r.json()


def test_volume_optimum_for_fixed_reach_is_the_papers(api):
    out = _optimize(api, objective="volume", reach=0.8)
    d = out["design"]
    assert d["L0"] == pytest.approx(0.0, abs=1e-4)
    assert d["L1"] == pytest.approx(0.4, abs=1e-3) and d["L2"] == pytest.approx(0.4, abs=1e-3)
    assert out["value"] == pytest.approx(4 / 3 * math.pi * 0.8**3, rel=1e-5)
    assert out["volume"] == pytest.approx(out["value"])
    assert out["objective"] == "volume" and out["evaluations"] > 0


def test_volume_optimum_inside_bounds(api):
    # the volume grows with L1 and L2 (for L0 = 0: 4/3 pi ((L1 + L2)^3 - |L1 - L2|^3)) and
    # shrinks with L0: the optimum is the corner L0 = 0, L1 = L2 = 0.3
    out = _optimize(
        api, reach=None, L0_bounds=[0.0, 0.2], L1_bounds=[0.1, 0.3], L2_bounds=[0.1, 0.3]
    )
    d = out["design"]
    assert d["L0"] == pytest.approx(0.0, abs=1e-4)
    assert d["L1"] == pytest.approx(0.3, abs=1e-4) and d["L2"] == pytest.approx(0.3, abs=1e-4)
    assert out["value"] == pytest.approx(4 / 3 * math.pi * 0.6**3, rel=1e-4)


def test_sampled_objective_with_a_small_budget(api):
    template = {"link_radius": 0.01, "joint_min": [-3, -3, -3], "joint_max": [3, 3, 3]}
    out = _optimize(
        api, objective="gci", reach=0.8, n_samples=64, maxiter=1, seed=2, design=template
    )
    d = out["design"]
    assert 0.0 < out["value"] <= 1.0
    assert d["L1"] + d["L2"] == pytest.approx(0.8)
    assert 0.0 <= d["L0"] <= 0.8 and 0.04 - 1e-9 <= d["L1"] <= 0.76 + 1e-9
    assert d["link_radius"] == 0.01 and d["joint_max"] == [3, 3, 3]  # the template's
    # deterministic for a seed
    assert (
        _optimize(api, objective="gci", reach=0.8, n_samples=64, maxiter=1, seed=2, design=template)
        == out
    )


@pytest.mark.parametrize(
    ("body", "loc"),
    [
        ({"objective": "beauty"}, ["body", "objective"]),
        ({"reach": -1}, ["body", "reach"]),
        ({"reach": "NaN"}, ["body", "reach"]),
        ({"L1_bounds": [0.5, 0.1]}, ["body", "L1_bounds"]),
        ({"L0_bounds": [0.1]}, ["body", "L0_bounds"]),
        ({"L2_bounds": [-0.1, 0.3]}, ["body", "L2_bounds", 0]),
        ({"reach": None}, ["body", "L1_bounds"]),
        ({"reach": None, "L1_bounds": [0.1, 0.2]}, ["body", "L2_bounds"]),
        ({"reach": 0.8, "L1_bounds": [0.9, 1.0]}, ["body", "L1_bounds"]),
        ({"n_samples": 10**9}, ["body", "n_samples"]),
        ({"maxiter": 10_000}, ["body", "maxiter"]),
        ({"kappa_max": 0.1}, ["body", "kappa_max"]),
        (
            {"design": {"joint_min": [0, 0, 0], "joint_max": [0, 1, 1]}},
            ["body", "design", "joint_max"],
        ),
        ({"budget": 5}, ["body", "budget"]),
    ],
)
def test_bad_optimize_requests_are_422_naming_the_field(api, body, loc):
    r = api.post("/v1/design/optimize", json=body)
    assert r.status_code == 422, r.text
    assert loc in [item["loc"] for item in r.json()["detail"]]
