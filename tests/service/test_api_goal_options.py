"""``goal.prefer`` and ``goal.tolerance`` of ``POST /v1/plan`` over HTTP: the chosen mode's
path never has a larger kappa(A) than the shortest one's on a seeded suite, measured by the
checker's own kinematics (not the library's); a goal within the tolerance is used when the
exact one cannot be, and the plan ends within it; every answer re-checked by
:func:`plan_checker.check_plan`; bad values answered 422 by name."""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest
from plan_checker import DEFAULT_DESIGN, check_plan, postures

START = {"q": [-0.2187, 2.8609, 0.2807], "assembly_mode": "+"}


def _plan(api, body: dict) -> dict:
    r = api.post("/v1/plan", json=body)
    assert r.status_code == 200, r.text
    answer = r.json()
    report = check_plan(body, answer)  # an answer other than solved carries no path
    assert report.ok if answer["status"] == "solved" else not report.failures, str(report)
    return answer


def _max_kappa(waypoints: list, step: float = 0.002) -> float:
    """Largest kappa(A) along the straight joint pieces, every ``step`` rad (own kinematics)."""
    w = np.asarray(waypoints, float)
    dense = [w[:1]]
    for a, b in pairwise(w):
        n = max(1, math.ceil(float(np.max(np.abs(b - a))) / step))
        dense.append(a + np.linspace(0, 1, n + 1)[1:, None] * (b - a))
    return float(np.max(postures(DEFAULT_DESIGN, np.vstack(dense), 1).kappa))


def _suite(n: int, seed: int = 7) -> list[tuple[list[float], list[float]]]:
    """Seeded (start q, goal P) pairs: valid starts (own measures within the margins) and
    goals P of other such postures, so that some working mode reaches each."""
    rng = np.random.default_rng(seed)
    out: list[list[float]] = []
    while len(out) < 2 * n:
        q = rng.uniform(-math.pi, math.pi, 3)
        post = postures(DEFAULT_DESIGN, q[None], 1)
        if post.ok[0] and post.kappa[0] < 8 and np.min(np.abs(post.measures[0])) > 0.1:
            out.append(q.tolist())
    p = postures(DEFAULT_DESIGN, np.array(out[n:]), 1).points["P"]
    return [(out[i], p[i].tolist()) for i in range(n)]


def test_best_conditioned_is_never_worse_than_shortest_in_max_kappa(api):
    solved, differ = 0, 0
    for q, p in _suite(8):
        base = {"start": {"q": q, "assembly_mode": "+"}, "planner": {"seed": 1}}
        shortest = _plan(api, {**base, "goal": {"p": p, "working_mode": "any"}})
        body = {**base, "goal": {"p": p, "working_mode": "any", "prefer": "best_conditioned"}}
        best = _plan(api, body)
        if shortest["status"] != "solved":
            continue
        assert best["status"] == "solved", best["message"]
        solved += 1
        k_short, k_best = (
            _max_kappa(shortest["path"]["waypoints"]),
            _max_kappa(best["path"]["waypoints"]),
        )
        assert k_best <= k_short * (1 + 1e-9), (q, p, k_best, k_short)
        differ += k_best < k_short * (1 - 1e-6)
        for answer, prefer in ((shortest, "shortest"), (best, "best_conditioned")):
            mode = answer["path"]["segments"][-1]["working_mode"]
            assert f"working mode {mode} chosen ({prefer}" in answer["message"]
    assert solved >= 4
    assert differ >= 1  # the option changes something on this suite


def test_prefer_needs_working_mode_any(api):
    body = {
        "start": START,
        "goal": {"p": [0.45, 0.3, 0.1], "working_mode": "+-+", "prefer": "best_conditioned"},
    }
    r = api.post("/v1/plan", json=body)
    assert r.status_code == 422
    item = r.json()["detail"][0]
    assert item["loc"] == ["body", "goal", "prefer"] and "working_mode 'any'" in item["msg"]


def test_a_cartesian_goal_within_tolerance_is_used_when_the_exact_one_is_out_of_reach(api):
    # on the ray from A through the start's P, 3 mm beyond the leg's reach L1 + L2
    d = DEFAULT_DESIGN
    a = np.array([0.0, -d["L0"] / 2, 0.0])
    p0 = postures(d, np.array([START["q"]]), 1).points["P"][0]
    goal = a + (d["L1"] + d["L2"] + 0.003) * (p0 - a) / np.linalg.norm(p0 - a)
    body = {"start": START, "goal": {"p": goal.tolist()}, "planner": {"seed": 1}}
    exact = _plan(api, body)
    assert exact["status"] == "unreachable"
    body["goal"]["tolerance"] = 0.01
    near = _plan(api, body)  # the checker allows the goal's tolerance, no more
    assert near["status"] == "solved", near["message"]
    end = postures(d, np.array(near["path"]["waypoints"][-1:]), 1).points["P"][0]
    miss = float(np.linalg.norm(end - goal))
    assert 0.003 < miss <= 0.01
    assert "within goal.tolerance = 0.01 m" in near["message"] and "unreachable" in near["message"]


def test_a_joint_goal_within_tolerance_is_used_when_the_exact_one_breaks_a_limit(api):
    design = {"joint_max": [0.5, math.pi, math.pi]}
    goal_q = [0.52, 2.8609, 0.2807]  # theta1 0.02 rad beyond its limit 0.5
    body = {
        "design": design,
        "start": START,
        "planner": {"seed": 1},
        "goal": {"q": goal_q, "assembly_mode": "+"},
    }
    exact = api.post("/v1/plan", json=body).json()
    assert exact["status"] == "invalid_goal", exact
    body["goal"]["tolerance"] = 0.05
    near = _plan(api, body)
    assert near["status"] == "solved", near["message"]
    end = np.asarray(near["path"]["waypoints"][-1])
    assert np.linalg.norm(end - goal_q) <= 0.05 and end[0] <= 0.5
    assert "within goal.tolerance = 0.05 rad" in near["message"]


def test_a_reachable_goal_is_planned_exactly_whatever_the_tolerance(api):
    goal = {"q": [0.3, 2.6, 0.5], "assembly_mode": "+", "tolerance": 0.2}
    answer = _plan(api, {"start": START, "goal": goal, "planner": {"seed": 1}})
    assert answer["status"] == "solved"
    assert np.allclose(answer["path"]["waypoints"][-1], goal["q"], atol=1e-12)
    assert "tolerance" not in answer["message"]


@pytest.mark.parametrize(
    ("goal", "loc", "words"),
    [
        ({"p": [0.4, 0, 0], "prefer": "fastest"}, ["body", "goal", "prefer"], "shortest"),
        ({"p": [0.4, 0, 0], "tolerance": -0.1}, ["body", "goal", "tolerance"], "greater"),
        ({"p": [0.4, 0, 0], "tolerance": 2.0}, ["body", "goal", "tolerance"], "less"),
        ({"p": [0.4, 0, 0], "tolerance": "0.1"}, ["body", "goal", "tolerance"], "number"),
        (
            {"q": [0, 2, 1], "assembly_mode": "+", "tolerance": 4.0},
            ["body", "goal", "tolerance"],
            "less",
        ),
        (
            {"q": [0, 2, 1], "assembly_mode": "+", "prefer": "shortest"},
            ["body", "goal", "prefer"],
            "not permitted",
        ),
    ],
)
def test_bad_goal_options_are_422_naming_the_field(api, goal, loc, words):
    r = api.post("/v1/plan", json={"start": START, "goal": goal})
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert any(d["loc"] == loc and words in d["msg"] for d in detail), detail


#: The request an outside verifier broke the proof with: the exact point is cut off (the
#: region map with obstacles proves it), but a goal 0.323 m away, inside the 0.35 m
#: tolerance, is joined by a straight motion.
CUT_OFF_POINT = {
    "design": {"L0": 0.5, "L1": 0.2, "L2": 0.6, "link_radius": 0.02,
               "joint_min": [-3.141593, -3.141593, -3.141593],
               "joint_max": [3.141593, 3.141593, 3.141593]},
    "start": {"q": [0, 2.0, 1.0], "assembly_mode": "+"},
    "obstacles": [
        {"type": "box", "center": [0.472765, 0.0, -0.736287], "size": [1.25, 2.4, 0.01],
         "quaternion": [0.877583, 0, 0.479426, 0]},
        {"type": "box", "center": [-0.472765, 0.0, 0.736287], "size": [1.25, 2.4, 0.01],
         "quaternion": [0.877583, 0, 0.479426, 0]},
        {"type": "box", "center": [-0.514938, 0.0, -0.707434], "size": [1.25, 2.4, 0.01],
         "quaternion": [0.453596, 0, 0.891207, 0]},
        {"type": "box", "center": [0.514938, 0.0, 0.707434], "size": [1.25, 2.4, 0.01],
         "quaternion": [0.453596, 0, 0.891207, 0]},
        {"type": "sphere", "center": [0.414591, 0.022037, -0.347592], "radius": 0.03}],
    "planner": {"seed": 1, "time_budget_s": 2.0}, "timing": {"method": "none"},
    "goal": {"p": [0.209807, 0.022037, -0.631429], "working_mode": "+-+", "tolerance": 0.35},
    "margins": {"kappa_max": 10.0, "serial_min": 0.05, "clearance": 0.01},
}  # fmt: skip


@pytest.mark.parametrize("method", ["none", "toppra"])
def test_no_proof_while_a_goal_within_the_tolerance_is_reachable(api, method):
    """The exact point alone is proven cut off, and was once answered so; a goal inside the
    tolerance plans, so the answer is that plan (the independent checker accepts it and its
    end within the tolerance), never ``proven_infeasible``."""
    body = {**CUT_OFF_POINT, "timing": {"method": method}}
    exact = api.post("/v1/plan", json={**body, "goal": {**body["goal"], "tolerance": 0}}).json()
    assert exact["status"] == "no_path" and exact["diagnostics"]["proven_infeasible"]
    answer = _plan(api, body)
    assert answer["status"] == "solved", answer["message"]
    assert not answer["diagnostics"]["proven_infeasible"]
    design = {**DEFAULT_DESIGN, **body["design"]}
    end = postures(design, np.array(answer["path"]["waypoints"][-1:]), 1).points["P"][0]
    assert np.linalg.norm(end - body["goal"]["p"]) <= 0.35
    assert "within goal.tolerance = 0.35 m" in answer["message"]
    assert answer["path"]["segments"][-1]["working_mode"] == "+-+"
