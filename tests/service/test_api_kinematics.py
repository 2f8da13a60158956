"""POST /v1/fk, /v1/ik and /v1/analyze, checked against independent geometry: link lengths
of the returned joint centres, finite differences of P(q) through the API itself, numpy's
condition numbers, and the round trip ik -> fk."""

from __future__ import annotations

import math

import numpy as np
import pytest

PAPER_OPTIMUM = {"L0": 0.0, "L1": 0.4, "L2": 0.4}


def _fk(api, q, mode=None, design=None):
    body = {"q": list(q)}
    if mode is not None:
        body["assembly_mode"] = mode
    if design is not None:
        body["design"] = design
    r = api.post("/v1/fk", json=body)
    assert r.status_code == 200, r.text
    return r.json()["postures"]


def _check_geometry(posture, L0=0.5, L1=0.2, L2=0.6):
    pts = {k: np.array(v) for k, v in posture["points"].items()}
    assert np.allclose(pts["A"], [0, -L0 / 2, 0]) and np.allclose(pts["B"], [0, L0 / 2, 0])
    assert np.linalg.norm(pts["C"] - pts["A"]) == pytest.approx(L1, abs=1e-12)
    assert np.linalg.norm(pts["D"] - pts["B"]) == pytest.approx(L1, abs=1e-12)
    assert np.linalg.norm(pts["P"] - pts["C"]) == pytest.approx(L2, abs=1e-12)
    assert np.linalg.norm(pts["P"] - pts["D"]) == pytest.approx(L2, abs=1e-12)
    assert np.allclose(posture["p"], pts["P"], atol=1e-12)
    # the five points lie in the plane through AB turned by theta1 (normal (sin t1, 0, cos t1))
    t1 = posture["q"][0]
    normal = np.array([math.sin(t1), 0.0, math.cos(t1)])
    assert np.allclose([normal @ p for p in pts.values()], 0.0, atol=1e-12)


def test_fk_returns_both_assembly_modes_with_correct_link_lengths(api):
    postures = _fk(api, [0.3, 1.0, 2.0])
    assert [p["assembly_mode"] for p in postures] == ["+", "-"]
    for p in postures:
        _check_geometry(p)
        # the assembly mode is the sign of sin(theta5 - theta4), from the returned passives
        t4, t5 = p["passive"]
        assert (math.sin(t5 - t4) > 0) == (p["assembly_mode"] == "+")
        assert p["within_limits"] is True


def test_fk_one_mode_and_non_assembling_q(api):
    (only,) = _fk(api, [0.0, 1.0, 2.0], "-")
    assert only["assembly_mode"] == "-"
    # C = D (theta2 = theta3 on the paper optimum, L0 = 0): P undetermined, no posture
    assert _fk(api, [0.0, 0.7, 0.7], design=PAPER_OPTIMUM) == []
    assert _fk(api, [0.0, 0.7, 0.7], "+", design=PAPER_OPTIMUM) == []


def test_fk_reports_joint_limits_literally(api):
    design = {"joint_min": [-1, -1, -1], "joint_max": [1, 1, 3]}
    (p,) = _fk(api, [0.5, 0.9, 2.5], "+", design=design)
    assert p["within_limits"] is True
    (p,) = _fk(api, [1.5, 0.9, 2.5], "+", design=design)
    assert p["within_limits"] is False


def test_ik_round_trips_through_fk(api):
    target = [0.25, 0.05, -0.3]
    r = api.post("/v1/ik", json={"p": target})
    assert r.status_code == 200
    postures = r.json()["postures"]
    assert len(postures) >= 2
    modes = [p["working_mode"] for p in postures]
    assert len(set(modes)) == len(modes)
    for p in postures:
        _check_geometry(p)
        assert np.allclose(p["p"], target, atol=1e-9)
        again = _fk(api, p["q"], p["assembly_mode"])
        assert np.allclose(again[0]["p"], target, atol=1e-9)
        assert again[0]["working_mode"] == p["working_mode"]
    # asking for one working mode returns just that one
    one = api.post("/v1/ik", json={"p": target, "working_mode": modes[-1]}).json()["postures"]
    assert [p["working_mode"] for p in one] == [modes[-1]]


def test_ik_out_of_reach_is_empty_not_an_error(api):
    r = api.post("/v1/ik", json={"p": [5.0, 0.0, 0.0]})
    assert r.status_code == 200 and r.json() == {"postures": []}


def test_ik_degenerate_point_is_422_naming_p(api):
    # erratum 6: P = A = B on the paper optimum, IK undetermined
    r = api.post("/v1/ik", json={"p": [0, 0, 0], "design": PAPER_OPTIMUM})
    assert r.status_code == 422
    (item,) = r.json()["detail"]
    assert item["loc"] == ["body", "p"] and item["type"] == "singular_posture"


def test_analyze_jacobians_match_finite_differences_of_fk(api):
    q = np.array([0.4, 1.1, 2.2])
    qd = np.array([0.3, -0.7, 0.5])
    r = api.post("/v1/analyze", json={"q": q.tolist(), "assembly_mode": "+", "qd": qd.tolist()})
    assert r.status_code == 200, r.text
    body = r.json()
    A, B = np.array(body["A"]), np.array(body["B"])
    h = 1e-6
    p_plus = np.array(_fk(api, q + h * qd, "+")[0]["p"])
    p_minus = np.array(_fk(api, q - h * qd, "+")[0]["p"])
    pd_fd = (p_plus - p_minus) / (2 * h)
    assert np.allclose(A @ pd_fd, B @ qd, atol=1e-7)
    assert np.allclose(body["pd"], pd_fd, atol=1e-7)
    assert body["det_A"] == pytest.approx(np.linalg.det(A), rel=1e-12)
    assert body["det_B"] == pytest.approx(np.linalg.det(B), rel=1e-12)
    # condition numbers by numpy's SVD route (2-norm)
    assert body["kappa_A"] == pytest.approx(np.linalg.cond(A), rel=1e-9)
    assert body["kappa_B"] == pytest.approx(np.linalg.cond(B), rel=1e-9)
    assert body["parallel_singular"] is False and body["serial_singular"] == []


def test_analyze_margins_from_the_points(api):
    q = [0.4, 1.1, 2.2]
    body = api.post("/v1/analyze", json={"q": q, "assembly_mode": "-"}).json()
    pts = {k: np.array(v) for k, v in body["posture"]["points"].items()}

    def sin_between(u, v):
        return np.linalg.norm(np.cross(u, v)) / (np.linalg.norm(u) * np.linalg.norm(v))

    leg_a = sin_between(pts["C"] - pts["A"], pts["P"] - pts["C"])
    leg_b = sin_between(pts["D"] - pts["B"], pts["P"] - pts["D"])
    on_axis = math.hypot(pts["P"][0], pts["P"][2]) / 0.8
    s = body["serial"]
    assert s["leg_A"] == pytest.approx(leg_a, abs=1e-12)
    assert s["leg_B"] == pytest.approx(leg_b, abs=1e-12)
    assert s["P_on_axis"] == pytest.approx(on_axis, abs=1e-12)
    assert s["min"] == pytest.approx(min(leg_a, leg_b, on_axis), abs=1e-12)
    assert s["nearest"] == ["P_on_axis", "leg_A", "leg_B"][int(np.argmin([on_axis, leg_a, leg_b]))]
    # parallel margin: angle between CP and DP folded to [0, pi/2]
    cp, dp = pts["P"] - pts["C"], pts["P"] - pts["D"]
    angle = math.acos(np.clip(cp @ dp / (np.linalg.norm(cp) * np.linalg.norm(dp)), -1, 1))
    assert body["parallel"] == pytest.approx(min(angle, math.pi - angle), abs=1e-9)
    assert body["posture"]["assembly_mode"] == "-"


def test_analyze_serial_singularity_P_on_axis(api):
    # a point on AB reached by the paper optimum: IK gives w = 0 postures
    post = api.post("/v1/ik", json={"p": [0.0, 0.5, 0.0], "design": PAPER_OPTIMUM}).json()
    # with L0 = 0 and L1 = L2 the modes with s_A = s_B put C on D (assembly '0'): skip them
    (posture, *_) = [p for p in post["postures"] if p["assembly_mode"] in "+-"]
    assert posture["working_mode"][0] == "0"
    r = api.post(
        "/v1/analyze",
        json={
            "q": posture["q"],
            "design": PAPER_OPTIMUM,
            "assembly_mode": posture["assembly_mode"],
        },
    )
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["posture"]["working_mode"] == posture["working_mode"]
    assert "P_on_axis" in body["serial_singular"]
    assert body["kappa_B"] is None  # infinite: written null
    assert body["det_B"] == pytest.approx(0.0, abs=1e-12)


def test_analyze_parallel_singularity_CD_stretched(api):
    # paper optimum, theta3 = theta2 + pi: C and D opposite, P the midpoint of a stretched CD
    body = api.post(
        "/v1/analyze",
        json={
            "q": [0.0, 0.0, math.pi],
            "assembly_mode": "+",
            "qd": [0.1, 0.1, 0.1],
            "design": PAPER_OPTIMUM,
        },
    )
    assert body.status_code == 200, body.text
    body = body.json()
    assert body["parallel_singular"] is True
    assert body["parallel"] == pytest.approx(0.0, abs=1e-6)
    assert body["pd"] is None
    assert abs(body["det_A"]) < 1e-6


def test_analyze_non_assembling_q_is_422_naming_q(api):
    r = api.post(
        "/v1/analyze", json={"q": [0.0, 0.7, 0.7], "assembly_mode": "+", "design": PAPER_OPTIMUM}
    )
    assert r.status_code == 422
    (item,) = r.json()["detail"]
    assert item["loc"] == ["body", "q"] and item["type"] == "assembly_error"
    assert "C on D" in item["msg"]
