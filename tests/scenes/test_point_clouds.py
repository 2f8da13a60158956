"""Point-cloud obstacles: clearance of a checker and of every returned path against a cloud,
checked by an independent route (scipy's k-d tree over densely sampled link capsules), and
the wire's answers to bad clouds (422 naming the field; 413 beyond the body limit)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from planning_factories import check_library_plan, plan_answer, reference_measures

from planner.constants import MAX_POINTS
from planner.design import Design
from planner.geometry import Points
from planner.kinematics import forward_batch, link_points
from planner.planning import JointPosture, PlanOptions, plan
from planner.validity import Margins, ValidityChecker

START = np.array([0.3, 2.0, 1.0])
GOAL = np.array([-0.6, 1.4, 0.7])


def _disc_cloud(center: np.ndarray, normal: np.ndarray, radius: float, n: int, seed: int = 0):
    """n points on a flat disc (a plate as a depth camera sees it)."""
    rng = np.random.default_rng(seed)
    normal = normal / np.linalg.norm(normal)
    u = np.cross(normal, [0.0, 0.0, 1.0] if abs(normal[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    r = radius * np.sqrt(rng.random(n))
    phi = rng.uniform(0, 2 * np.pi, n)
    return center + (r * np.cos(phi))[:, None] * u + (r * np.sin(phi))[:, None] * v


def _blocking_cloud(design: Design) -> Points:
    """A disc of 4,000 points across the straight motion START -> GOAL, at P's midpoint."""
    fb = forward_batch(design, (START + GOAL)[None] / 2, "+")
    return Points(_disc_cloud(fb.p[0], np.array([0.0, 1.0, 0.3]), 0.09, 4000), 0.004)


def test_checker_clearance_matches_a_kd_tree_over_sampled_links():
    design = Design.default()
    cloud = _blocking_cloud(design)
    chk = ValidityChecker(design, Margins(), [cloud], "+", "+-+")
    rng = np.random.default_rng(1)
    q = START + rng.normal(0, 0.4, (300, 3))
    got = chk.check_states(q)
    ok, _, _, ref = reference_measures(design, q, "+", "+-+", [cloud], k=600)
    closed = ok & np.isfinite(got.clearance)
    assert closed.sum() > 100
    # sampling the links every 1/600 of their length (<= 1 mm) can only overestimate the
    # distance, by at most half a step: the checker's exact value is below and close
    diff = ref[closed] - got.clearance[closed]
    assert diff.min() > -1e-9
    assert diff.max() < 6e-4
    # both sides of the clearance rule are met among the postures
    assert (got.clearance[closed] < 0.01).any() and (got.clearance[closed] > 0.05).any()


def test_every_returned_path_keeps_clearance_to_the_cloud():
    """The straight motion passes through the cloud; the plan goes around it, and the
    independent plan checker (tests/plan_checker.py, k-d tree for clouds) re-checks every
    rule of the first answer; every answer's links, sampled densely, keep the clearance to
    the points by a k-d tree."""
    design = Design.default()
    cloud = _blocking_cloud(design)
    margins = Margins()
    straight = ValidityChecker(design, margins, [cloud], "+", "+-+").check_motion(START, GOAL)
    assert not straight.valid and straight.reason == "clearance"
    solved = 0
    for seed in (1, 2, 3):
        res = plan(
            design,
            JointPosture(START, "+"),
            JointPosture(GOAL, "+"),
            obstacles=[cloud],
            margins=margins,
            options=PlanOptions(time_budget_s=5.0, seed=seed),
        )
        if res.status.value != "solved":
            continue
        solved += 1
        if solved == 1:  # the whole independent checker (seconds: a k-d tree query per sample)
            goal_wire = {"q": GOAL.tolist(), "assembly_mode": "+"}
            report = check_library_plan(
                design, JointPosture(START, "+"), goal_wire, margins, [cloud], plan_answer(res)
            )
            assert report.ok, str(report)
        # and the least distance of the densest sampling of its links to the points
        from scipy.spatial import cKDTree

        from planner.validity import densify

        tree = cKDTree(cloud.points)
        qd = densify(res.path.waypoints, 0.005)
        fb = forward_batch(design, qd, "+")
        assert fb.ok.all()
        pts = link_points(design, fb.q, fb.passive)
        s = np.linspace(0, 1, 400)
        least = np.inf
        for i, j in ((0, 2), (1, 3), (2, 4), (3, 4)):
            x = pts[:, i, None] + s[None, :, None] * (pts[:, j] - pts[:, i])[:, None]
            least = min(least, tree.query(x.reshape(-1, 3))[0].min())
        assert least - cloud.radius - design.link_radius >= margins.clearance - 1e-9
    assert solved >= 2


# ------------------------------------------------------------------------------- the wire
def _plan_body(obstacles: list) -> dict:
    return {
        "start": {"q": START.tolist(), "assembly_mode": "+"},
        "goal": {"q": GOAL.tolist(), "assembly_mode": "+"},
        "obstacles": obstacles,
        "timing": {"method": "none"},
    }


@pytest.mark.parametrize(
    ("cloud", "loc_tail", "words"),
    [
        ({"type": "points", "points": [], "radius": 0.01}, ("points",), "at least 1"),
        ({"type": "points", "points": [[0, 0, 1e5]], "radius": 0.01}, ("points", 0, 2), "less"),
        ({"type": "points", "points": [[0, 0]], "radius": 0.01}, ("points", 0), "at least 3"),
        ({"type": "points", "points": [[0, 0, 0]], "radius": 0.0}, ("radius",), "greater"),
        ({"type": "points", "points": [[0, 0, 0]], "radius": -1}, ("radius",), "greater"),
        ({"type": "points", "points": [[0, 0, 0]]}, ("radius",), "required"),
    ],
)
def test_bad_clouds_are_422_at_the_field(api, cloud, loc_tail, words):
    r = api.post("/v1/plan", json=_plan_body([cloud]))
    assert r.status_code == 422, r.text
    item = r.json()["detail"][0]
    # the union's tag ("points") comes before the field
    assert tuple(item["loc"]) == ("body", "obstacles", 0, "points", *loc_tail), item
    assert words.lower() in item["msg"].lower()


def test_non_finite_points_are_422(api):
    text = json.dumps(_plan_body([{"type": "points", "points": [[0, 0, 0]], "radius": 0.01}]))
    text = text.replace("[[0, 0, 0]]", "[[0, 0, 0], [0, NaN, 0]]")
    r = api.post("/v1/plan", content=text, headers={"content-type": "application/json"})
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "obstacles", 0, "points", "points", 1, 1]


def test_too_many_points_are_422_before_the_points_are_validated(api):
    """One point over the limit: a 422 at the list, named by its length (the list is
    refused by its length; its 250,001 points are not validated one by one)."""
    pts = "[" + ",".join(["[0.5,0.5,0.5]"] * (MAX_POINTS + 1)) + "]"
    body = json.dumps(_plan_body([])).replace(
        '"obstacles": []', f'"obstacles": [{{"type": "points", "radius": 0.01, "points": {pts}}}]'
    )
    r = api.post("/v1/plan", content=body, headers={"content-type": "application/json"})
    assert r.status_code == 422, r.text[:300]
    item = r.json()["detail"][0]
    assert item["loc"] == ["body", "obstacles", 0, "points", "points"]
    assert "250000" in item["msg"].replace(",", "")


def test_the_limit_holds_over_all_clouds_of_a_request():
    from planner.exceptions import InputError
    from planner.wire import PlanRequest, plan_inputs

    half = [[0.5, 0.5, 0.5]] * (MAX_POINTS // 2 + 1)
    req = PlanRequest.model_validate(
        _plan_body([{"type": "points", "points": half, "radius": 0.01}] * 2)
    )
    with pytest.raises(InputError, match="at most 250000 points in all") as err:
        plan_inputs(req)
    assert err.value.loc == ("body", "obstacles", 1, "points")


def test_a_cloud_of_the_largest_size_fits_the_default_body_limit(api):
    """MAX_POINTS points written at full float precision pass the body limit (no 413) and
    are planned against (the cloud lies far from the robot: the straight motion is valid)."""
    rng = np.random.default_rng(3)
    pts = rng.uniform(5.0, 6.0, (MAX_POINTS, 3))
    body = _plan_body([{"type": "points", "points": pts.tolist(), "radius": 0.01}])
    text = json.dumps(body)
    assert len(text) > 12_000_000  # full precision: about 65 bytes a point
    r = api.post("/v1/plan", content=text, headers={"content-type": "application/json"})
    assert r.status_code == 200, r.text[:300]
    assert r.json()["status"] == "solved"
