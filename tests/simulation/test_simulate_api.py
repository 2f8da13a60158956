"""POST /v1/simulate through the service: a trajectory and a plan request simulated in a
worker, and bad input answered with a 422 naming the field."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from simulation_factories import quintic_move

from planner import Design, forward_batch


def _trajectory(duration: float = 0.2) -> dict:
    t, q, qd, qdd = quintic_move(duration=duration)
    return {"t": t.tolist(), "q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist()}


def test_a_trajectory_is_simulated(api) -> None:
    r = api.post("/v1/simulate", json={"trajectory": _trajectory(), "hold_s": 0.1})
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["engine"] == f"mujoco {mujoco.__version__}"
    assert body["controller"] == "computed_torque" and body["rate_hz"] == 1000
    n = len(body["t"])
    assert all(len(body[k]) == n for k in ("q", "qd", "tau", "p", "p_error_mm"))
    assert body["tracking"]["p_max_mm"] < 1e-2 and len(body["tracking"]["q_max"]) == 3
    assert body["planned_duration"] == pytest.approx(0.2)
    assert body["realised_duration"] == pytest.approx(0.2)
    assert body["settle_times"] == [0.0] and body["stops"][-1]["final"]
    # the realised P is the product's forward kinematics of the realised q (2e-8 m: the
    # loop's softness), and p_error_mm is its distance to the reference's P
    q = np.asarray(body["q"])
    np.testing.assert_allclose(body["p"], forward_batch(Design.default(), q, "+").p, atol=2e-8)
    assert body["trajectory"] is None


def test_a_plan_request_is_planned_then_simulated_with_saturation(api) -> None:
    """A plan request with torque limits: planned at the control rate (its samples are the
    controller's), simulated on its robot; the applied torques within the limits."""
    request = {
        "start": {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"},
        "goal": {"q": [0.3, 2.2, 0.9], "assembly_mode": "+"},
        "limits": {"torque": [20.0, 10.0, 10.0]},
    }
    r = api.post("/v1/simulate", json={"request": request, "controller": {"kind": "pd"}})
    assert r.status_code == 200, r.text
    body = r.json()
    planned = body["trajectory"]
    assert planned is not None and np.allclose(np.diff(planned["t"])[:-1], 1e-3)
    assert body["planned_duration"] == pytest.approx(planned["t"][-1] - planned["t"][0])
    tau = np.abs(np.asarray(body["tau"]))
    assert np.all(tau <= np.array([20.0, 10.0, 10.0]) + 1e-9)
    assert body["controller"] == "pd" and body["tracking"]["p_max_mm"] > 0


def test_a_sequence_request_is_simulated_with_a_settle_time_per_stop(api) -> None:
    """A sequence with two stops and its return (cycle): the answer's stops are the
    reference's rests, one settle time each, all settled with computed torque."""
    goals = ([0.2, 2.1, 0.9], [0.0, 2.2, 1.1])
    request = {
        "start": {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"},
        "targets": [{"goal": {"q": q, "assembly_mode": "+"}} for q in goals],
        "cycle": True,
    }
    r = api.post("/v1/simulate", json={"request": request, "hold_s": 0.1})
    assert r.status_code == 200, r.text
    body = r.json()
    assert len(body["stops"]) == 3 and len(body["settle_times"]) == 3
    assert all(s is not None and s <= 2e-3 for s in body["settle_times"])
    assert body["tracking"]["p_max_mm"] < 0.1


@pytest.mark.parametrize(
    ("change", "loc"),
    [
        ({"controller": {"kind": "lqr"}}, ["body", "controller", "kind"]),
        ({"controller": {"kp": [1, -1, 1]}}, ["body", "controller", "kp", 1]),
        ({"rate_hz": 5}, ["body", "rate_hz"]),
        ({"limits": {"torque": [1, 0, 1]}}, ["body", "limits", "torque", 1]),
        ({"design": {"L2": 0.3}}, ["body", "trajectory", "q", 0]),  # does not assemble
        ({"trajectory": {**_trajectory(), "qd": [[0, 0, 0]]}}, ["body", "trajectory", "qd"]),
        ({"trajectory": {**_trajectory(), "t": [0.0] * 201}}, ["body", "trajectory", "t"]),
        ({"trajectory": {**_trajectory(), "p": []}}, ["body", "trajectory", "p"]),
        ({"trajectory": None}, ["body", "trajectory"]),
        ({"hold_s": 10.0, "rate_hz": 10_000, "trajectory": {
            "t": [0.0, 20.0], "q": [[0, 2, 1]] * 2, "qd": [[0] * 3] * 2, "qdd": [[0] * 3] * 2}},
         ["body", "rate_hz"]),  # 300,000 samples: over the bound
        ({"request": {"start": {"q": [0, 2, 1], "assembly_mode": "+"},
                     "goal": {"q": [0.1, 2, 1], "assembly_mode": "+"}}},
         ["body", "trajectory"]),  # both
        ({"trajectory": None, "gravity": [0, 0, -1],
          "request": {"start": {"q": [0, 2, 1], "assembly_mode": "+"},
                     "goal": {"q": [0.1, 2, 1], "assembly_mode": "+"}}},
         ["body", "gravity"]),  # the robot is the request's
    ],
)  # fmt: skip
def test_bad_input_is_a_422_at_the_field(api, change, loc) -> None:
    body = {"trajectory": _trajectory(), "hold_s": 0.0, **change}
    body = {k: v for k, v in body.items() if v is not None}
    r = api.post("/v1/simulate", json=body)
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["loc"][: len(loc)] == loc, r.json()


def test_the_bag_route_and_the_client_give_the_runs_bag(api) -> None:
    """POST /v1/simulate/bag: the MCAP bytes of the same run (read back: the realised q of
    POST /v1/simulate's answer, the followed trajectory's q); the client's simulate takes a
    plan's answer trajectory (arrays form, with its extra fields) and simulate_bag the same
    arguments, both through the service."""
    import io

    import httpx

    from planner.client import PlannerClient
    from planner.simulation.bag import read_bag

    body = {"trajectory": _trajectory(0.1), "hold_s": 0.05}
    answer = api.post("/v1/simulate", json=body).json()
    r = api.post("/v1/simulate/bag", json=body)
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == "application/octet-stream"
    back = read_bag(io.BytesIO(r.content))
    assert back.realised is not None and back.trajectory is not None
    np.testing.assert_array_equal(back.realised["q"], answer["q"])
    np.testing.assert_array_equal(back.trajectory["q"], body["trajectory"]["q"])
    bad = api.post("/v1/simulate/bag", json={**body, "controller": {"kind": "lqr"}})
    assert bad.status_code == 422
    assert bad.json()["detail"][0]["loc"] == ["body", "controller", "kind"]

    def forward(request: httpx.Request) -> httpx.Response:
        out = api.request(
            request.method,
            request.url.path,
            content=request.content,
            headers={"content-type": "application/json"},
        )
        return httpx.Response(out.status_code, content=out.content, headers=out.headers)

    plan_like = {**body["trajectory"], "duration": 0.1, "p": [[0, 0, 0]] * 101}
    with PlannerClient("http://x", transport=httpx.MockTransport(forward)) as client:
        sim = client.simulate(plan_like, hold_s=0.05)
        bag = client.simulate_bag(plan_like, hold_s=0.05)
    assert sim.q == answer["q"]
    assert read_bag(io.BytesIO(bag)).realised["q"].tolist() == answer["q"]
