"""The OMPL side of single-mode planning: state space, validity callbacks, planners, seeds,
simplification. The only module of the product that imports ``ompl``.

Every OMPL object lives inside :func:`search` and is dropped before it returns (objects alive
at interpreter exit make nanobind print "leaked" warnings). OMPL's own log is silenced on import
(``LOG_NONE``): its messages would go to stderr past our logging, and the outcomes that matter
come back as statuses. Two of its messages are harmless anyway: ``RNG.setSeed`` logs an error
when a seed is set after sampling began, although the new seed still takes effect, and AORRTC
logs one when its first solution is the straight start-goal motion.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

from planner.planning.problem import PlanOptions
from planner.validity import ValidityChecker

__all__ = ["DEFAULT_RANGE", "SearchOutcome", "search"]

logger = logging.getLogger(__name__)
ou.setLogLevel(ou.LOG_NONE)

#: Default ``range`` (longest motion added at once, rad, Euclidean) of tree planners, tuned
#: on ``benchmarks/planning.py``.
DEFAULT_RANGE = 1.0

_FACTORIES = {
    "rrtconnect": og.RRTConnect,
    "rrt": og.RRT,
    "rrtstar": og.RRTstar,
    "prmstar": og.PRMstar,
    "bitstar": og.BITstar,
    "aorrtc": og.AORRTC,
    "lbkpiece": og.LBKPIECE1,
}
_WITH_RANGE = ("rrtconnect", "rrt", "rrtstar", "aorrtc", "lbkpiece")


@dataclass(frozen=True, slots=True)
class SearchOutcome:
    """``waypoints`` (N, 3) or None; ``exact``: OMPL found an exact solution; ``ompl_status``:
    OMPL's status string; ``simplified``: the simplified path was kept; ``certified``: every
    motion of ``waypoints`` passed the motion certificate on its way into the path (the
    compiled search's paths, :mod:`planner.planning.compiled_rrt`; OMPL's are re-certified
    by the planner, its simplifier's motions being its validator's); ``nodes``: the compiled
    search's tree nodes (0 for OMPL's and for a remembered path)."""

    waypoints: np.ndarray | None
    exact: bool
    ompl_status: str
    simplified: bool
    certified: bool = False
    nodes: int = 0


def _seed(seed: int) -> None:
    level = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)
    try:
        ou.RNG.setSeed(seed)
    finally:
        ou.setLogLevel(level)


def _make_motion_validator(si, checker: ValidityChecker):
    """A ``MotionValidator`` whose two-state ``checkMotion`` certifies the whole motion in one
    compiled call (:meth:`ValidityChecker.motion_test`, the certificate of
    :meth:`ValidityChecker.check_motion`)."""
    motion_test = checker.motion_test()

    class _Certified(ob.MotionValidator):
        def checkMotion(self, s1, s2):
            return motion_test(np.array((s1[0], s1[1], s1[2])), np.array((s2[0], s2[1], s2[2])))

    return _Certified(si)


def search(
    checker: ValidityChecker,
    q_start: np.ndarray,
    q_goal: np.ndarray,
    options: PlanOptions,
    time_budget_s: float,
    *,
    naive_resolution: float | None = None,
    naive_defaults: bool = False,
) -> SearchOutcome:
    """Plan from ``q_start`` to ``q_goal`` (3,) rad inside the checker's region with OMPL;
    ``q_goal`` (K, 3) is a set of goal postures (OMPL's ``GoalStates``: the path ends at one
    of them, whichever the search meets first).

    Parameters
    ----------
    checker : the region (design limits are the state-space bounds).
    options : planner name, seed, simplification, range.
    time_budget_s : search budget, s (simplification runs after it, a few ms).
    naive_resolution : None for the product set-up. A value (rad) selects the *naive*
        set-up used by ``benchmarks/planning.py`` for comparison (the fair baseline): OMPL's
        default discrete motion validator at that resolution (0: OMPL's own default, 1 % of
        the state space's extent, 0.109 rad over [-pi, pi]^3) calling the product's fastest
        single-posture check (:meth:`ValidityChecker.is_valid_one`) per state. Its paths are
        sampled, not certified.
    naive_defaults : with ``naive_resolution``, also keep OMPL's defaults elsewhere: the
        planner's own range, and ``simplifyMax`` (what ``SimpleSetup.simplifySolution()``
        does) instead of our shortcut-and-reduce simplification.

    Returns
    -------
    SearchOutcome
    """
    design = checker.design
    space = ob.RealVectorStateSpace(3)
    bounds = ob.RealVectorBounds(3)
    for i in range(3):
        bounds.setLow(i, float(design.joint_min[i]))
        bounds.setHigh(i, float(design.joint_max[i]))
    space.setBounds(bounds)
    si = ob.SpaceInformation(space)
    validator = None
    if naive_resolution is None:
        si.setStateValidityChecker(lambda s: checker.is_valid_one(s[0], s[1], s[2]))
        validator = _make_motion_validator(si, checker)
        si.setMotionValidator(validator)
    else:
        si.setStateValidityChecker(lambda s: checker.is_valid_one(s[0], s[1], s[2]))
        if naive_resolution > 0:
            si.setStateValidityCheckingResolution(naive_resolution / space.getMaximumExtent())
    si.setup()
    _seed(options.seed)
    goals_q = np.asarray(q_goal, dtype=float).reshape(-1, 3)
    start = space.allocState()
    for i in range(3):
        start[i] = float(q_start[i])
    pdef = ob.ProblemDefinition(si)
    goal_set = None
    if len(goals_q) == 1:
        goal = space.allocState()
        for i in range(3):
            goal[i] = float(goals_q[0, i])
        pdef.setStartAndGoalStates(start, goal)
    else:
        pdef.addStartState(start)
        goal_set = ob.GoalStates(si)
        for g in goals_q:
            goal = space.allocState()
            for i in range(3):
                goal[i] = float(g[i])
            goal_set.addState(goal)
        pdef.setGoal(goal_set)
    planner = _FACTORIES[options.name](si)
    if options.name in _WITH_RANGE and not (naive_defaults and options.range is None):
        planner.setRange(options.range if options.range is not None else DEFAULT_RANGE)
    planner.setProblemDefinition(pdef)
    planner.setup()
    status = planner.solve(float(time_budget_s))
    exact = bool(pdef.hasExactSolution())
    waypoints = None
    simplified = False
    if exact:
        path = pdef.getSolutionPath()
        raw = _waypoints(path)
        waypoints = raw
        if options.simplify:
            t0 = time.monotonic()
            simplifier = og.PathSimplifier(si)
            # rope shortcutting then vertex reduction: on benchmarks/planning.py within 3 % of
            # the length of OMPL's full simplify() at a third of its time
            if naive_defaults:
                simplifier.simplifyMax(path)
            else:
                simplifier.ropeShortcutPath(path)
                simplifier.reduceVertices(path)
            # the simplifier only keeps motions the validator accepted; the caller
            # (plan_in_region) certifies the final path once more
            waypoints, simplified = _waypoints(path), True
            logger.debug("simplification took %.4f s", time.monotonic() - t0)
            del simplifier
        del path
    ompl_status = str(status)
    # drop OMPL objects in a safe order (planner, problem, validator, space information)
    del planner, pdef, start, goal, goal_set, validator, si, space, bounds
    return SearchOutcome(waypoints, exact, ompl_status, simplified)


def _waypoints(path) -> np.ndarray:
    n = path.getStateCount()
    out = np.empty((n, 3))
    for k in range(n):
        s = path.getState(k)
        out[k] = (s[0], s[1], s[2])
    return out
