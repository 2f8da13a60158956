"""POST /v1/calibrate, /v1/calibrate/poses and /v1/identify, the client's methods and the CLI's
calibrate and identify: answers against the library, bad input as 422s naming the field."""

from __future__ import annotations

import json

import numpy as np
import pytest
from calibration_factories import NOMINAL, measure, random_valid, true_parameters
from typer.testing import CliRunner

from planner.dynamics import Inertia, inverse_dynamics
from planner_cli import app


def _body(n: int = 20, seed: int = 31, noise: float = 0.0) -> tuple[dict, np.ndarray]:
    full = true_parameters(seed=seed)
    q, modes = random_valid(n, seed=seed + 1)
    m = measure(full, q, modes, noise=noise)
    rows = [{"q": qi.tolist(), "p": pi.tolist()} for qi, pi in zip(m.q, m.p, strict=True)]
    return {"measurements": rows}, full


def _loc(r) -> list:
    assert r.status_code == 422, r.text
    return r.json()["detail"][0]["loc"]


def test_calibrate_endpoint_recovers_the_robot(api) -> None:
    body, full = _body()
    r = api.post("/v1/calibrate", json=body)
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["design"]["L0"] == pytest.approx(full[0], abs=1e-9)
    assert out["offsets"][1:] == pytest.approx(full[6:8].tolist(), abs=1e-9)
    assert out["unidentified"] == ["offsets[0]"]
    assert out["residual_max_m"] < 1e-10
    assert set(out["std"]) == {"L0", "L1", "L2", "offsets[1]", "offsets[2]"} | {
        f"frame.{k}[{i}]" for k in ("position", "rotation") for i in range(3)
    }
    assert out["provenance"]["measurements"] == 20
    assert out["condition_number"] > 1


def _nan(body: dict) -> None:
    body["measurements"][3]["p"][1] = float("nan")


def _few(body: dict) -> None:
    body["measurements"] = body["measurements"][:3]


def _colour(body: dict) -> None:
    body["identify"] = ["lengths", "colour"]


def _short(body: dict) -> None:
    """Distal links too short for measurement 0 (|CD| = 0.9 m > 2 L2)."""
    body["design"] = {"L0": 0.5, "L1": 0.2, "L2": 0.3}
    body["measurements"][0]["q"] = [0.0, 3.14159, 0.0]
    for row in body["measurements"][1:]:
        row["q"] = [0.0, 2.0, 1.0]


def _mode(body: dict) -> None:
    body["measurements"][2]["working_mode"] = "+x+"


CASES = [
    (_nan, ["body", "measurements", 3, "p", 1]),
    (_few, ["body", "measurements"]),
    (_colour, ["body", "identify", 1]),
    (_short, ["body", "measurements", 0, "q"]),
    (_mode, ["body", "measurements", 2, "working_mode"]),
]


@pytest.mark.parametrize(("change", "loc"), CASES, ids=[c.__name__ for c, _ in CASES])
def test_calibrate_bad_input_is_a_422_naming_the_field(api, change, loc) -> None:
    body, _ = _body()
    change(body)
    raw = json.dumps(body)  # NaN written as the bare token NaN, which JSON does not allow
    r = api.post("/v1/calibrate", content=raw, headers={"content-type": "application/json"})
    assert _loc(r)[: len(loc)] == loc


def test_poses_and_identify_endpoints(api) -> None:
    r = api.post("/v1/calibrate/poses", json={"n": 12})
    assert r.status_code == 200, r.text
    postures = r.json()["postures"]
    assert len(postures) == 12 and len({p["working_mode"] for p in postures}) >= 2
    rng = np.random.default_rng(0)
    q = np.array([0.0, 2.0, 1.0]) + rng.uniform(-0.5, 0.5, size=(60, 3))
    qd, qdd = rng.normal(0, 2, size=q.shape), rng.normal(0, 8, size=q.shape)
    prior = Inertia.default(NOMINAL)
    tau = inverse_dynamics(NOMINAL, prior, q, qd, qdd).tau
    body = {"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist(), "tau": tau.tolist()}
    r = api.post("/v1/identify", json={**body, "friction": True})
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["residual_rms"] < 1e-9 and out["friction"]["viscous"] == pytest.approx(
        [0, 0, 0], abs=1e-9
    )
    assert "proximal.mass" in out["unidentified"]
    # the answer's inertia is a design.inertia the dynamics endpoint accepts as it is
    three = {k: body[k][:3] for k in ("q", "qd", "qdd")}
    r2 = api.post("/v1/dynamics", json={**three, "design": {"inertia": out["inertia"]}})
    assert r2.status_code == 200, r2.text
    np.testing.assert_allclose(r2.json()["tau"], tau[:3], atol=1e-8)
    bad = {**body, "tau": body["tau"][:-1]}
    assert _loc(api.post("/v1/identify", json=bad)) == ["body", "tau"]
    nan = json.loads(json.dumps(body))
    nan["qd"][5][0] = None
    assert _loc(api.post("/v1/identify", json=nan))[:3] == ["body", "qd", 5]


def test_client_calibrate(api) -> None:
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

    body, full = _body(seed=41)
    with PlannerClient("http://x", transport=httpx.MockTransport(forward)) as client:
        out = client.calibrate(body["measurements"], identify=["lengths", "offsets", "frame"])
        poses = client.calibration_poses(5)
    assert out.design.L2 == pytest.approx(full[3], abs=1e-9)
    assert len(poses.postures) == 5


def test_cli_calibrate_suggest_and_export(tmp_path) -> None:
    runner = CliRunner()
    r = runner.invoke(app, ["calibrate", "--suggest", "6"])
    assert r.exit_code == 0, r.output
    assert len(json.loads(r.output)["postures"]) == 6
    body, full = _body(seed=51, noise=5e-5)
    path = tmp_path / "m.json"
    path.write_text(json.dumps(body["measurements"]))  # a bare list of measurements
    out, xml = tmp_path / "model.json", tmp_path / "robot.xml"
    r = runner.invoke(app, ["calibrate", str(path), "--output", str(out), "--mjcf", str(xml)])
    assert r.exit_code == 0, r.output
    model = json.loads(out.read_text())
    assert model["design"]["L1"] == pytest.approx(full[1], abs=1e-4)
    text = xml.read_text()
    assert "identified by planner calibrate" in text and "20 measurements" in text
    mujoco = pytest.importorskip("mujoco")
    mujoco.MjModel.from_xml_string(text)  # the export loads


def test_fourth_part_calibration_vocabulary() -> None:
    """docs/conventions.md, "Wire, fourth part" (Calibration): the fixed names."""
    from planner.wire import (
        CalibrateRequest,
        CalibrateResponse,
        FrameModel,
        IdentifyRequest,
        IdentifyResponse,
        MeasurementModel,
    )

    assert {"design", "measurements", "identify"} <= set(CalibrateRequest.model_fields)
    assert set(MeasurementModel.model_fields) == {"q", "p", "working_mode", "assembly_mode"}
    assert CalibrateRequest.model_fields["identify"].default_factory() == [
        "lengths",
        "offsets",
        "frame",
    ]
    assert {
        "design",
        "offsets",
        "frame",
        "residual_rms_m",
        "residual_max_m",
        "std",
        "condition_number",
        "unidentified",
    } <= set(CalibrateResponse.model_fields)
    assert set(FrameModel.model_fields) == {"position", "rotation"}
    assert {"design", "gravity", "assembly_mode", "q", "qd", "qdd", "tau", "friction"} == set(
        IdentifyRequest.model_fields
    )
    assert {"inertia", "friction", "residual_rms", "unidentified"} <= set(
        IdentifyResponse.model_fields
    )
