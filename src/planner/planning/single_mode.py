"""Single-mode planning: :func:`plan_single_mode` and its building block :func:`plan_in_region`.

The library's entry point is :func:`planner.planning.plan` (:mod:`planner.planning.dispatch`),
which calls :func:`plan_single_mode` first and changes working mode when the goal needs it.
A single-mode plan lives in one working mode and one assembly mode, both taken from the start
posture.
Steps: check start and goal (a broken rule gives ``invalid_start`` / ``invalid_goal`` with the
rule and the measured value); turn a Cartesian goal into joint candidates (inverse kinematics
in the start's modes, every 2 pi shift inside the joint limits, valid ones ordered by joint
distance); try the straight motion; otherwise search with OMPL, simplify, and re-certify the
final path with :meth:`ValidityChecker.check_path`.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from itertools import product

import numpy as np

from planner.design import Design
from planner.geometry import Obstacle
from planner.kinematics import (
    WORKING_MODES,
    forward_batch,
    inverse_batch,
    mode_label,
    reach_reason,
)
from planner.planning import compiled_rrt, corridor
from planner.planning.problem import CartesianTarget, JointPosture, PlanOptions
from planner.planning.result import Diagnostics, PlanPath, PlanResult, PlanStatus, Segment
from planner.validity import Margins, ValidityChecker, assembly_reason

__all__ = [
    "goal_candidates",
    "joint_shifts",
    "plan_in_region",
    "plan_single_mode",
    "plan_to_goal_set",
    "posture_mode",
]

logger = logging.getLogger(__name__)

#: The hook of :func:`plan_in_region` run just before its first OMPL search: goal
#: candidates (K, 3) -> the answer without a search, or None to search.
BeforeSearch = Callable[[np.ndarray], PlanResult | None]


def posture_mode(design: Design, posture: JointPosture) -> str | None:
    """Working mode label of a joint posture in its assembly mode, or None when the loop does
    not close or a serial measure is exactly zero (the mode is undefined there)."""
    fb = forward_batch(design, posture.q, posture.assembly_mode)
    if not fb.ok[0]:
        return None
    label = mode_label(fb.working_mode_signs[0])
    return label if label in WORKING_MODES else None


def joint_shifts(design: Design, q: np.ndarray) -> np.ndarray:
    """Every posture q + 2 pi k (k integer per joint) inside the design's joint limits, (S, 3)
    (S may be 0): the same posture of the robot reached with other joint values."""
    lo, hi = np.asarray(design.joint_min), np.asarray(design.joint_max)
    shifts = []
    for j in range(3):
        k_lo = math.ceil((lo[j] - q[j]) / (2 * math.pi) - 1e-12)
        k_hi = math.floor((hi[j] - q[j]) / (2 * math.pi) + 1e-12)
        shifts.append([q[j] + 2 * math.pi * k for k in range(k_lo, k_hi + 1)])
    return np.array(list(product(*shifts)), dtype=float).reshape(-1, 3)


def goal_candidates(
    design: Design, target: CartesianTarget, checker: ValidityChecker, q_start: np.ndarray
) -> tuple[np.ndarray, str]:
    """Valid joint goals for a Cartesian target in the checker's working and assembly mode.

    Returns
    -------
    candidates : array (K, 3), rad, ordered by Euclidean joint distance to ``q_start``; K may
        be 0.
    why : when K = 0, the reason (for the ``unreachable`` message).
    """
    mode = checker.working_mode
    if target.working_mode not in ("any", mode):
        return np.empty((0, 3)), (
            f"the goal's working mode {target.working_mode} differs from the start's {mode}: "
            "a single-mode plan cannot change working mode"
        )
    ik = inverse_batch(design, target.p)
    if ik.degenerate[0]:
        return np.empty((0, 3)), "the goal point is degenerate (P on a pivot with L1 = L2)"
    slot = WORKING_MODES.index(mode)
    if not ik.ok[0, slot]:
        why = reach_reason(design, target.p) if not ik.ok[0].any() else None
        if why is not None:  # the same reason in every mode: said without one
            return np.empty((0, 3)), f"the goal point is unreachable in every working mode: {why}"
        return np.empty((0, 3)), f"the goal point is out of reach in working mode {mode}"
    q = ik.q[0, slot]
    asm = int(ik.assembly_mode_signs[0, slot])
    want = 1 if checker.assembly_mode == "+" else -1
    if asm != want:
        return np.empty((0, 3)), (
            f"in working mode {mode} the goal point is only reached in assembly mode "
            f"{'+' if asm > 0 else '-'}, not the start's {checker.assembly_mode}"
        )
    cands = joint_shifts(design, q)
    if len(cands) == 0:
        return (
            cands,
            f"the inverse-kinematics solution in working mode {mode} breaks the joint limits",
        )
    report = checker.check_states(cands)
    if not report.valid.any():
        return np.empty((0, 3)), "the goal posture breaks a rule: " + checker.explain(cands[0])
    cands = cands[report.valid]
    order = np.argsort(np.linalg.norm(cands - q_start, axis=1), kind="stable")
    return cands[order], ""


def _mode_undefined(design: Design, posture: JointPosture, which: str) -> str:
    """Why a posture has no working mode, with the measured values: it does not assemble
    (|CD|), or it lies exactly on a serial singularity (the serial measures)."""
    fb = forward_batch(design, posture.q, posture.assembly_mode)
    if not fb.ok[0]:
        return f"{which} {assembly_reason(design, posture.q)}"
    return (
        f"{which} working_mode: the {which} lies exactly on a serial singularity "
        f"(serial measures {np.round(fb.serial_measures[0], 9).tolist()})"
    )


def plan_single_mode(
    design: Design,
    start: JointPosture,
    goal: JointPosture | CartesianTarget,
    *,
    obstacles: Sequence[Obstacle] = (),
    margins: Margins | None = None,
    options: PlanOptions | None = None,
    before_search: BeforeSearch | None = None,
    when_stuck: BeforeSearch | None = None,
) -> PlanResult:
    """Plan a valid joint path from ``start`` to ``goal`` inside the start's working mode.

    The first step of :func:`planner.planning.plan`, which goes on through transits when
    this one answers ``unreachable`` for a goal in another working mode. Call this one
    directly for a plan that must stay in the start's working mode.

    Parameters
    ----------
    design : the manipulator.
    start : joint posture; its working mode (from its signs) and assembly mode are the plan's.
    goal : joint posture, or Cartesian target (``working_mode`` 'any' or the start's).
    obstacles : spheres, boxes, capsules (:mod:`planner.geometry`).
    margins : default :class:`Margins`.
    options : default :class:`PlanOptions`.
    before_search : called once with the goal candidates (K, 3) after the checks and the
        straight motion, just before the first OMPL search (see :func:`plan_in_region`).
    when_stuck : called once with the goal candidates when a first short search (and the
        corridor) found nothing, before the rest of the budget is searched (see
        :func:`plan_in_region`).

    Returns
    -------
    PlanResult
        ``solved`` with a path whose every motion is certified; ``invalid_start`` /
        ``invalid_goal`` naming the broken rule and its value; ``unreachable`` when a goal
        lies in another working or assembly mode, out of reach, or breaks a rule in every
        joint solution; ``no_path`` when the search budget ran out.
    """
    t0 = time.monotonic()
    margins = margins if margins is not None else Margins()
    options = options if options is not None else PlanOptions()

    def finish(status: PlanStatus, message: str, path=None, **diag) -> PlanResult:
        d = Diagnostics(planning_time_s=time.monotonic() - t0, **diag)
        if status is not PlanStatus.SOLVED:
            logger.info("plan %s: %s", status.value, message)
        return PlanResult(status, message, path, d)

    goal_mode = None
    if isinstance(goal, JointPosture):  # one kinematics call for both modes
        asm: str | np.ndarray = start.assembly_mode
        if goal.assembly_mode != asm:
            asm = np.array([1.0 if p.assembly_mode == "+" else -1.0 for p in (start, goal)])
        fb = forward_batch(design, np.array([start.q, goal.q]), asm)
        labels = [
            mode_label(sg) if ok else None
            for sg, ok in zip(fb.working_mode_signs, fb.ok, strict=True)
        ]
        mode, goal_mode = (lab if lab in WORKING_MODES else None for lab in labels)
    else:
        mode = posture_mode(design, start)
    if mode is None:
        return finish(PlanStatus.INVALID_START, _mode_undefined(design, start, "start"))
    checker = ValidityChecker(design, margins, obstacles, start.assembly_mode, mode)
    if not checker.is_valid_one(*start.q):
        return finish(PlanStatus.INVALID_START, "start " + checker.explain(start.q))

    if isinstance(goal, JointPosture):
        goal_checker = checker if goal_mode in (None, mode) else checker.with_mode(goal_mode)
        if goal_mode is None:
            return finish(PlanStatus.INVALID_GOAL, _mode_undefined(design, goal, "goal"))
        if goal.assembly_mode == start.assembly_mode and not goal_checker.is_valid_one(*goal.q):
            return finish(PlanStatus.INVALID_GOAL, "goal " + goal_checker.explain(goal.q))
        if goal.assembly_mode != start.assembly_mode:
            return finish(
                PlanStatus.UNREACHABLE,
                f"the goal is in assembly mode {goal.assembly_mode}, the start in "
                f"{start.assembly_mode}: changing assembly mode crosses a parallel singularity",
            )
        if goal_mode != mode:
            return finish(
                PlanStatus.UNREACHABLE,
                f"the goal is in working mode {goal_mode}, the start in {mode}: "
                "a single-mode plan cannot change working mode",
            )
        candidates = goal.q[None].copy()
    else:
        candidates, why = goal_candidates(design, goal, checker, start.q)
        if len(candidates) == 0:
            return finish(PlanStatus.UNREACHABLE, why)

    return plan_in_region(
        checker,
        start.q,
        candidates,
        options=options,
        before_search=before_search,
        when_stuck=when_stuck,
        _t0=t0,
    )


def plan_in_region(
    checker: ValidityChecker,
    q_start: np.ndarray,
    q_goals: np.ndarray,
    *,
    options: PlanOptions | None = None,
    before_search: BeforeSearch | None = None,
    when_stuck: BeforeSearch | None = None,
    _t0: float | None = None,
) -> PlanResult:
    """Plan inside the region of a validity checker from ``q_start`` to the first reachable
    of the goal candidates ``q_goals`` (K, 3), rad, tried in order.

    The building block of :func:`plan_single_mode` and of the mode-change planner, which
    plans each segment between postures it chose (e.g. next to a transit) with its own
    checker. Start and goals must be valid for ``checker`` (not re-checked here); the
    straight motion is tried first, then OMPL within ``options.time_budget_s`` in total;
    with obstacles and ``options.corridor``, the search is guided by the corridor grid of
    the checker's valid set (a short plain search here first when the grid is not cached,
    then :func:`planner.planning.corridor.guided_search`: the grid's path, shortcut and certified;
    ``diagnostics.planner`` is 'corridor' when it produced the path), and the plain search
    gets what remains of the budget when the corridor finds nothing.
    ``before_search``, when given, is called once with ``q_goals`` just before the first OMPL
    search (the straight motion failed); a result it returns is the answer, no search run
    (the planner's proof that no path exists, :func:`planner.planning.dispatch.plan`).
    ``when_stuck``, when given and the scene has obstacles, is called once with ``q_goals``
    when the first try found nothing (the corridor, when its grid is cached; else a plain
    search of :data:`planner.planning.corridor.FIRST_TRY_S`), before a corridor grid is built:
    a result it returns is the answer (the proof with obstacles, which costs too much to run
    before every search but less than a grid build), else the search goes on.

    Returns
    -------
    PlanResult
        ``solved`` (one segment in the checker's modes, every motion certified) or
        ``no_path``; ``diagnostics.searches`` counts the OMPL searches run.
    """
    t0 = time.monotonic() if _t0 is None else _t0
    options = options if options is not None else PlanOptions()
    q_start = np.array(q_start, dtype=float)
    q_goals = np.atleast_2d(np.array(q_goals, dtype=float))
    deadline = time.monotonic() + options.time_budget_s
    attempts = searches = 0
    last_status = ""
    for q_goal in q_goals:
        attempts += 1
        waypoints, name, certified = None, "", False
        if options.try_direct and checker.motion_valid(q_start, q_goal):
            waypoints, name, certified = np.array([q_start, q_goal]), "direct", True
        elif (walked := compiled_rrt.walk(checker, q_start, q_goal, options)) is not None:
            # a path remembered in the scene joins them: a path exists, no proof is asked
            waypoints, name, certified = walked.waypoints, options.name, True
        else:
            if before_search is not None:
                answer, before_search = before_search(q_goals), None
                if answer is not None:
                    return answer
            budget = deadline - time.monotonic()
            if budget <= 0:
                break
            # with obstacles: the corridor at once when its grid is cached; else a short
            # first try, the proof with obstacles when it fails (cheaper than a grid
            # build), then the corridor with a grid built now
            guide = bool(options.corridor and checker.obstacles)
            stuck = when_stuck is not None and bool(checker.obstacles)
            if guide and corridor.cached_corridor_grid(checker) is not None:
                guided = corridor.guided_search(checker, q_start, q_goal, options, deadline)
                searches += guided.searches
                last_status = guided.ompl_status or last_status
                waypoints, name, certified = guided.waypoints, guided.name, guided.certified
                guide = False
            elif stuck or guide:
                searches += 1
                first_try = min(budget, corridor.FIRST_TRY_S)
                outcome = compiled_rrt.search(
                    checker, q_start, q_goal, options, first_try, walked=True
                )
                last_status = outcome.ompl_status
                if outcome.waypoints is not None:
                    waypoints, name = outcome.waypoints, options.name
                    certified = outcome.certified
            if waypoints is None and stuck and when_stuck is not None:
                answer, when_stuck = when_stuck(q_goals), None
                if answer is not None:
                    return replace(
                        answer, diagnostics=replace(answer.diagnostics, searches=searches)
                    )
            if waypoints is None and guide:
                guided = corridor.guided_search(checker, q_start, q_goal, options, deadline)
                searches += guided.searches
                last_status = guided.ompl_status or last_status
                waypoints, name, certified = guided.waypoints, guided.name, guided.certified
            budget = deadline - time.monotonic()
            if waypoints is None and budget > 0:
                searches += 1
                outcome = compiled_rrt.search(
                    checker, q_start, q_goal, options, budget, walked=True
                )
                last_status = outcome.ompl_status
                if outcome.waypoints is not None:
                    waypoints, name = outcome.waypoints, options.name
                    certified = outcome.certified
        if waypoints is None:
            continue
        waypoints[0], waypoints[-1] = q_start, q_goal  # exact ends (OMPL copies them anyway)
        solved = _certified(checker, waypoints, name, certified, t0, attempts, searches)
        if solved is not None:
            return solved
    return _no_path(checker, options, last_status, t0, attempts, searches)


def _certified(
    checker: ValidityChecker,
    waypoints: np.ndarray,
    name: str,
    certified: bool,
    t0: float,
    attempts: int,
    searches: int,
) -> PlanResult | None:
    """The ``solved`` answer of a found path after its final re-certification, except of
    motions certified already (``certified``: the straight motion; a corridor path without
    OMPL repairs, each motion by the motion test; a compiled search's path,
    :mod:`planner.planning.compiled_rrt`); None when it fails."""
    report = checker.check_path(waypoints, certify=not certified)
    if not report.valid:  # pragma: no cover - would be a validator bug
        logger.error(
            "a found path failed re-certification at motion %d (%s)",
            report.bad_motion,
            report.reason,
        )
        return None
    mode, asm = checker.working_mode, checker.assembly_mode
    path = PlanPath(waypoints, (Segment(mode, asm, 0, len(waypoints) - 1),), ())
    return PlanResult(
        PlanStatus.SOLVED,
        f"solved in working mode {mode} ({name})",
        path,
        Diagnostics(
            planning_time_s=time.monotonic() - t0,
            path_length=report.length,
            min_clearance=report.min_clearance,
            max_kappa_A=report.max_kappa_A,
            min_serial_margin=report.min_serial_margin,
            planner=name,
            attempts=attempts,
            searches=searches,
        ),
    )


def _no_path(
    checker: ValidityChecker,
    options: PlanOptions,
    last_status: str,
    t0: float,
    attempts: int,
    searches: int,
) -> PlanResult:
    message = (
        f"no path found within {options.time_budget_s:g} s in working mode "
        f"{checker.working_mode}" + (f" (OMPL: {last_status})" if last_status else "")
    )
    logger.info("plan no_path: %s", message)
    return PlanResult(
        PlanStatus.NO_PATH,
        message,
        None,
        Diagnostics(planning_time_s=time.monotonic() - t0, attempts=attempts, searches=searches),
    )


def plan_to_goal_set(
    checker: ValidityChecker,
    q_start: np.ndarray,
    q_goals: np.ndarray,
    *,
    options: PlanOptions | None = None,
    search_goals: int = 32,
    before_search: BeforeSearch | None = None,
) -> PlanResult:
    """Plan inside the checker's region from ``q_start`` to *any* of the goal postures
    ``q_goals`` (K, 3) (valid for ``checker``, in order of preference): a set searched as a
    set, for a goal tolerance. The straight motion to each goal first, in order (the first
    that is certified is the answer); then one OMPL search towards at most ``search_goals``
    of them at once (OMPL's ``GoalStates``; spread evenly over the list, the first one
    included) within ``options.time_budget_s``; the path is re-certified.
    ``diagnostics.attempts`` is the number of straight motions tried. ``before_search``, when
    given, is called once with ``q_goals`` after the straight motions failed, before the
    search: a result it returns is the answer (the proof over the whole goal set)."""
    t0 = time.monotonic()
    options = options if options is not None else PlanOptions()
    q_start = np.array(q_start, dtype=float)
    q_goals = np.atleast_2d(np.array(q_goals, dtype=float))
    attempts = 0
    if options.try_direct:
        for q_goal in q_goals:
            attempts += 1
            if checker.motion_valid(q_start, q_goal):
                waypoints = np.stack([q_start, q_goal])
                return _certified(checker, waypoints, "direct", True, t0, attempts, 0) or (
                    _no_path(checker, options, "", t0, attempts, 0)
                )
    if before_search is not None:
        answer = before_search(q_goals)
        if answer is not None:
            return answer
    budget = options.time_budget_s - (time.monotonic() - t0)
    if budget <= 0:
        return _no_path(checker, options, "", t0, attempts, 0)
    if len(q_goals) > search_goals:
        q_goals = q_goals[np.linspace(0, len(q_goals) - 1, search_goals).round().astype(int)]
    outcome = compiled_rrt.search(checker, q_start, q_goals, options, budget)
    if outcome.waypoints is not None:
        waypoints = outcome.waypoints
        end = int(np.argmin(np.linalg.norm(q_goals - waypoints[-1], axis=1)))
        waypoints[0], waypoints[-1] = q_start, q_goals[end]  # exact ends (OMPL's are copies)
        solved = _certified(checker, waypoints, options.name, False, t0, attempts, 1)
        if solved is not None:
            return solved
    return _no_path(checker, options, outcome.ompl_status, t0, attempts, 1)
