"""A moving target (a part on a belt) over HTTP: ``/v1/sequence`` meets it and says when and
where (``meet_time``, ``meet_point``: the part's own position then, by the request's numbers);
the bad inputs of the issue answered 422 by name."""

from __future__ import annotations

import numpy as np
import pytest

START = {"q": [1.98902066, 1.68682059, -0.4043776], "assembly_mode": "+"}  # P at the bin
BIN = [-0.2, 0.25, -0.45]
PART = {"p": [-0.7, 0.0, -0.45], "velocity": [0.5, 0.0, 0.0], "t0": 0.0}


def body(part: dict | None = None, dwell: float = 0.2) -> dict:
    return {
        "start": START,
        "targets": [{"goal": part or PART, "dwell": dwell}, {"goal": {"p": BIN}}],
        "timing": {"sample_rate_hz": 200},
    }


def test_a_part_on_a_belt_is_met_and_the_leg_says_when_and_where(api):
    r = api.post("/v1/sequence", json=body())
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["status"] == "solved", out["message"]
    leg = out["legs"][0]
    t = leg["meet_time"]
    expected = np.array(PART["p"]) + np.array(PART["velocity"]) * (t - PART["t0"])
    assert np.allclose(leg["meet_point"], expected, atol=1e-9)
    assert leg["end_time"] == pytest.approx(t)
    assert out["legs"][1]["meet_time"] is None and out["legs"][1]["meet_point"] is None
    assert out["cycle_time"] > t + 0.2


@pytest.mark.parametrize(
    ("path", "request_body", "loc"),
    [
        (
            "/v1/sequence",
            body({**PART, "velocity": [2.5, 0.0, 0.0]}),
            ["body", "targets", 0, "goal", "velocity"],
        ),
        ("/v1/sequence", body(dwell=-0.1), ["body", "targets", 0, "dwell"]),
        (
            "/v1/plan",
            {"start": START, "goal": PART},
            ["body", "goal", "velocity"],
        ),
    ],
)
def test_bad_belt_input_is_a_422_naming_the_field(api, path, request_body, loc):
    r = api.post(path, json=request_body)
    assert r.status_code == 422, r.text
    assert any(d["loc"][: len(loc)] == loc for d in r.json()["detail"]), r.text
