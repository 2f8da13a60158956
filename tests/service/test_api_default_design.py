"""PLANNER_DEFAULT_DESIGN: the robot of requests that send no design (or part of one)."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from planner import Design, Manipulator
from planner_api.settings import Settings


@pytest.fixture
def optimum_client(api_with):
    """The session's warm service, its default design the paper's optimum (the routes read
    it per request)."""
    return api_with(default_design="paper-optimum")


def test_absent_design_is_the_configured_preset(optimum_client):
    q = [0.3, 0.4, 2.0]
    r = optimum_client.post("/v1/fk", json={"q": q, "assembly_mode": "+"})
    assert r.status_code == 200, r.text
    expected = Manipulator(Design.paper_optimum()).posture(q, "+").p
    assert np.allclose(r.json()["postures"][0]["p"], expected, atol=1e-12)
    # the built-in default robot would put P elsewhere
    assert not np.allclose(expected, Manipulator(Design.default()).posture(q, "+").p)


def test_partial_design_takes_the_rest_from_the_configured_robot(optimum_client):
    r = optimum_client.post("/v1/design/check", json={"design": {"L0": 0.1}})
    assert r.status_code == 200, r.text
    body = r.json()
    # L0 = 0.1 with the optimum's L1 = L2 = 0.4: 2 L1 > L0, so C = D can occur
    assert "C=D" in body["parallel_singularities"]
    assert body["singularity_free"] is False


def test_merged_design_breaking_a_rule_is_a_422_naming_the_field(api_with):
    client = api_with(default_design='{"L1": 0.3, "L2": 0.4, "joint_max": [1, 1, 1]}')
    r = client.post("/v1/fk", json={"design": {"joint_min": [2, 0, 0]}, "q": [0.5, 0.5, 0.5]})
    assert r.status_code == 422
    locs = [tuple(d["loc"]) for d in r.json()["detail"]]
    assert any(loc[:2] == ("body", "design") for loc in locs), locs


@pytest.mark.parametrize("value", ["elbow", '{"L1": -1}', "{not json"])
def test_bad_default_design_setting_is_refused(value):
    with pytest.raises(ValidationError, match="default_design"):
        Settings(default_design=value)
