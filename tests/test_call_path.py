"""The call path of a motion request, from its endpoint down to the OMPL search: each module
entered once (no climb back up into a module already left), and no detour through the
analysis room. Observed on real requests: the OMPL search is wrapped, and the Python stack
of the library's modules is read each time it is called."""

from __future__ import annotations

import sys

import golden_motions
import pytest

import planner.planning.compiled_rrt as compiled_rrt
import planner.planning.single_mode as single_mode
from planner.cartesian import plan as straight


def _library_stack() -> list[str]:
    """The library's modules on the caller's stack, outermost first, runs collapsed."""
    frame, names = sys._getframe(2), []
    while frame is not None:
        name = frame.f_globals.get("__name__", "")
        if name.startswith("planner"):
            names.append(name)
        frame = frame.f_back
    runs: list[str] = []
    for name in reversed(names):
        if not runs or runs[-1] != name:
            runs.append(name)
    return runs


@pytest.fixture
def searches(monkeypatch):
    """Every call path that reached the search (compiled RRT-Connect or OMPL) during the test."""
    seen: list[list[str]] = []
    real = compiled_rrt.search  # the planner's search: compiled RRT-Connect or OMPL

    def spy(*args, **kwargs):
        seen.append(_library_stack())
        return real(*args, **kwargs)

    monkeypatch.setattr(compiled_rrt, "search", spy)
    monkeypatch.setattr(single_mode.compiled_rrt, "search", spy)
    return seen


AROUND = {"goal": {"q": [1.2, 2.3, 1.3], "assembly_mode": "+"}}
SEQUENCE = {
    **golden_motions.BASE,
    "obstacles": golden_motions.OBSTACLES,
    "targets": [AROUND],
    "objective": "fixed",
}
PLAN = golden_motions.CASES["plan_obstacles"][1]
THE_PLAN_PATH = [
    "planner.endpoints.plan",
    "planner.motion.pipeline",
    "planner.solver",
    "planner.planning.goal_options",
    "planner.planning.dispatch",
    "planner.planning.single_mode",
]


def _check(paths: list[list[str]]) -> None:
    assert paths, "the request reached no OMPL search: the case tests nothing"
    for path in paths:
        assert len(path) == len(set(path)), f"a module entered twice: {path}"
        assert not [m for m in path if m.startswith("planner.analysis")], path


def test_a_plan_goes_straight_down_to_ompl(searches):
    golden_motions.run("plan", PLAN)
    _check(searches)
    assert searches[0] == THE_PLAN_PATH


def test_a_sequence_plans_its_legs_without_climbing_back(searches):
    golden_motions.run("sequence", SEQUENCE)
    _check(searches)
    assert searches[0] == [
        "planner.endpoints.sequence",
        "planner.sequence.solve",
        "planner.motion.pipeline",
        "planner.sequence.motion",
        *THE_PLAN_PATH[2:],
    ]


def test_the_mode_search_enters_each_module_once_per_assignment(searches):
    target = {"goal": {"p": golden_motions.at_posture([1.2, 2.3, 1.3]), "working_mode": "any"}}
    golden_motions.run("sequence", {**SEQUENCE, "targets": [target], "objective": "time"})
    _check(searches)
    assert searches[0][:5] == [
        "planner.endpoints.sequence",
        "planner.sequence.solve",
        "planner.sequence.mode_search",
        "planner.motion.pipeline",
        "planner.sequence.motion",
    ]


def test_a_straight_path_never_searches(searches, monkeypatch):
    walked: list[list[str]] = []
    real = straight.probe_polyline

    def spy(*args, **kwargs):
        walked.append(_library_stack())
        return real(*args, **kwargs)

    monkeypatch.setattr(straight, "probe_polyline", spy)
    golden_motions.run(*golden_motions.CASES["cartesian_line"])
    assert searches == [] and walked == [
        ["planner.endpoints.cartesian", "planner.motion.pipeline", "planner.cartesian.plan"]
    ]
