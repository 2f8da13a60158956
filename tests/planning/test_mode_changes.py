"""Working-mode changes through serial singularities: every reachable mode pair of the paper
optimum and of the singularity-free design is planned (or answered "unreachable" for a reason
verified here independently); the working mode along each path, sampled densely from the
kinematics, changes only at the listed transits and by one sign; no posture comes near a
parallel singularity; the independent checker (tests/plan_checker.py) accepts every plan;
/v1/plan end to end."""

from __future__ import annotations

import itertools
import time

import numpy as np
import pytest
from plan_checker import check_plan
from planning_factories import check_library_plan, plan_answer, wire_design

from planner.design import Design
from planner.kinematics import WORKING_MODES, forward_batch, inverse_batch
from planner.planning import (
    CartesianTarget,
    JointPosture,
    PlanOptions,
    PlanStatus,
    mode_sequences,
    path_state_checker,
    plan,
)
from planner.validity import Margins, ValidityChecker

MARGINS = Margins()
#: A search budget with room: a solvable mode change takes tens of milliseconds here, so 3 s
#: holds on a much slower machine; a disconnected pair spends all of it.
OPTIONS = PlanOptions(time_budget_s=3.0, seed=3)
DESIGNS = {"paper": Design.paper_optimum(), "free": Design.singularity_free()}
STEP = 0.002  # rad, dense walk along the paths


def _valid_postures(design, asm, mode, seed=0, n=6000):
    rng = np.random.default_rng(seed)
    q = rng.uniform(design.joint_min, design.joint_max, (n, 3))
    return q[ValidityChecker(design, MARGINS, (), asm, mode).is_valid(q)]


def _label(signs) -> str:
    return "".join("+" if s > 0 else "-" if s < 0 else "0" for s in signs)


def _dense(waypoints, step=STEP):
    out = [waypoints[:1]]
    for a, b in itertools.pairwise(waypoints):
        n = max(1, int(np.ceil(np.max(np.abs(b - a)) / step)))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return out


def check_mode_path(design, start, res, goal_q=None, goal_p=None):
    """Independent checks of a solved mode-change plan (kinematics only, no validity code)."""
    path = res.path
    w = path.waypoints
    asm = start.assembly_mode
    np.testing.assert_array_equal(w[0], start.q)
    if goal_q is not None:
        np.testing.assert_array_equal(w[-1], goal_q)
    if goal_p is not None:
        np.testing.assert_allclose(forward_batch(design, w[-1], asm).p[0], goal_p, atol=1e-9)
    segs, trs = path.segments, path.transits
    assert len(segs) == len(trs) + 1 and segs[0].start_index == 0
    assert segs[-1].end_index == len(w) - 1
    for a, b, t in zip(segs[:-1], segs[1:], trs, strict=True):
        assert a.end_index == b.start_index == t.index
        np.testing.assert_array_equal(w[t.index], t.q)
        flipped = [k for k in range(3) if a.working_mode[k] != b.working_mode[k]]
        assert flipped == [{"axis": 0, "A": 1, "B": 2}[t.flipped]]  # one sign, the named one
        # the transit posture lies on the serial singularity it names
        fb = forward_batch(design, w[t.index], asm)
        # (a sine near a stretched/folded leg is the square root of the distance error)
        assert abs(fb.serial_measures[0, flipped[0]]) < 1e-7
        if t.kind == "P_on_axis":
            assert abs(fb.w[0]) < 1e-9
        else:
            pivot = np.array([0.0, (-1 if t.flipped == "A" else 1) * design.L0 / 2, 0.0])
            reach = design.L1 + design.L2 if "stretched" in t.kind else abs(design.L2 - design.L1)
            assert np.linalg.norm(fb.p[0] - pivot) == pytest.approx(reach, abs=1e-9)
        # q_in, q_transit, q_out are consecutive and collinear (a straight crossing)
        np.testing.assert_allclose(w[t.index - 1] + w[t.index + 1], 2 * w[t.index], atol=1e-9)
    # dense walk: the mode is the segment's wherever every measure is away from 0
    pieces = _dense(w)
    transit_idx = {t.index for t in trs}
    for seg in segs:
        for i in range(seg.start_index, seg.end_index):
            q = pieces[i + 1]
            fb = forward_batch(design, q, asm)
            assert fb.ok.all()
            assert np.all(fb.assembly_mode_signs == (1 if asm == "+" else -1))
            delta = fb.passive[:, 0] - fb.passive[:, 1]
            c = np.abs(np.cos(delta))
            kappa = np.sqrt((1 + c) / (1 - c))  # corrected eq. 8
            assert kappa.max() <= MARGINS.kappa_max * (1 + 1e-9)  # never near C = D or CD stretched
            m = fb.serial_measures
            away = np.min(np.abs(m), axis=1) > 1e-6  # signs are 0 within SIGN_TOL = 1e-7
            labels = {_label(s) for s in fb.working_mode_signs[away]}
            assert labels <= {seg.working_mode}, (i, labels, seg.working_mode)
            if i not in transit_idx and i + 1 not in transit_idx:
                assert np.min(np.abs(m)) >= MARGINS.serial_min - 1e-12
    assert res.diagnostics.min_serial_margin >= MARGINS.serial_min
    assert res.diagnostics.max_kappa_A <= MARGINS.kappa_max


def _goal_wire(goal):
    if isinstance(goal, JointPosture):
        return {"q": goal.q.tolist(), "assembly_mode": goal.assembly_mode}
    return {"p": goal.p.tolist(), "working_mode": goal.working_mode}


def _operative(design, asm):
    return [m for m in WORKING_MODES if len(_valid_postures(design, asm, m))]


def test_mode_graph_walks():
    walks = mode_sequences("+-+", ["++-"], detour=0)
    assert walks == [("+-+", "+++", "++-"), ("+-+", "+--", "++-")]  # both orders of the flips
    walks = mode_sequences("+-+", ["+++"], detour=2)
    assert walks[0] == ("+-+", "+++") and all(len(wk) in (2, 4) for wk in walks)
    for wk in walks:
        assert len(set(wk)) == len(wk)
        for a, b in itertools.pairwise(wk):
            assert sum(x != y for x, y in zip(a, b, strict=True)) == 1


def test_operative_modes_of_the_reference_designs():
    """The facts the pair tests rely on, checked by sampling: the paper optimum has two
    operative modes per assembly mode (s_A != s_B, differing in the axis sign); the
    singularity-free design ties the axis sign to the assembly mode."""
    paper, free = DESIGNS["paper"], DESIGNS["free"]
    assert _operative(paper, "+") == ["+-+", "--+"] and _operative(paper, "-") == ["++-", "-+-"]
    assert _operative(free, "+") == [m for m in WORKING_MODES if m[0] == "+"]
    assert _operative(free, "-") == [m for m in WORKING_MODES if m[0] == "-"]


def _pairs():
    out = []
    for name, design in DESIGNS.items():
        for asm in "+-":
            modes = _operative(design, asm)
            out += [(name, asm, a, b) for a in modes for b in modes if a != b]
    return out


@pytest.mark.parametrize(("name", "asm", "m0", "m1"), _pairs())
def test_every_reachable_mode_pair_is_planned(name, asm, m0, m1):
    design = DESIGNS[name]
    starts, goals = _valid_postures(design, asm, m0, 1), _valid_postures(design, asm, m1, 2)
    # literal joint limits and parallel singularities split each mode region into
    # components: a pair may need detours through other modes, or (paper optimum: the
    # diagonal theta2 = theta3 is C = D) be disconnected; up to 3 seeded pairs are tried
    for k in range(3):
        start, goal = JointPosture(starts[k], asm), JointPosture(goals[k], asm)
        res = plan(design, start, goal, margins=MARGINS, options=OPTIONS)
        assert res.status in (PlanStatus.SOLVED, PlanStatus.NO_PATH), res.message
        if res.solved:
            break
    assert res.solved, res.message
    assert res.path.segments[0].working_mode == m0 and res.path.segments[-1].working_mode == m1
    hamming = sum(a != b for a, b in zip(m0, m1, strict=True))
    assert len(res.path.transits) >= hamming
    check_mode_path(design, start, res, goal_q=goal.q)
    report = check_library_plan(design, start, _goal_wire(goal), MARGINS, [], plan_answer(res))
    assert report.ok, report


def test_paper_optimum_transits_are_on_the_axis_only():
    design = DESIGNS["paper"]
    start = JointPosture(_valid_postures(design, "+", "+-+", 1)[0], "+")
    for goal_q in _valid_postures(design, "+", "--+", 2)[:4]:
        res = plan(design, start, JointPosture(goal_q, "+"), options=OPTIONS)
        if res.solved:
            break
    assert res.solved
    assert {t.kind for t in res.path.transits} == {"P_on_axis"}


@pytest.mark.parametrize(("name", "target_mode"), [("paper", "-+-"), ("free", "-+-")])
def test_goal_in_the_other_assembly_mode_is_unreachable(name, target_mode):
    """A Cartesian goal whose only solution in the requested mode lies in the other assembly
    mode: verified with the inverse kinematics and forward kinematics in both modes."""
    design = DESIGNS[name]
    start = JointPosture(_valid_postures(design, "+", _operative(design, "+")[0], 1)[0], "+")
    q_other = _valid_postures(design, "-", target_mode, 4)[0]
    p = forward_batch(design, q_other, "-").p[0]
    # independent: the IK solution of that mode assembles in '-' and not in '+' at p
    ik = inverse_batch(design, p)
    slot = WORKING_MODES.index(target_mode)
    assert ik.ok[0, slot] and ik.assembly_mode_signs[0, slot] == -1
    fb_plus = forward_batch(design, ik.q[0, slot], "+")
    assert not (fb_plus.ok[0] and np.allclose(fb_plus.p[0], p, atol=1e-9))
    res = plan(design, start, CartesianTarget(p, target_mode), options=OPTIONS)
    assert res.status is PlanStatus.UNREACHABLE
    assert "assembly mode -" in res.message
    # a joint goal in the other assembly mode: crossing would cross a parallel singularity
    res = plan(design, start, JointPosture(q_other, "-"), options=OPTIONS)
    assert res.status is PlanStatus.UNREACHABLE and "parallel singularity" in res.message


def test_no_axis_transit_makes_the_axis_sign_unreachable():
    """Singularity-free design with theta1 limited and a mirrored goal: the same point in
    the other axis mode needs the other assembly mode (the two are tied), and P never
    reaches the axis (independent interval check in tests/planning/test_transits.py)."""
    design = DESIGNS["free"]
    start = JointPosture([0.0, 2.0, 1.0], "+")
    assert forward_batch(design, start.q, "+").working_mode_signs[0, 0] == 1
    p = forward_batch(design, np.array([0.3, 2.1, 1.1]), "+").p[0]
    ik = inverse_batch(design, p)
    for m in WORKING_MODES:
        slot = WORKING_MODES.index(m)
        if ik.ok[0, slot]:  # tied: axis sign '+' <=> assembly '+'
            assert (m[0] == "+") == (ik.assembly_mode_signs[0, slot] == 1)
    res = plan(design, start, CartesianTarget(p, "-++"), options=OPTIONS)
    assert res.status is PlanStatus.UNREACHABLE and "assembly mode" in res.message


def test_cartesian_goal_in_a_specific_other_mode():
    design = DESIGNS["free"]
    start = JointPosture([0.0, 2.0, 1.0], "+")  # +-+
    q_goal = _valid_postures(design, "+", "+++", 5)[0]
    p = forward_batch(design, q_goal, "+").p[0]
    target = CartesianTarget(p, "+++")
    res = plan(design, start, target, options=OPTIONS)
    assert res.solved, res.message
    assert [s.working_mode for s in res.path.segments][-1] == "+++"
    check_mode_path(design, start, res, goal_p=p)
    report = check_library_plan(design, start, _goal_wire(target), MARGINS, [], plan_answer(res))
    assert report.ok, report


def test_any_mode_changes_mode_when_the_start_mode_cannot_reach():
    """A point whose solution in the start's mode (++-) breaks a rule: 'any' must change mode."""
    design = DESIGNS["free"]
    start = JointPosture(_valid_postures(design, "+", "++-", 1)[0], "+")
    chk = ValidityChecker(design, MARGINS, (), "+", "++-")
    slot = WORKING_MODES.index("++-")
    for q in _valid_postures(design, "+", "+++", 6):
        p = forward_batch(design, q, "+").p[0]
        ik = inverse_batch(design, p)  # independent: the start's mode cannot reach p validly
        if not ik.ok[0, slot] or not chk.is_valid(ik.q[0, slot][None])[0]:
            break
    else:
        pytest.fail("no such point sampled")
    res = plan(design, start, CartesianTarget(p, "any"), options=OPTIONS)
    assert res.solved, res.message
    assert len(res.path.transits) >= 1 and res.path.segments[-1].working_mode != "++-"
    check_mode_path(design, start, res, goal_p=p)
    report = check_library_plan(
        design,
        start,
        {"p": p.tolist(), "working_mode": "any"},
        MARGINS,
        [],
        plan_answer(res),
    )
    assert report.ok, report


def test_any_mode_changes_mode_when_the_start_region_is_cut_off():
    """The goal point's solution in the start's mode lies in another component of that mode's
    region (joint limits at +-pi split it): the single-mode search finds no path, 'any'
    reaches the point in another mode through a transit."""
    from planner.planning.single_mode import plan_single_mode

    design = DESIGNS["free"]
    rng = np.random.default_rng(1)
    q = rng.uniform(-np.pi, np.pi, (4000, 3))
    s_q = q[ValidityChecker(design, MARGINS, (), "+", "+-+").is_valid(q)][2]
    g_q = q[ValidityChecker(design, MARGINS, (), "+", "+++").is_valid(q)][2]
    start, p = JointPosture(s_q, "+"), forward_batch(design, g_q, "+").p[0]
    # no path exists in the start's region, so the single-mode search fails whatever its
    # budget (a short one keeps the test fast); the mode change gets a budget with room
    alone = plan_single_mode(
        design, start, CartesianTarget(p, "any"), options=PlanOptions(time_budget_s=0.6, seed=1)
    )
    assert alone.status is PlanStatus.NO_PATH
    res = plan(
        design, start, CartesianTarget(p, "any"), options=PlanOptions(seed=1, time_budget_s=10.0)
    )
    assert res.solved, res.message
    assert res.path.segments[-1].working_mode != "+-+"
    check_mode_path(design, start, res, goal_p=p)
    goal_wire = {"p": p.tolist(), "working_mode": "any"}
    report = check_library_plan(design, start, goal_wire, MARGINS, [], plan_answer(res))
    assert report.ok, report


def test_obstacle_next_to_the_transit_still_solved():
    """A sphere on the first choice of transit: the plan uses another one or goes around."""
    from planner.geometry import Sphere

    design = DESIGNS["free"]
    start = JointPosture([0.0, 2.0, 1.0], "+")
    goal = JointPosture(_valid_postures(design, "+", "+++", 5)[0], "+")
    first = plan(design, start, goal, options=OPTIONS)
    assert first.solved
    qt = np.array(first.path.transits[0].q)
    fb = forward_batch(design, qt, "+")
    obstacles = [Sphere(fb.p[0], 0.05)]
    res = plan(design, start, goal, obstacles=obstacles, options=PlanOptions(time_budget_s=10.0))
    assert res.solved, res.message
    assert not np.allclose(res.path.transits[0].q, qt)
    check_mode_path(design, start, res, goal_q=goal.q)
    report = check_library_plan(
        design, start, _goal_wire(goal), MARGINS, obstacles, plan_answer(res)
    )
    assert report.ok, report


def test_path_state_checker_accepts_the_crossing_only_near_it():
    from planner.transits import sample_transits

    design = DESIGNS["free"]
    start = JointPosture([0.0, 2.0, 1.0], "+")
    goal = JointPosture(_valid_postures(design, "+", "+++", 5)[0], "+")
    res = plan(design, start, goal, options=OPTIONS)
    assert res.solved
    check = path_state_checker(design, MARGINS, (), res.path, near=0.0)
    dense = np.vstack(_dense(res.path.waypoints))
    assert check(dense).all()  # the whole planned path is valid piece by piece
    t = res.path.transits[0]
    # other postures on the same singular surface, far from this crossing, are not valid
    others = sample_transits(
        design,
        t.kind,
        working_mode=res.path.segments[0].working_mode,
        assembly_mode="+",
        n=200,
        rng=np.random.default_rng(0),
    )
    far = others[np.linalg.norm(others - np.array(t.q), axis=1) > 0.3]
    assert len(far) > 10 and not check(far).any()
    # a valid posture of a mode the path does not visit is not valid either
    unvisited = {"+++", "++-", "+-+", "+--"} - {s.working_mode for s in res.path.segments}
    q_other = _valid_postures(design, "+", sorted(unvisited)[0], 7)[:20]
    assert not check(q_other).any()


def test_no_transit_on_a_walk_is_unreachable_with_the_reason():
    """Paper optimum: +-+ -> +-- would flip B, but a stretched leg stretches both legs
    (C = D) and a folded one puts P on the base point (tests/planning/test_transits.py checks that no
    such posture assembles regularly), and +++ is parallel-singular everywhere."""
    from planner.planning.mode_change import plan_mode_change

    design = DESIGNS["paper"]
    start = JointPosture(_valid_postures(design, "+", "+-+", 1)[0], "+")
    assert not len(_valid_postures(design, "+", "+++")) and not len(
        _valid_postures(design, "+", "+--")
    )
    t0 = time.perf_counter()
    res = plan_mode_change(
        design,
        start,
        "+-+",
        {"+--": np.array([[0.0, 1.0, -1.0]])},
        obstacles=(),
        margins=MARGINS,
        options=OPTIONS,
        t0=t0,
        deadline=t0 + 60.0,
    )
    assert res.status is PlanStatus.UNREACHABLE
    assert "leg_B_stretched or leg_B_folded" in res.message


@pytest.mark.parametrize("stop", [False, True])
def test_v1_plan_end_to_end_with_a_mode_change(api, stop):
    design = DESIGNS["free"]
    goal_q = _valid_postures(design, "+", "+++", 5)[0]
    body = {
        "design": wire_design(design),
        "start": {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"},
        "goal": {"q": goal_q.tolist(), "assembly_mode": "+"},
        "margins": {"kappa_max": 10.0, "serial_min": 0.05, "clearance": 0.01},
        "planner": {"seed": 1, "time_budget_s": 1.0, "stop_at_transits": stop},
        "limits": {"velocity": [1.0, 1.5, 2.0], "acceleration": [4.0, 5.0, 6.0]},
    }
    r = api.post("/v1/plan", json=body)
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["status"] == "solved", out["message"]
    trs = out["path"]["transits"]
    assert len(trs) >= 1 and trs[0]["flipped"] in ("A", "B")
    segs = out["path"]["segments"]
    assert segs[0]["end_index"] == trs[0]["index"] == segs[1]["start_index"]
    traj = out["trajectory"]
    q, qd = np.array(traj["q"]), np.array(traj["qd"])
    # with stops the trajectory rests exactly on the transit posture, at a sample; without,
    # its corner blend passes within the blend deviation (0.05 rad)
    d = np.linalg.norm(q - np.array(trs[0]["q"]), axis=1)
    k = int(np.argmin(d))
    if stop:
        assert d[k] < 1e-9 and np.abs(qd[k]).max() < 1e-9
    else:
        assert d[k] < 0.05
    report = check_plan(body, out)  # the trajectory too, densely
    assert report.ok, report
