"""POST /v1/dynamics, design.inertia and gravity on the wire, torque-limited plans and timing,
the client's dynamics() and the CLI's dynamics and mjcf: answers against the library, bad
input as 422s naming the field and the rule."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from planner import Design
from planner.dynamics import Inertia, LinkInertia, inverse_dynamics
from planner_cli import app

Q = [[0.0, 2.0, 1.0], [0.4, 2.2, 1.1], [-0.5, 1.8, 0.7]]
QD = [[0.3, -0.2, 0.5], [0.0, 0.0, 0.0], [1.0, 1.0, -1.0]]
QDD = [[1.0, 2.0, -3.0], [0.0, 0.0, 0.0], [-2.0, 0.5, 4.0]]
INERTIA = {
    "proximal": {"mass": 0.7, "com": 0.3, "I_perp": 0.004, "I_axial": 0.0075},
    "distal": {"mass": 1.1, "com": 0.65, "I_perp": 0.02, "I_axial": 0.001},
    "payload": {"mass": 0.8},
    "base": {"inertia": 0.03},
    "rotor": [0.002, 0.001, 0.003],
}
LIB_INERTIA = Inertia(
    LinkInertia(0.7, 0.3, 0.004, 0.0075),
    LinkInertia(1.1, 0.65, 0.02, 0.001),
    0.8,
    0.03,
    (0.002, 0.001, 0.003),
)


def _loc(r) -> list:
    assert r.status_code == 422, r.text
    return r.json()["detail"][0]["loc"]


def test_dynamics_endpoint_answers_the_library(api) -> None:
    body = {
        "q": Q,
        "qd": QD,
        "qdd": QDD,
        "gravity": [0.0, 1.0, -9.81],
        "assembly_mode": "-",
        "design": {"inertia": INERTIA},
    }
    r = api.post("/v1/dynamics", json=body)
    assert r.status_code == 200, r.text
    out = r.json()
    ref = inverse_dynamics(
        Design.default(),
        LIB_INERTIA,
        np.array(Q),
        np.array(QD),
        np.array(QDD),
        assembly_mode="-",
        gravity=(0.0, 1.0, -9.81),
        with_mass_matrix=True,
    )
    np.testing.assert_allclose(out["tau"], ref.tau, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(out["mass_matrix"], ref.mass_matrix, rtol=1e-12, atol=1e-14)
    # absent inertia: the documented defaults; a part given alone keeps the others' defaults
    default = api.post("/v1/dynamics", json={"q": Q, "qd": QD, "qdd": QDD}).json()
    ref = inverse_dynamics(
        Design.default(),
        Inertia.default(Design.default()),
        np.array(Q),
        np.array(QD),
        np.array(QDD),
    )
    np.testing.assert_allclose(default["tau"], ref.tau, rtol=1e-12, atol=1e-12)
    part = api.post(
        "/v1/dynamics",
        json={"q": Q, "qd": QD, "qdd": QDD, "design": {"inertia": {"payload": {"mass": 2.0}}}},
    )
    heavier = np.array(part.json()["mass_matrix"]) - np.array(default["mass_matrix"])
    assert np.all(np.linalg.eigvalsh(heavier) > -1e-12) and np.max(heavier) > 0.05


def test_a_singular_posture_is_a_422_naming_it(api) -> None:
    body = {
        "q": [[0.0, 1.0, 1.3], [0.0, 1.0, 1.0]],
        "qd": [[0, 0, 0]] * 2,
        "qdd": [[0, 0, 0]] * 2,
        "design": {"L0": 0.0, "L1": 0.4, "L2": 0.4},
    }
    r = api.post("/v1/dynamics", json=body)
    assert _loc(r) == ["body", "q", 1]
    assert "singular" in r.json()["detail"][0]["msg"]


@pytest.mark.parametrize(
    ("inertia", "loc", "words"),
    [
        ({"proximal": {"mass": -1, "com": 0.5, "I_perp": 1, "I_axial": 1}},
         ["proximal", "mass"], "greater than or equal"),
        ({"distal": {"mass": 1, "com": 1.5, "I_perp": 1, "I_axial": 1}},
         ["distal", "com"], "less than or equal"),
        ({"distal": {"mass": 1, "com": 0.5, "I_perp": 0.1, "I_axial": 0.3}},
         ["distal", "I_axial"], "triangle inequality"),
        ({"base": {"inertia": -0.1}}, ["base", "inertia"], "greater than or equal"),
        ({"payload": {"mass": 1e9}}, ["payload", "mass"], "less than or equal"),
        ({"rotor": [0.1, -1, 0.1]}, ["rotor", 1], "greater than or equal"),
    ],
)  # fmt: skip
def test_bad_inertia_is_a_422_naming_the_field(api, inertia, loc, words) -> None:
    body = {"q": Q[:1], "qd": QD[:1], "qdd": QDD[:1], "design": {"inertia": inertia}}
    r = api.post("/v1/dynamics", json=body)
    assert _loc(r)[:4] == ["body", "design", "inertia", loc[0]]
    assert _loc(r)[4:] == loc[1:]
    assert words in r.json()["detail"][0]["msg"]


@pytest.mark.parametrize(
    ("change", "loc"),
    [
        ({"gravity": [0, 0, 1e5]}, ["body", "gravity", 2]),
        ({"gravity": [0, 0]}, ["body", "gravity"]),
        ({"qd": QD[:2]}, ["body", "qd"]),
        ({"qdd": [[0, 0, "x"]] * 3}, ["body", "qdd", 0, 2]),
        ({"q": []}, ["body", "q"]),
    ],
)
def test_bad_motions_and_gravity_are_422s(api, change, loc) -> None:
    body = {"q": Q, "qd": QD, "qdd": QDD, **change}
    assert _loc(api.post("/v1/dynamics", json=body)) == loc


def test_plan_with_torque_limits_carries_tau_and_the_ratio(api) -> None:
    """A torque-limited plan: tau in the arrays form (= the library's torques of the samples),
    effort in the points form, max_torque_ratio <= 1; gravity alone above a limit at the
    start is invalid_start naming the joint; a zero limit is a 422 at limits.torque.0."""
    base = {"start": {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"},
            "goal": {"q": [0.8, 2.3, 1.2], "assembly_mode": "+"},
            "limits": {"velocity": [3, 3, 3], "acceleration": [30, 30, 30],
                       "torque": [9.0, 2.0, 2.0]}}  # fmt: skip
    out = api.post("/v1/plan", json=base).json()
    assert out["status"] == "solved", out["message"]
    traj = out["trajectory"]
    ref = inverse_dynamics(
        Design.default(),
        Inertia.default(Design.default()),
        np.array(traj["q"]),
        np.array(traj["qd"]),
        np.array(traj["qdd"]),
    )
    np.testing.assert_allclose(traj["tau"], ref.tau, atol=1e-9)
    assert 0.9 < out["diagnostics"]["max_torque_ratio"] <= 1.0 + 1e-6
    points = api.post("/v1/plan", json={**base, "timing": {"format": "points"}}).json()
    efforts = [p["effort"] for p in points["trajectory"]["points"]]
    np.testing.assert_allclose(efforts, traj["tau"], atol=1e-12)
    weak = {**base, "limits": {**base["limits"], "torque": [5.0, 2.0, 2.0]}}
    held = api.post("/v1/plan", json=weak).json()
    assert held["status"] == "invalid_start" and "tau1| = 6.67" in held["message"]
    zero = {**base, "limits": {**base["limits"], "torque": [0.0, 2.0, 2.0]}}
    assert _loc(api.post("/v1/plan", json=zero)) == ["body", "limits", "torque", 0]
    plain = api.post("/v1/plan", json={**base, "limits": {}}).json()
    assert plain["trajectory"]["tau"] is None and plain["diagnostics"]["max_torque_ratio"] is None
    with_inertia = api.post(
        "/v1/plan", json={**base, "limits": {}, "design": {"inertia": INERTIA}}
    ).json()
    assert with_inertia["trajectory"]["tau"] is not None


def test_timing_endpoint_with_torque_limits(api) -> None:
    body = {
        "waypoints": [[0, 2.0, 1.0], [0.8, 2.3, 1.2], [1.5, 1.9, 0.9]],
        "method": "ruckig",
        "gravity": [0, 0, -9.81],
        "limits": {
            "velocity": [3, 3, 3],
            "acceleration": [30, 30, 30],
            "jerk": [500, 500, 500],
            "torque": [9.0, 2.0, 2.0],
        },
    }
    out = api.post("/v1/timing", json=body).json()
    assert out["status"] == "solved", out["message"]
    assert out["diagnostics"]["max_torque_ratio"] <= 1.0 + 1e-6
    assert np.max(np.abs(out["trajectory"]["tau"]) / [9.0, 2.0, 2.0]) <= 1.0 + 1e-6


def test_client_dynamics(api) -> None:
    """The typed client's dynamics() builds the body and reads the answer (through a
    transport that hands each request to the session's service)."""
    import httpx

    from planner.client import PlannerClient

    def forward(request: httpx.Request) -> httpx.Response:
        r = api.request(
            request.method,
            request.url.path,
            content=request.content,
            headers={"content-type": "application/json"},
        )
        return httpx.Response(r.status_code, content=r.content, headers=r.headers)

    with PlannerClient("http://x", transport=httpx.MockTransport(forward)) as client:
        out = client.dynamics(Q, QD, QDD, design={"inertia": INERTIA}, gravity=[0, 0, -9.81])
    ref = inverse_dynamics(Design.default(), LIB_INERTIA, np.array(Q), np.array(QD), np.array(QDD))
    np.testing.assert_allclose(out.tau, ref.tau, rtol=1e-12, atol=1e-12)


def test_cli_dynamics_and_mjcf(tmp_path) -> None:
    runner = CliRunner()
    r = runner.invoke(app, ["dynamics", "0", "2", "1", "--qdd", "1,0,0"])
    assert r.exit_code == 0, r.output
    tau = json.loads(r.output)["tau"][0]
    ref = inverse_dynamics(
        Design.default(),
        Inertia.default(Design.default()),
        np.array([0, 2.0, 1.0]),
        np.zeros(3),
        np.array([1.0, 0, 0]),
    ).tau[0]
    np.testing.assert_allclose(tau, ref, rtol=1e-12)
    bad = runner.invoke(app, ["dynamics", "0", "2", "1", "--qd", "1,2"])
    assert bad.exit_code == 2 and "--qd" in bad.output
    out = tmp_path / "robot.xml"
    r = runner.invoke(app, ["mjcf", "--output", str(out), "--design", "singularity-free"])
    assert r.exit_code == 0, r.output
    assert "<connect" in out.read_text() and 'site1="tip_C"' in out.read_text()
    r = runner.invoke(app, ["mjcf", "--home", "0,3.14159,0", "--L2", "0.3"])  # |CD| > 2 L2
    assert r.exit_code == 2 and "home" in r.output


def test_cli_plan_csv_has_the_torque_columns(tmp_path) -> None:
    from planner.timing.export import read_csv

    body = {"start": {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"},
            "goal": {"q": [0.8, 2.3, 1.2], "assembly_mode": "+"},
            "limits": {"torque": [9.0, 2.0, 2.0]}}  # fmt: skip
    request = tmp_path / "plan.json"
    request.write_text(json.dumps(body))
    out, csv = tmp_path / "answer.json", tmp_path / "traj.csv"
    r = CliRunner().invoke(app, ["plan", str(request), "--out", str(out), "--csv", str(csv)])
    assert r.exit_code == 0, r.output
    header = csv.read_text().splitlines()[1].split(",")
    assert header[-3:] == ["tau1", "tau2", "tau3"]
    arrays = read_csv(csv)
    np.testing.assert_array_equal(arrays.tau, json.loads(out.read_text())["trajectory"]["tau"])


def test_cartesian_with_torque_limits_and_an_inertia(api) -> None:
    """A straight tool path timed under torque limits with the request's inertia and
    gravity: tau equals the library's torques of the samples with that inertia."""
    start = {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"}
    p0 = api.post("/v1/fk", json={"q": start["q"], "assembly_mode": "+"}).json()
    p = np.array(p0["postures"][0]["p"])
    body = {
        "start": start,
        "waypoints": [(p + np.array([0.05, 0.0, 0.05])).tolist()],
        "design": {"inertia": INERTIA},
        "gravity": [0.0, 0.0, -5.0],
        "limits": {"torque": [20.0, 8.0, 8.0]},
    }
    out = api.post("/v1/cartesian", json=body).json()
    assert out["status"] == "solved", out["message"]
    traj = out["trajectory"]
    ref = inverse_dynamics(
        Design.default(),
        LIB_INERTIA,
        np.array(traj["q"]),
        np.array(traj["qd"]),
        np.array(traj["qdd"]),
        gravity=(0, 0, -5.0),
    )
    np.testing.assert_allclose(traj["tau"], ref.tau, atol=1e-9)
    assert out["diagnostics"]["max_torque_ratio"] <= 1.0 + 1e-6


def test_cartesian_start_held_by_gravity_is_invalid_start(api) -> None:
    """/v1/cartesian answers a start where gravity alone needs more than a torque limit as
    invalid_start naming the joint and the value, as /v1/plan does (the same gravity torque
    as the library's inverse dynamics at rest there), before any timing."""
    start = {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"}
    p0 = api.post("/v1/fk", json={"q": start["q"], "assembly_mode": "+"}).json()
    p = np.array(p0["postures"][0]["p"])
    body = {
        "start": start,
        "waypoints": [(p + np.array([0.05, 0.0, 0.05])).tolist()],
        "limits": {"torque": [5.0, 2.0, 2.0]},
    }
    out = api.post("/v1/cartesian", json=body).json()
    held = inverse_dynamics(
        Design.default(),
        Inertia.default(Design.default()),
        np.array(start["q"]),
        np.zeros(3),
        np.zeros(3),
    ).tau[0]
    assert abs(held[0]) > 5.0  # the oracle: gravity alone breaks limits.torque[0]
    assert out["status"] == "invalid_start", out["message"]
    assert f"tau1| = {abs(held[0]):.6g} N m" in out["message"]
    assert "limits.torque[0] = 5 N m" in out["message"]
    assert out["trajectory"] is None and out["fraction"] == 0.0
    plan = api.post(
        "/v1/plan",
        json={
            "start": start,
            "goal": {"q": [0.8, 2.3, 1.2], "assembly_mode": "+"},
            "limits": body["limits"],
        },
    ).json()
    assert plan["status"] == "invalid_start" and plan["message"] == out["message"]
    untimed = api.post("/v1/cartesian", json={**body, "timing": {"method": "none"}}).json()
    assert untimed["status"] == "solved", untimed["message"]  # no timing, no torque rule


#: The sequence of issue 36 that answered 500 (gravity on theta1 above its limit where only
#: theta2 and theta3 move): now solved, its torque ratio reported.
ISSUE_36_SEQUENCE = {
    "design": {
        "L0": 0.3398,
        "L1": 0.346,
        "L2": 0.5009,
        "link_radius": 0.0112,
        "inertia": {
            "proximal": {"mass": 0.9459, "com": 0.5113, "I_perp": 0.0098, "I_axial": 0.0089},
            "distal": {"mass": 0.1268, "com": 0.6074, "I_perp": 0.0075, "I_axial": 0.0062},
            "payload": {"mass": 1.6038},
            "base": {"inertia": 0.0087},
            "rotor": [0.0026, 0.0016, 0.0027],
        },
    },
    "start": {"q": [-0.3249, 2.0669, -2.3286], "assembly_mode": "+"},
    "cycle": True,
    "margins": {"kappa_max": 10, "serial_min": 0.05, "clearance": 0.01},
    "limits": {
        "velocity": [2.0933, 2.3585, 2.4519],
        "acceleration": [6.5664, 17.4075, 13.3698],
        "torque": [8.6829, 9.4724, 12.4909],
    },
    "timing": {"method": "toppra", "sample_rate_hz": 100},
    "planner": {"seed": 2},
    "targets": [
        {"goal": {"p": [0.187, 0.1548, 0.0969]}, "stop": False, "blend": 0.03},
        {"goal": {"p": [0.187, -0.0993, 0.0969]}, "stop": False, "blend": 0.03},
        {"goal": {"p": [0.187, -0.0993, 0.063]}},
    ],
}


def test_random_sequences_with_inertia_and_torque_limits_never_answer_5xx(api) -> None:
    """Issue 36: the sequence that answered 500, then seeded variations of it (inertias,
    payloads, torque limits from tight to loose, both methods, stops and passes): every
    answer is a 200 (solved or a named failure) or a 422, never a 5xx; a solved one reports
    its max_torque_ratio, within the limit."""
    rng = np.random.default_rng(3603)
    bodies = [ISSUE_36_SEQUENCE]
    for i in range(5):
        body = json.loads(json.dumps(ISSUE_36_SEQUENCE))
        inertia = body["design"]["inertia"]
        for link in ("proximal", "distal"):
            inertia[link]["mass"] = float(rng.uniform(0.1, 1.5))
            i_perp = float(rng.uniform(0.002, 0.012))
            inertia[link]["I_perp"] = i_perp
            inertia[link]["I_axial"] = float(rng.uniform(0.1, 2.0) * i_perp)
        inertia["payload"]["mass"] = float(rng.uniform(0.0, 2.5))
        body["limits"]["torque"] = [float(x) for x in rng.uniform(2.0, 15.0, 3)]
        body["timing"]["method"] = ("toppra", "ruckig")[i % 2]
        if body["timing"]["method"] == "ruckig":
            body["limits"]["jerk"] = [300.0, 300.0, 300.0]
        for target in body["targets"][:2]:
            target["stop"] = bool(rng.uniform() < 0.3)
            target["blend"] = 0.0 if target["stop"] else float(rng.uniform(0.0, 0.04))
        bodies.append(body)
    solved = 0
    for body in bodies:
        r = api.post("/v1/sequence", json=body)
        assert r.status_code in (200, 422), r.text
        out = r.json()
        if r.status_code == 200 and out["status"] == "solved":
            solved += 1
            ratio = out["diagnostics"]["max_torque_ratio"]
            assert ratio is not None and ratio <= 1.0 + 1e-6
    assert solved >= 1
