"""The motion problem and the one pipeline (:mod:`planner.motion`): what every kind of motion
shares is checked once, the steps run in order, and the three kinds answer alike where the
pipeline decides (gravity at the start, the sample bound, a passed deadline)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from planner import Design
from planner.cartesian import StraightMotion, plan_cartesian
from planner.exceptions import DeadlineError, InputError, TimingError, TimingInfeasibleError
from planner.kinematics import forward_batch
from planner.motion import Budget, MotionProblem, Planned, Timed, TimingRequest, run
from planner.motion import pipeline as P
from planner.planning import CartesianTarget, JointPosture, PlanStatus
from planner.sequence import SequenceTarget, plan_sequence
from planner.solver import GoalMotion
from planner.timing import JointLimits, TimingOptions

DESIGN = Design.default()
START = JointPosture([0.0, 2.0, 1.0], "+")
GOAL = JointPosture([0.4, 2.2, 1.1], "+")


def test_the_problem_checks_each_field_once_and_names_it():
    with pytest.raises(InputError) as e:
        MotionProblem(DESIGN, START, limits={"velocity": [1, 1, 1]})  # type: ignore[arg-type]
    assert e.value.field == "limits" and "JointLimits" in str(e.value)
    with pytest.raises(InputError) as e:
        MotionProblem(DESIGN, START, gravity=(0.0, float("nan"), -9.81))
    assert e.value.field == "gravity"
    with pytest.raises(InputError) as e:
        MotionProblem(DESIGN, [0.0, 2.0, 1.0])  # type: ignore[arg-type]
    assert e.value.field == "start"
    problem = MotionProblem(DESIGN, START, obstacles=[], gravity=[0, 0, -9.81])  # type: ignore[arg-type]
    assert problem.obstacles == () and problem.gravity == (0.0, 0.0, -9.81)
    assert problem.with_(start=GOAL).start is GOAL and problem.start is START


def test_the_budget_is_one_deadline_on_the_monotonic_clock():
    assert Budget().left() == float("inf") and Budget().search_deadline is None
    Budget().check("never")  # no deadline: never raises
    soon = Budget.within(10.0)
    assert 9.0 < soon.left() <= 10.0 and abs(soon.deadline - time.monotonic() - 10.0) < 1.0
    with pytest.raises(DeadlineError, match="the deadline passed while testing"):
        Budget.within(-1.0).check("while testing")
    with pytest.raises(InputError):
        Budget(float("inf"))


class _Recorder:
    """A kind of motion that records what the pipeline asks of it."""

    def __init__(self, plan=None, raises=None):
        self.calls: list[str] = []
        self._plan, self._raises = plan, raises

    def plan(self, problem):
        self.calls.append("plan")
        if self._raises is not None:
            raise self._raises
        return self._plan

    def answer(self, problem, planned, timed):
        self.calls.append("answer")
        return planned, timed


def _line_request() -> TimingRequest:
    q = np.array([START.q, GOAL.q])
    return TimingRequest(q, "+", lambda x: np.ones(len(np.atleast_2d(x)), bool), 0.0)


def test_run_plans_times_and_answers_in_that_order():
    motion = _Recorder(Planned(PlanStatus.SOLVED, "ok", "detail", _line_request()))
    planned, timed = run(MotionProblem(DESIGN, START), motion)
    assert motion.calls == ["plan", "answer"] and planned.detail == "detail"
    assert timed.trajectory is not None and timed.error is None
    assert np.allclose(timed.trajectory.q[-1], GOAL.q) and timed.time_s > 0
    # timing "none": the plan is answered untimed
    untimed = MotionProblem(DESIGN, START, timing=TimingOptions(method="none"))
    planned, timed = run(untimed, _Recorder(Planned(PlanStatus.SOLVED, "", None, _line_request())))
    assert timed.trajectory is None and timed.error is None


def test_run_refuses_a_start_that_gravity_alone_overloads_before_planning():
    weak = JointLimits.default().__class__(
        velocity=(2.0,) * 3, acceleration=(8.0,) * 3, torque=(1e-3,) * 3
    )
    motion = _Recorder(Planned(PlanStatus.SOLVED, "", None, None))
    planned, timed = run(MotionProblem(DESIGN, START, limits=weak), motion)
    assert motion.calls == ["answer"]
    assert planned.status is PlanStatus.INVALID_START and "gravity alone" in planned.message
    assert planned.detail is None and timed.trajectory is None


def test_a_deadline_passing_while_planning_is_the_timeout_answer():
    motion = _Recorder(raises=DeadlineError("the deadline passed while probing"))
    planned, _ = run(MotionProblem(DESIGN, START), motion)
    assert planned.status is PlanStatus.TIMEOUT and "while probing" in planned.message
    assert motion.calls == ["plan", "answer"]


def test_the_fallback_method_times_what_the_first_cannot(monkeypatch):
    tried: list[str] = []
    real = P._time_path

    def flaky(problem, request, method):
        tried.append(method)
        if method == "ruckig":
            raise TimingInfeasibleError("no profile")
        return real(problem, request, method)

    monkeypatch.setattr(P, "_time_path", flaky)
    problem = MotionProblem(DESIGN, START, timing=TimingOptions(method="ruckig"))
    request = _line_request()
    with_fallback = TimingRequest(**{**_fields(request), "fallback": ("toppra",)})
    timed = P.time_planned(problem, with_fallback)
    assert tried == ["ruckig", "toppra"] and timed.trajectory is not None
    assert timed.note == "ruckig failed (no profile); timed with toppra instead"
    tried.clear()
    timed = P.time_planned(problem, request)  # no fallback asked: the failure is the answer
    assert tried == ["ruckig"] and isinstance(timed.error, TimingError)
    assert timed.reason == "no profile" and not timed.late


def _fields(request: TimingRequest) -> dict:
    return {name: getattr(request, name) for name in TimingRequest.__dataclass_fields__}


def test_timed_reports_every_method_that_failed():
    timed = Timed(error=TimingError("b"), failures=("ruckig: a", "toppra: b"))
    assert timed.reason == "ruckig: a; toppra: b"
    assert Timed().reason == "" and not Timed().late


def _pick_point() -> list[float]:
    p = forward_batch(DESIGN, np.asarray(GOAL.q), "+").p[0]
    return p.tolist()


def test_every_kind_answers_a_passed_deadline_with_status_timeout():
    """The one timeout answer: a plan, a sequence and a straight path whose deadline has
    passed all answer ``timeout`` (none raises, none answers no_path)."""
    past = MotionProblem(DESIGN, START, budget=Budget(time.monotonic() - 1.0))
    plan = run(past, GoalMotion(GOAL))
    sequence = plan_sequence(past, [SequenceTarget(GOAL)], objective="fixed")
    p0 = forward_batch(DESIGN, np.asarray(START.q), "+").p[0]
    straight = run(past, StraightMotion(p0 + np.array([0.0, 0.02, 0.0])))
    assert [plan.status.value, sequence.status.value, straight.status.value] == ["timeout"] * 3
    assert plan.trajectory is None and sequence.trajectory is None
    assert straight.trajectory is None


@pytest.mark.parametrize("kind", ["plan", "sequence", "straight"])
def test_the_sample_bound_is_checked_before_any_sample_for_every_kind(kind):
    """``timing.max_samples`` is one rule, decided in the timing step from the duration
    before the trajectory is sampled: an InputError under ``timing.sample_rate_hz``."""
    problem = MotionProblem(DESIGN, START, timing=TimingOptions(max_samples=3))
    p0 = forward_batch(DESIGN, np.asarray(START.q), "+").p[0]
    with pytest.raises(InputError) as e:
        if kind == "plan":
            run(problem, GoalMotion(GOAL))
        elif kind == "sequence":
            plan_sequence(problem, [SequenceTarget(GOAL)], objective="fixed")
        else:
            run(problem, StraightMotion(p0 + np.array([0.0, 0.05, 0.0])))
    assert e.value.field_path == ("timing", "sample_rate_hz"), e.value.field_path


def test_the_keyword_call_and_the_problem_give_the_same_straight_path():
    p0 = forward_batch(DESIGN, np.asarray(START.q), "+").p[0]
    end = p0 + np.array([0.0, 0.05, 0.02])
    by_keywords = plan_cartesian(DESIGN, START, end, sample_rate_hz=50.0)
    problem = MotionProblem(DESIGN, START, timing=TimingOptions(sample_rate_hz=50.0))
    by_problem = run(problem, StraightMotion(end))
    assert by_keywords.status is PlanStatus.SOLVED and by_problem.status is PlanStatus.SOLVED
    assert np.array_equal(by_keywords.path.waypoints, by_problem.path.waypoints)
    assert np.array_equal(by_keywords.trajectory.q, by_problem.trajectory.q)


def test_gravity_at_the_start_is_invalid_start_for_every_kind():
    """A start where gravity alone needs more than a joint's torque limit: ``invalid_start``
    naming the torque, for a plan, a sequence (fixed modes and the mode search) and a
    straight path alike (a sequence said "could not be timed" before the pipeline)."""
    weak = JointLimits(velocity=(2.0,) * 3, acceleration=(8.0,) * 3, torque=(1e-3,) * 3)
    problem = MotionProblem(DESIGN, START, limits=weak)
    p0 = forward_batch(DESIGN, np.asarray(START.q), "+").p[0]
    any_mode = CartesianTarget(_pick_point(), "any")
    answers = [
        run(problem, GoalMotion(GOAL)),
        plan_sequence(problem, [SequenceTarget(GOAL)], objective="fixed"),
        plan_sequence(problem, [SequenceTarget(any_mode)], objective="time"),
        run(problem, StraightMotion(p0 + np.array([0.0, 0.02, 0.0]))),
    ]
    for answer in answers:
        assert answer.status is PlanStatus.INVALID_START, answer.message
        assert "gravity alone needs |tau" in answer.message
