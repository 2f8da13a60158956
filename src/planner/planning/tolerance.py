"""A goal with a tolerance: the set of goals it allows, searched as a set, and a proof that
covers the whole set or no claim at all.

``goal.tolerance`` (MoveIt's goal tolerance) lets a plan end anywhere within ``tolerance`` of
the asked goal: P within that many metres of a Cartesian target's point (in the target's
working mode, or any mode for "any"), or q within that many radians (Euclidean) of a joint
goal. :func:`plan_within_tolerance` runs when the exact goal's plan was not solved:

1. *The goal set* (:func:`sample_goal_set`): the asked goal, the points towards the start
   and along the axes at the full tolerance (:func:`goal_alternatives`), and
   :data:`SAMPLES` points drawn uniformly in the ball (seeded with ``options.seed``); their
   inverse kinematics in every allowed working mode (the start's assembly mode, every 2 pi
   shift inside the joint limits), kept when valid for that mode's checker, nearest to the
   asked goal first (at most :data:`MAX_PER_MODE` per mode).
2. *The search* over that set: in the start's working mode, the straight motion to each goal
   in turn, then one OMPL search towards all of them at once
   (:func:`planner.planning.single_mode.plan_to_goal_set`); goals of other modes through transits
   (:func:`planner.planning.mode_change.plan_mode_change`, which takes a set of goals per mode).
   The two share one more ``options.time_budget_s``.
3. *The proof*, asked once after the straight motions failed and before the first search
   (milliseconds, where a search spends its budget), or when no goal was found: the region
   map's proofs asked about every cell that may hold an allowed goal (:mod:`planner.analysis.goal_cells`: the obstacle-free map, then,
   with obstacles, the 3-D map). ``diagnostics.proven_infeasible`` is set only then: it is a
   promise about every goal the request allows. Where the proof cannot cover the set, the
   answer is a plain ``no_path`` whose message says so; the exact goal's own proof (which
   covers its point only) is never passed on.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from planner.analysis.goal_cells import GoalBall, prove_ball_disconnected
from planner.analysis.obstacle_regions import prove_disconnected_with_obstacles
from planner.design import Design
from planner.geometry import Obstacle
from planner.kinematics import WORKING_MODES, forward_batch, inverse_batch, mode_label
from planner.planning.mode_change import plan_mode_change
from planner.planning.problem import CartesianTarget, JointPosture, PlanOptions
from planner.planning.proofs import proof_region_map
from planner.planning.result import Diagnostics, PlanResult, PlanStatus, proven_no_path
from planner.planning.single_mode import joint_shifts, plan_to_goal_set, posture_mode
from planner.validity import Margins, ValidityChecker

__all__ = [
    "MAX_PER_MODE",
    "SAMPLES",
    "SEARCH_GOALS",
    "GoalSet",
    "goal_alternatives",
    "goal_ball",
    "plan_within_tolerance",
    "prove_goal_set",
    "sample_goal_set",
]

logger = logging.getLogger(__name__)

#: Points drawn uniformly in a tolerance ball, besides the asked goal and the fixed ones.
SAMPLES = 256
#: Goal postures kept per working mode, nearest to the asked goal first: every one is tried
#: by a straight motion (a cheap certified test each).
MAX_PER_MODE = 256
#: Goals per working mode handed to a search (OMPL's goal set in the start's mode, the
#: transit planner's candidates in another), spread over the kept ones from near to far.
SEARCH_GOALS = 32
#: Goals are placed this much inside the tolerance (a rounding must not leave it).
_INSIDE = 1.0 - 1e-9


def goal_alternatives(goal: np.ndarray, towards: np.ndarray, tolerance: float) -> np.ndarray:
    """Goals within ``tolerance`` (Euclidean) of ``goal`` (3,), the first ones tried:
    towards ``towards`` (the start's P or q) at the full tolerance and at half of it, then
    +-x, +-y, +-z (+-theta1.. for joints) at the full tolerance. Shape (K, 3)."""
    goal = np.asarray(goal, dtype=float)
    r = tolerance * _INSIDE
    d = np.asarray(towards, dtype=float) - goal
    out = []
    n = float(np.linalg.norm(d))
    if n > 0.0:
        u = d / n
        out += [goal + min(r, n) * u, goal + min(0.5 * r, n) * u]
    for axis in range(3):
        for sign in (1.0, -1.0):
            e = np.zeros(3)
            e[axis] = sign * r
            out.append(goal + e)
    return np.asarray(out)


def goal_ball(goal: JointPosture | CartesianTarget, tolerance: float) -> GoalBall:
    """Every goal the request allows, as the proofs see it."""
    if isinstance(goal, CartesianTarget):
        modes = WORKING_MODES if goal.working_mode == "any" else (goal.working_mode,)
        return GoalBall("point", goal.p, tolerance, modes)
    return GoalBall("joint", goal.q, tolerance)


@dataclass(frozen=True, slots=True)
class GoalSet:
    """Valid goals inside a tolerance ball.

    Attributes
    ----------
    ball : the set the request allows.
    targets : working mode -> (K, 3) valid goal postures in that mode (the start's assembly
        mode), nearest to the asked goal first; modes without one left out.
    offsets : working mode -> (K,) how far each goal is from the asked one (m of P, or rad).
    sampled : how many points (or postures) of the ball were examined.
    """

    ball: GoalBall
    targets: dict[str, np.ndarray]
    offsets: dict[str, np.ndarray]
    sampled: int

    @property
    def count(self) -> int:
        return sum(len(t) for t in self.targets.values())


def _ball_points(centre: np.ndarray, towards: np.ndarray, radius: float, seed: int) -> np.ndarray:
    """The asked goal, :func:`goal_alternatives`, then :data:`SAMPLES` uniform points."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(SAMPLES, 3))
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    r = radius * _INSIDE * rng.random(SAMPLES) ** (1.0 / 3.0)
    return np.vstack([centre, goal_alternatives(centre, towards, radius), centre + d * r[:, None]])


def sample_goal_set(
    design: Design,
    start: JointPosture,
    goal: JointPosture | CartesianTarget,
    tolerance: float,
    *,
    obstacles: Sequence[Obstacle] = (),
    margins: Margins | None = None,
    seed: int = 1,
) -> GoalSet:
    """The valid goals of the tolerance ball around ``goal`` (see the module docstring)."""
    margins = margins if margins is not None else Margins()
    ball = goal_ball(goal, tolerance)
    asm = start.assembly_mode
    postures: list[np.ndarray] = []
    modes: list[str] = []
    offsets: list[float] = []
    if isinstance(goal, CartesianTarget):
        fb = forward_batch(design, start.q, asm)
        towards = fb.p[0] if fb.ok[0] else goal.p
        points = _ball_points(goal.p, towards, tolerance, seed)
        ik = inverse_batch(design, points)
        want = 1 if asm == "+" else -1
        for i, point in enumerate(points):
            if ik.degenerate[i]:
                continue
            for m in ball.working_modes:
                slot = WORKING_MODES.index(m)
                if ik.ok[i, slot] and int(ik.assembly_mode_signs[i, slot]) == want:
                    for q in joint_shifts(design, ik.q[i, slot]):
                        postures.append(q)
                        modes.append(m)
                        offsets.append(float(np.linalg.norm(point - goal.p)))
    elif goal.assembly_mode == asm:
        points = _ball_points(goal.q, start.q, tolerance, seed)
        fb = forward_batch(design, points, asm)
        for q, ok, signs in zip(points, fb.ok, fb.working_mode_signs, strict=True):
            label = mode_label(signs) if ok else ""
            if label in WORKING_MODES:
                postures.append(q)
                modes.append(label)
                offsets.append(float(np.linalg.norm(q - goal.q)))
    else:
        points = np.empty((0, 3))
    targets: dict[str, np.ndarray] = {}
    dists: dict[str, np.ndarray] = {}
    if postures:
        q_all, m_all, d_all = np.asarray(postures), np.asarray(modes), np.asarray(offsets)
        free = ValidityChecker(design, margins, obstacles, asm, "+++")
        for m in WORKING_MODES:
            sel = np.flatnonzero(m_all == m)
            if len(sel) == 0:
                continue
            sel = sel[free.with_mode(m).is_valid(q_all[sel])]
            sel = sel[np.argsort(d_all[sel], kind="stable")][:MAX_PER_MODE]
            if len(sel):
                targets[m], dists[m] = q_all[sel], d_all[sel]
    return GoalSet(ball, targets, dists, len(points))


def prove_goal_set(
    design: Design,
    start: JointPosture,
    ball: GoalBall,
    *,
    obstacles: Sequence[Obstacle] = (),
    margins: Margins | None = None,
    options: PlanOptions | None = None,
    deadline: float | None = None,
) -> PlanResult | None:
    """``no_path`` with ``diagnostics.proven_infeasible`` when the region map proves that no
    valid path joins the start to *any* goal of ``ball``: the obstacle-free map
    (:func:`planner.analysis.goal_cells.prove_ball_disconnected`), then with obstacles the
    3-D map (:func:`planner.analysis.obstacle_regions.prove_disconnected_with_obstacles` with
    the ball). None when neither can (or ``options.region_map`` is off). ``deadline``: a
    :func:`time.monotonic` value before which the obstacle-free map may be built."""
    t0 = time.monotonic()
    margins = margins if margins is not None else Margins()
    options = options if options is not None else PlanOptions()
    if not options.region_map:
        return None
    asm = start.assembly_mode
    unit = "m of goal.p" if ball.kind == "point" else "rad of goal.q"
    within = f"any goal within goal.tolerance = {ball.radius:g} {unit}"
    rmap = proof_region_map(design, margins, options, t0 + 1.0 if deadline is None else deadline)
    if rmap is not None and prove_ball_disconnected(rmap, start.q, ball, asm):
        return proven_no_path(
            f"no valid path exists to {within} (proven by the region map, {rmap.n} x "
            f"{rmap.n} cells, over every cell that can hold such a goal): in assembly mode "
            f"{asm} no chain of regions and serial transits joins the start to them, so every "
            "path crosses a posture that breaks a rule (joint limits, kappa_max, serial_min)",
            t0,
        )
    if not obstacles:
        return None
    proof = prove_disconnected_with_obstacles(
        design, margins, obstacles, start.q, np.empty((0, 3)), asm, goal_ball=ball
    )
    if not proof.proven:
        return None
    n1, n3, n2 = proof.shape
    return proven_no_path(
        f"no valid path exists to {within} (proven by the region map with obstacles, {n1} x "
        f"{n3} x {n2} cells over (theta1, theta3, theta2), over every cell that can hold such "
        f"a goal): in assembly mode {asm} the {proof.visited} cells reachable from the start "
        "hold none, and every path out of them crosses cells where a link surely comes closer "
        "to an obstacle than link_radius + clearance, or a posture breaks a rule",
        t0,
    )


def _spread(q: np.ndarray, k: int) -> np.ndarray:
    """At most ``k`` rows of ``q`` spread evenly over it, the first one included."""
    return q if len(q) <= k else q[np.linspace(0, len(q) - 1, k).round().astype(int)]


def _search(
    design: Design,
    start: JointPosture,
    goals: GoalSet,
    obstacles: Sequence[Obstacle],
    margins: Margins,
    options: PlanOptions,
    prove: Callable[[], PlanResult | None],
) -> tuple[PlanResult, str, float]:
    """The set search (module docstring, step 2): (result, mode of the goal reached, its
    offset); the result is ``no_path`` when nothing was found within the budget, or the
    proof's answer: ``prove`` is asked once, after the straight motions and before the
    first search (it costs milliseconds, a search its budget)."""
    t0 = time.monotonic()
    deadline = t0 + options.time_budget_s
    start_mode = posture_mode(design, start)
    own = goals.targets.get(start_mode) if start_mode is not None else None
    others = {m: _spread(t, SEARCH_GOALS) for m, t in goals.targets.items() if m != start_mode}
    searches = 0
    result = PlanResult(PlanStatus.NO_PATH, "", None, Diagnostics(0.0))
    if own is not None and start_mode is not None:
        share = options.time_budget_s * (0.5 if others else 1.0)
        checker = ValidityChecker(design, margins, obstacles, start.assembly_mode, start_mode)
        result = plan_to_goal_set(
            checker,
            start.q,
            own,
            options=replace(options, time_budget_s=share),
            search_goals=SEARCH_GOALS,
            before_search=lambda _: prove(),
        )
        if result.diagnostics.proven_infeasible:
            return result, "", float("nan")
        searches += result.diagnostics.searches
        if result.solved and result.path is not None:
            end = result.path.waypoints[-1]
            k = int(np.argmin(np.linalg.norm(own - end, axis=1)))
            return result, start_mode, float(goals.offsets[start_mode][k])
    if others and start_mode is not None and own is None:
        proof = prove()
        if proof is not None:
            return proof, "", float("nan")
    if others and start_mode is not None and time.monotonic() < deadline:
        result = plan_mode_change(
            design,
            start,
            start_mode,
            others,
            obstacles=obstacles,
            margins=margins,
            options=options,
            t0=t0,
            deadline=deadline,
            rmap=proof_region_map(design, margins, options, deadline),
        )
        searches += result.diagnostics.searches
        if result.solved and result.path is not None:
            mode = result.path.segments[-1].working_mode
            end = result.path.waypoints[-1]
            k = int(np.argmin(np.linalg.norm(goals.targets[mode] - end, axis=1)))
            return result, mode, float(goals.offsets[mode][k])
    diag = replace(result.diagnostics, searches=searches)
    return replace(result, status=PlanStatus.NO_PATH, diagnostics=diag), "", float("nan")


def plan_within_tolerance(
    design: Design,
    start: JointPosture,
    goal: JointPosture | CartesianTarget,
    tolerance: float,
    exact: PlanResult,
    *,
    obstacles: Sequence[Obstacle] = (),
    margins: Margins | None = None,
    options: PlanOptions | None = None,
    t0: float | None = None,
) -> PlanResult:
    """The answer to a goal with ``tolerance`` > 0 whose exact goal was answered ``exact``
    (not solved): the goal set searched as a set, then the proof over the whole set (see the
    module docstring). ``options.time_budget_s`` is the set search's budget; ``t0`` (a
    :func:`time.monotonic` value) the request's start, for ``planning_time_s``.

    Returns ``solved`` (the message says how far from the asked goal the path ends);
    ``no_path`` with ``proven_infeasible`` only when the proof covers every allowed goal;
    a plain ``no_path`` when valid goals exist in the ball but none was reached (the message
    says no proof covers the set); ``exact`` itself (its proof dropped) when the ball holds
    no valid goal that the sampling found.
    """
    t0 = time.monotonic() if t0 is None else t0
    margins = margins if margins is not None else Margins()
    options = options if options is not None else PlanOptions()
    cartesian = isinstance(goal, CartesianTarget)
    unit, field = ("m", "goal.p") if cartesian else ("rad", "goal.q")
    why = exact.message.rstrip(".")
    was = f"the exact goal alone: {exact.status.value}: {why}"
    goals = sample_goal_set(
        design, start, goal, tolerance, obstacles=obstacles, margins=margins, seed=options.seed
    )
    searches = exact.diagnostics.searches
    asked: list[PlanResult | None] = []

    def prove() -> PlanResult | None:
        if not asked:
            asked.append(
                prove_goal_set(
                    design,
                    start,
                    goals.ball,
                    obstacles=obstacles,
                    margins=margins,
                    options=options,
                    deadline=time.monotonic() + options.time_budget_s,
                )
            )
        return asked[0]

    if goals.count:
        found, mode, offset = _search(design, start, goals, obstacles, margins, options, prove)
        searches += found.diagnostics.searches
        if found.solved:
            note = (
                f"the path ends {offset:.3g} {unit} from {field}, within goal.tolerance = "
                f"{tolerance:g} {unit}, in working mode {mode} ({goals.count} valid goals "
                f"searched as a set; {was})"
            )
            diag = replace(
                found.diagnostics, planning_time_s=time.monotonic() - t0, searches=searches
            )
            return replace(found, message=f"{found.message}; {note}", diagnostics=diag)
    proof = prove()
    if proof is not None and (goals.count or exact.status is PlanStatus.NO_PATH):
        diag = replace(proof.diagnostics, planning_time_s=time.monotonic() - t0, searches=searches)
        return replace(proof, message=f"{proof.message} ({was})", diagnostics=diag)
    diag = Diagnostics(
        planning_time_s=time.monotonic() - t0,
        attempts=exact.diagnostics.attempts,
        searches=searches,
    )
    if goals.count:
        message = (
            f"no path found to any of the {goals.count} valid goals sampled within "
            f"goal.tolerance = {tolerance:g} {unit} of {field} (budget spent); no proof covers "
            f"every goal within the tolerance, so none is claimed ({was})"
        )
        logger.info("plan no_path: %s", message)
        return PlanResult(PlanStatus.NO_PATH, message, None, diag)
    # the ball holds no valid goal the sampling found: the exact goal's status stands (it is
    # not ``no_path``: an exact goal planned to no path is valid, so it is in the set)
    note = (
        f"no valid goal either among {goals.sampled} points sampled within goal.tolerance = "
        f"{tolerance:g} {unit} of {field}"
    )
    return PlanResult(exact.status, f"{why}; {note}", None, diag)
