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


def _jobs_run(api, job: str) -> float:
    """How many ``job`` jobs the service's workers have reported (``/metrics``: the duration
    each worker process measures around a job and sends back with its answer)."""
    for line in api.get("/metrics").text.splitlines():
        if line.startswith(f'planner_job_duration_seconds_count{{job="{job}"}}'):
            return float(line.rsplit(maxsplit=1)[1])
    return 0.0


def test_design_check_runs_in_a_worker_and_names_bad_fields(api):
    """The check of a design that is not the default one is computed by a worker on that
    design: one more ``design_check`` job reported by a worker, the answer's design the one
    sent, its closed-form volume and singularities those of docs/conventions.md for its
    lengths, its sampled volume cut by its joint limits (and not without them).

    Mutants caught: the job checking ``Design.default()`` instead of the request's design
    (the old test sent the default design and passed it), the route computing the answer
    in the serving process (no worker reports the job), and the job dropping the joint limits
    (``Design(L0, L1, L2)``)."""
    # L0 = 0 <= 2 L1: C = D occurs; L0 + 2 L1 = 0.5 < 2 L2 = 0.7: CD never stretches
    lengths = {"L0": 0.0, "L1": 0.25, "L2": 0.35}
    limited = {**lengths, "joint_min": [-1.0, -2.0, -3.0], "joint_max": [1.0, 2.0, 3.0]}
    # L0 = 0: the workspace is the shell between r = |L1 - L2| and R = L1 + L2
    shell = 4.0 / 3.0 * math.pi * (0.6**3 - 0.1**3)
    before = _jobs_run(api, "design_check")
    r = api.post("/v1/design/check", json={"design": limited, "rel_se": 0.05})
    assert r.status_code == 200, r.text
    assert _jobs_run(api, "design_check") >= before + 1  # (+2 if a long job ends meanwhile)
    body = r.json()
    assert body["design"] == {**limited, "link_radius": 0.02}
    assert body["volume"] == pytest.approx(shell, rel=1e-9)
    assert body["parallel_singularities"] == ["C=D"] and body["singularity_free"] is False
    cut = body["sampled_volume"]
    assert cut["value"] + 5 * cut["standard_error"] < 0.8 * shell  # the limits were applied
    r = api.post("/v1/design/check", json={"design": lengths, "rel_se": 0.05})
    full = r.json()["sampled_volume"]
    assert full["value"] == pytest.approx(shell, abs=5 * full["standard_error"] + 0.01 * shell)
    r = api.post(
        "/v1/design/check",
        content=b'{"design": {"L2": NaN}}',
        headers={"content-type": "application/json"},
    )
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "design", "L2"]
