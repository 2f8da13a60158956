"""The library's one entry point :func:`plan` (exported as ``planner.planning.plan``): a
dispatcher over the three kinds of goal, which asks the single-mode planner first, plans
through transits when the goal needs another working mode, and asks the region map's proofs
when no path may exist.

Goals in the start's own mode go to the single-mode planner
(:func:`planner.planning.single_mode.plan_single_mode`) unchanged. A goal in another working mode
of the start's assembly mode is planned through serial-singularity transits
(:func:`planner.planning.mode_change.plan_mode_change`). A Cartesian target with
``working_mode`` "any" is first planned in the start's mode; the mode change is tried when
that fails, or when its estimate is shorter than :data:`BETTER_RATIO` times the single-mode
path (the shorter solved path wins).

*When the proofs are asked* (:mod:`planner.planning.proofs` says what each proves): the region
map's proof before the first OMPL search (and before a mode-change search), over every goal
candidate the request allows (:meth:`_Search.disproof`). With obstacles, a search whose first
try found nothing (single mode: the corridor's, or a short plain search; mode change:
:data:`OBSTACLE_PROOF_AFTER_S`) asks the 3-D proof before it goes on with the rest of the
budget (:meth:`_Search.obstacle_disproof`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from planner.analysis import regions as region_maps
from planner.design import Design
from planner.geometry import Obstacle
from planner.kinematics import WORKING_MODES
from planner.planning.mode_change import estimated_transit_length, plan_mode_change
from planner.planning.problem import CartesianTarget, JointPosture, PlanOptions
from planner.planning.proofs import (
    disprove_with_map,
    disprove_with_obstacles,
    proof_region_map,
)
from planner.planning.result import Diagnostics, PlanResult, PlanStatus
from planner.planning.single_mode import goal_candidates, plan_single_mode, posture_mode
from planner.validity import Margins, ValidityChecker

__all__ = [
    "BETTER_RATIO",
    "OBSTACLE_PROOF_AFTER_S",
    "plan",
]

logger = logging.getLogger(__name__)

#: "any" goal: a mode change is tried when its estimated length is below this fraction of
#: the single-mode path's length.
BETTER_RATIO = 0.7
#: With obstacles, the search time (s) after which a mode-change search that found nothing
#: asks the 3-D proof (:meth:`_Search.obstacle_disproof`) before it goes on: most plans
#: among obstacles are found well within it (``benchmarks/planning.py``), and a stuck one can
#: afford the proof's few to tens of milliseconds. A single-mode search asks it after its
#: first try (:func:`planner.planning.single_mode.plan_in_region`).
OBSTACLE_PROOF_AFTER_S = 0.03


def plan(
    design: Design,
    start: JointPosture,
    goal: JointPosture | CartesianTarget,
    *,
    obstacles: Sequence[Obstacle] = (),
    margins: Margins | None = None,
    options: PlanOptions | None = None,
) -> PlanResult:
    """Plan a valid joint path from ``start`` to ``goal``, changing working mode through serial
    singularities where the goal needs it (the assembly mode never changes). The library's
    one entry point, exported as ``planner.planning.plan``; the wire, the service and the
    CLI call it.

    One function per kind of goal: :func:`_plan_to_joint_goal`,
    :func:`_plan_to_point_in_mode` (Cartesian target in a given working mode) and
    :func:`_plan_to_point_in_any_mode` (``working_mode`` 'any'). Each asks the single-mode
    planner (:func:`planner.planning.single_mode.plan_single_mode`) first, and plans through
    transits (:func:`planner.planning.mode_change.plan_mode_change`) when that answer calls
    for it.

    Parameters
    ----------
    design : the manipulator.
    start : joint posture (its working and assembly modes come from it).
    goal : joint posture (in any working mode of the start's assembly mode), or Cartesian
        target (a specific working mode, or 'any').
    obstacles : spheres, boxes, capsules (:mod:`planner.geometry`).
    margins : default :class:`Margins`.
    options : default :class:`PlanOptions`; ``options.time_budget_s`` bounds the whole
        search (every segment and fallback).

    Returns
    -------
    PlanResult
        ``solved`` with ``path.segments`` (one per working mode visited) and
        ``path.transits`` (one per sign flip; consecutive segments share the transit
        waypoint); ``invalid_start`` / ``invalid_goal`` naming the broken rule and its value;
        ``unreachable`` when the goal lies in the other assembly mode, out of reach, breaks a
        rule in every joint solution, or no mode sequence has a transit posture (the message
        says why); ``no_path`` when the budget ran out.
    """
    t0 = time.monotonic()
    options = options if options is not None else PlanOptions()
    request = _Search(
        design,
        start,
        tuple(obstacles),
        margins if margins is not None else Margins(),
        options,
        t0,
        t0 + options.time_budget_s,
    )
    if isinstance(goal, JointPosture):
        return _plan_to_joint_goal(request, goal)
    if goal.working_mode == "any":
        return _plan_to_point_in_any_mode(request, goal)
    return _plan_to_point_in_mode(request, goal)


@dataclass(frozen=True, slots=True)
class _Search:
    """One call's search state, shared by every step of :func:`plan`: its inputs, its clock
    and deadline, and what its steps learn (goal candidates per mode, the goal sets the
    proofs were asked about). Not a problem object: :class:`planner.motion.MotionProblem`
    is that, one layer up; this lives and dies with one call."""

    design: Design
    start: JointPosture
    obstacles: tuple[Obstacle, ...]
    margins: Margins
    options: PlanOptions
    t0: float
    deadline: float
    #: goal candidates of a Cartesian target per working mode, once computed (see
    #: :meth:`goal_candidates`), and why each mode has none
    _targets: dict[str, np.ndarray] = field(default_factory=dict)
    _whys: dict[str, str] = field(default_factory=dict)
    #: every goal set :meth:`disproof` was asked about, in order (the 3-D proof reuses them)
    _asked: list[np.ndarray] = field(default_factory=list)
    #: what one call asks more than once, answered once: the proof's region map
    #: (:meth:`region_map`) and the start's working mode (:meth:`start_mode`)
    _once: dict[str, object] = field(default_factory=dict)

    def single_mode(
        self,
        goal: JointPosture | CartesianTarget,
        *,
        share: float = 1.0,
        before_search: Callable[[np.ndarray], PlanResult | None] | None = None,
    ) -> PlanResult:
        """The single-mode plan to ``goal`` with ``share`` of the time budget; by default
        the region map's proof (:meth:`disproof`) runs just before its first OMPL search.
        Among obstacles, a first try that found nothing asks :meth:`obstacle_disproof`
        about the goals that proof was asked about (every candidate the request allows)
        before the rest of the budget is searched."""
        t0 = time.monotonic()
        options = self.options
        if share != 1.0:
            options = replace(options, time_budget_s=options.time_budget_s * share)

        def when_stuck(goals: np.ndarray) -> PlanResult | None:
            asked = self._asked[-1] if self._asked else goals
            return self.obstacle_disproof(asked, searched_s=time.monotonic() - t0)

        return plan_single_mode(
            self.design,
            self.start,
            goal,
            obstacles=self.obstacles,
            margins=self.margins,
            options=options,
            before_search=self.disproof if before_search is None else before_search,
            when_stuck=when_stuck if options.region_map else None,
        )

    def _sliced(self, options: PlanOptions) -> bool:
        """Whether a mode change among obstacles first searches for
        :data:`OBSTACLE_PROOF_AFTER_S` only, then asks :meth:`obstacle_disproof`."""
        return bool(self.obstacles and options.region_map) and (
            options.time_budget_s > 2.0 * OBSTACLE_PROOF_AFTER_S
        )

    def obstacle_disproof(self, goals: np.ndarray, *, searched_s: float) -> PlanResult | None:
        """The 3-D proof with obstacles over the goal candidates ``goals`` (K, 3) (every
        candidate the request allows):
        :func:`planner.planning.proofs.disprove_with_obstacles`. ``searched_s``: how long the
        search ran before (for the message)."""
        return disprove_with_obstacles(
            self.design,
            self.margins,
            self.obstacles,
            self.start,
            goals,
            searched_s=searched_s,
            t0=self.t0,
        )

    def region_map(self) -> region_maps.RegionMap | None:
        """The design's obstacle-free region map for a proof, when it is cheap now
        (:func:`planner.planning.proofs.proof_region_map` before the request's deadline);
        asked once per call (a map absent then is not built later in the call: the budget
        only shrinks)."""
        if "rmap" not in self._once:
            self._once["rmap"] = proof_region_map(
                self.design, self.margins, self.options, self.deadline
            )
        return self._once["rmap"]  # type: ignore[return-value]

    def disproof(self, goals: np.ndarray) -> PlanResult | None:
        """The region map's proof that no valid path joins the start to any of the goal
        candidates ``goals`` (K, 3) (every candidate the request allows; valid postures):
        :func:`planner.planning.proofs.disprove_with_map`, no search run. The goals are
        remembered for the 3-D proof (:meth:`obstacle_disproof`)."""
        self._asked.append(goals)
        return disprove_with_map(self.region_map(), self.start, goals, self.t0)

    def elsewhere(self, mode: str, goals: np.ndarray) -> str | None:
        """Why no path inside working mode ``mode`` joins the start to any of the goal
        candidates ``goals`` (K, 3) of that mode, when the region map shows it: the map
        places the start and every goal, and no region of ``mode`` holds both (each region is
        a connected over-approximation of the mode's valid postures, so a path that stays in
        the mode stays in one region). None when the map cannot say (no map, a posture it
        cannot place) or a region holds both: the single-mode search is worth running.

        The dispatcher then plans through transits at once (the detour through other modes
        that joins the two regions, :func:`planner.planning.region_walks.region_walks`)
        rather than spend the budget on a search that cannot succeed."""
        rmap = self.region_map()
        if rmap is None or len(goals) == 0:
            return None
        asm = self.start.assembly_mode

        def ids(q: np.ndarray) -> set[int]:
            return {r.id for r in region_maps.regions_at(rmap, q, asm) if r.working_mode == mode}

        here = ids(self.start.q)
        there = [ids(g) for g in goals]
        if not here or not all(there) or any(here & t for t in there):
            return None
        return (
            f"the start lies in region {_ids(here)} of working mode {mode} and the goal in "
            f"region {_ids(set().union(*there))}, which no path inside the mode joins "
            f"(design region map, {rmap.n} cells)"
        )

    def start_mode(self) -> str | None:
        """The start's working mode (None where it is undefined), computed once per call."""
        if "mode" not in self._once:
            self._once["mode"] = posture_mode(self.design, self.start)
        return self._once["mode"]  # type: ignore[return-value]

    def disproof_or_detour(self, goals: np.ndarray) -> PlanResult | None:
        """The single-mode planner's ``before_search`` for a goal in the start's mode (joint
        posture, or Cartesian target in that mode), ``goals`` (K, 3) all its candidates: the
        region map's proof (:meth:`disproof`); else, when the goals lie in other regions of
        the mode than the start (:meth:`elsewhere`), the plan through transits
        (:meth:`detour`); else None (the search runs)."""
        proof = self.disproof(goals)
        mode = self.start_mode()
        if proof is not None or mode is None:
            return proof
        why = self.elsewhere(mode, goals)
        return None if why is None else self.detour(mode, {mode: goals}, why)

    def detour(self, mode: str, targets: dict[str, np.ndarray], why: str) -> PlanResult:
        """The plan through transits from the start's ``mode`` to the goal candidates
        ``targets`` (mode -> (K, 3), all the candidates the request allows, ``mode``'s own
        among them), when :meth:`elsewhere` said ``why`` no path inside ``mode`` joins the
        start to its own; the answer's message says it too."""
        res = self.mode_change(mode, targets)
        if res.diagnostics.proven_infeasible:
            return res
        return replace(res, message=f"{res.message}; {why}")

    def mode_change(
        self, start_mode: str, targets: dict[str, np.ndarray], *, prove: bool = True
    ) -> PlanResult:
        """:func:`plan_mode_change` to the goal candidates ``targets`` (mode -> (K, 3)),
        after the region map's proof (:meth:`disproof`) over all of them when ``prove``
        (only when ``targets`` are all the candidates the request allows)."""
        goals = np.vstack(list(targets.values()))
        proof = self.disproof(goals) if prove else None
        if proof is not None:
            return proof
        t0 = time.monotonic()
        rmap = self.region_map()

        def run(deadline: float) -> PlanResult:
            return plan_mode_change(
                self.design,
                self.start,
                start_mode,
                targets,
                obstacles=self.obstacles,
                margins=self.margins,
                options=self.options,
                t0=self.t0,
                deadline=deadline,
                rmap=rmap,
            )

        if not (prove and self._sliced(self.options)):
            return run(self.deadline)
        first = run(min(self.deadline, t0 + OBSTACLE_PROOF_AFTER_S))
        if first.status is not PlanStatus.NO_PATH:
            return first
        proof = self.obstacle_disproof(goals, searched_s=time.monotonic() - t0)
        if proof is not None:
            return replace(
                proof, diagnostics=replace(proof.diagnostics, searches=first.diagnostics.searches)
            )
        second = run(self.deadline)
        searches = first.diagnostics.searches + second.diagnostics.searches
        return replace(second, diagnostics=replace(second.diagnostics, searches=searches))

    def goal_candidates(
        self, p: np.ndarray, modes: Sequence[str]
    ) -> tuple[dict[str, np.ndarray], dict[str, str]]:
        """Valid joint goals of the point ``p`` (the request's goal point) in each working
        mode of ``modes`` (mode -> (K, 3), modes with none left out), and why each mode left
        out has none; computed once per mode."""
        asm = self.start.assembly_mode
        for m in modes:
            if m in self._targets or m in self._whys:
                continue
            checker = ValidityChecker(self.design, self.margins, self.obstacles, asm, m)
            cands, why = goal_candidates(self.design, CartesianTarget(p, m), checker, self.start.q)
            if len(cands):
                self._targets[m] = cands
            else:
                self._whys[m] = why
        targets = {m: self._targets[m] for m in modes if m in self._targets}
        whys = {m: self._whys[m] for m in modes if m in self._whys}
        return targets, whys

    def finish(self, status: PlanStatus, message: str) -> PlanResult:
        """An answer without a path, timed from the request's start."""
        logger.info("plan %s: %s", status.value, message)
        return PlanResult(status, message, None, Diagnostics(time.monotonic() - self.t0))


def _plan_to_joint_goal(request: _Search, goal: JointPosture) -> PlanResult:
    """A joint goal: the single-mode plan, or through transits when the goal lies in another
    working mode of the start's assembly mode (the single-mode planner answers every other
    case, checks and messages included, at no extra cost). A goal in the start's mode but
    in another region of it (:meth:`_Search.elsewhere`) is planned through transits at
    once: the detour through other modes, back to the start's."""

    first = request.single_mode(goal, before_search=request.disproof_or_detour)
    if first.status is not PlanStatus.UNREACHABLE:
        return first
    start_mode = request.start_mode()
    goal_mode = posture_mode(request.design, goal)
    if (
        start_mode is None  # pragma: no cover - the single-mode planner said invalid_start
        or goal.assembly_mode != request.start.assembly_mode
        or goal_mode in (None, start_mode)
    ):
        return first
    # the single-mode planner checked the goal in its own mode already
    return request.mode_change(start_mode, {goal_mode: goal.q[None].copy()})


def _plan_to_point_in_mode(request: _Search, goal: CartesianTarget) -> PlanResult:
    """A Cartesian target in a given working mode: the single-mode plan, or through
    transits when that mode is not the start's, or when it is but the goal's candidates lie
    in other regions of it than the start (as for a joint goal)."""

    first = request.single_mode(goal, before_search=request.disproof_or_detour)
    if first.status is not PlanStatus.UNREACHABLE:
        return first
    start_mode = request.start_mode()
    if start_mode is None:  # pragma: no cover - the single-mode planner said invalid_start
        return first
    if goal.working_mode == start_mode:
        return first
    targets, whys = request.goal_candidates(goal.p, [goal.working_mode])
    if not targets:
        return request.finish(PlanStatus.UNREACHABLE, whys[goal.working_mode])
    return request.mode_change(start_mode, targets)


def _plan_to_point_in_any_mode(request: _Search, goal: CartesianTarget) -> PlanResult:
    """A Cartesian target in working mode 'any': the start's mode first with half the
    budget, then through transits to the other modes when that fails, or when their
    estimate is shorter than :data:`BETTER_RATIO` times the single-mode path. When the start's
    own candidates lie in other regions of its mode (:meth:`_Search.elsewhere`), no
    single-mode search runs: the plan goes through transits to every mode's candidates, the
    start's mode included (a detour back to it)."""
    start_mode = request.start_mode()
    detoured = False

    def every_mode_disproof(cands: np.ndarray) -> PlanResult | None:
        # the proof must cover the goal's candidates in every working mode, not only the
        # start's ``cands``
        nonlocal detoured
        targets, _ = request.goal_candidates(goal.p, [m for m in WORKING_MODES if m != start_mode])
        proof = request.disproof(np.vstack([cands, *targets.values()]))
        assert start_mode is not None  # the single-mode planner checked the start
        why = request.elsewhere(start_mode, cands) if proof is None else None
        if why is None:
            return proof
        detoured = True
        return request.detour(start_mode, {start_mode: cands, **targets}, why)

    first = request.single_mode(goal, share=0.5, before_search=every_mode_disproof)
    if first.status is PlanStatus.INVALID_START or first.diagnostics.proven_infeasible:
        return first
    if detoured:
        return first
    if start_mode is None:  # pragma: no cover - the single-mode planner said invalid_start
        return first
    others = [m for m in WORKING_MODES if m != start_mode]
    targets, whys = request.goal_candidates(goal.p, others)
    if not targets:
        if first.solved or first.status is not PlanStatus.UNREACHABLE:
            return first
        return request.finish(
            PlanStatus.UNREACHABLE, _unreachable_everywhere({start_mode: first.message, **whys})
        )
    if first.solved:
        return _shorter_through_transits(request, first, start_mode, targets)
    if first.status is PlanStatus.NO_PATH:  # the start's own candidates count too
        own, _ = request.goal_candidates(goal.p, [start_mode])
        proof = request.disproof(np.vstack([*own.values(), *targets.values()]))
        if proof is not None:
            return proof
    # ``targets`` are all the candidates only when the start's mode has none
    other = request.mode_change(start_mode, targets, prove=first.status is PlanStatus.UNREACHABLE)
    if other.solved or first.status is PlanStatus.UNREACHABLE:
        return other
    return other if other.status is PlanStatus.NO_PATH else first


def _ids(ids: set[int]) -> str:
    """Region ids for a message: '25' or '25 or 27'."""
    return " or ".join(str(i) for i in sorted(ids))


def _unreachable_everywhere(whys: dict[str, str]) -> str:
    """The message of a Cartesian goal no working mode reaches: each distinct reason once,
    with the modes it holds in (a point out of a leg's reach is one reason for all eight)."""
    modes: dict[str, list[str]] = {}
    for mode, why in whys.items():
        modes.setdefault(why, []).append(mode)
    if len(modes) == 1 and "every working mode" in next(iter(modes)):
        return next(iter(modes))
    parts = [
        _in_mode(ms[0], why) if len(ms) == 1 else f"in working modes {', '.join(ms)} {why}"
        for why, ms in modes.items()
    ]
    return "the goal point is unreachable in every working mode: " + "; ".join(parts)


def _in_mode(mode: str, why: str) -> str:
    """``why`` a goal is unreachable in ``mode``, naming the mode once."""
    return why if f"working mode {mode}" in why else f"in {mode} {why}"


def _shorter_through_transits(
    request: _Search, first: PlanResult, start_mode: str, targets: dict[str, np.ndarray]
) -> PlanResult:
    """The shorter of the solved single-mode plan ``first`` and a plan through transits to
    ``targets``; the transit search runs only when it may beat ``first`` by
    :data:`BETTER_RATIO`."""
    limit = BETTER_RATIO * first.diagnostics.path_length
    # a path is never shorter than the straight distance to its goal: skip the transit
    # sampling when no goal candidate of another mode is close enough
    bound = min(float(np.linalg.norm(c[0] - request.start.q)) for c in targets.values())
    if not bound < limit:
        return first
    best = estimated_transit_length(
        request.design,
        request.start,
        start_mode,
        targets,
        obstacles=request.obstacles,
        margins=request.margins,
        options=request.options,
        deadline=request.deadline,
    )
    if not best < limit:
        return first
    other = request.mode_change(start_mode, targets, prove=False)
    if other.solved and other.diagnostics.path_length < first.diagnostics.path_length:
        return other
    planning_time_s = time.monotonic() - request.t0
    return replace(first, diagnostics=replace(first.diagnostics, planning_time_s=planning_time_s))
