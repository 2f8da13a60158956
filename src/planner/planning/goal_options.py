"""Goal options on top of :func:`planner.planning.plan`: ``prefer`` and ``tolerance``
(MoveIt's goal tolerance, and the paper's choice of working mode for the task, section 3.3).

:func:`planner.planning.plan` plans to one exact goal; :func:`plan_with_goal_options` calls it
once, or a few times, and :func:`planner.planning.preference.choose_plan` chooses among the
candidates. It is the library's function behind ``goal.prefer`` and ``goal.tolerance`` of
``POST /v1/plan`` (the wire converts, :mod:`planner_api.compute` calls this), so a library
user gets the same options without the service.

``prefer`` (a Cartesian target with ``working_mode`` "any"):

- ``"shortest"`` (default): today's plan to "any" (the planner's shortest path over the
  reachable modes); the message names the mode it ended in.
- ``"best_conditioned"``: that same plan, then one plan per other working mode whose inverse
  kinematics reaches the goal in the start's assembly mode (these share one more search
  budget), and :func:`planner.planning.preference.choose_plan` keeps the solved path whose
  largest kappa(A) is lowest. Because the "shortest" plan (same seed, same budget) is one of
  the candidates, the choice is never worse than "shortest" in that measure.

``tolerance`` (m for a Cartesian target, rad for a joint goal; 0 = exact): the exact goal is
planned first; when it is answered ``invalid_goal``, ``unreachable`` or ``no_path``, goals
within the tolerance are tried in turn (:func:`goal_alternatives`: towards the start first,
then along the axes), and the first solved one is the answer, its message saying how far
from the asked goal the path ends.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from planner.design import Design
from planner.exceptions import InputError
from planner.geometry import Obstacle
from planner.kinematics import WORKING_MODES, Manipulator, forward_batch
from planner.planning.preference import PREFERENCES, choose_plan
from planner.planning.problem import CartesianTarget, JointPosture, PlanOptions
from planner.planning.result import PlanResult
from planner.validity import Margins

__all__ = ["RETRIED_STATUSES", "goal_alternatives", "plan_with_goal_options"]

#: Statuses of the exact goal after which the goals within ``goal.tolerance`` are tried.
RETRIED_STATUSES = frozenset({"invalid_goal", "unreachable", "no_path"})
#: Alternatives are placed this much inside the tolerance (a rounding must not leave it).
_INSIDE = 1.0 - 1e-9
#: Time kept back from the searches for timing and answering before the deadline, s.
_RESERVE_S = 0.25


def goal_alternatives(goal: np.ndarray, towards: np.ndarray, tolerance: float) -> np.ndarray:
    """Goals within ``tolerance`` (Euclidean) of ``goal`` (3,), in the order they are tried:
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


def _left(deadline: float | None) -> float:
    return np.inf if deadline is None else deadline - time.monotonic() - _RESERVE_S


def _goal_mode(result: PlanResult) -> str:
    return result.path.segments[-1].working_mode if result.path.segments else ""


def _with_budget(options: PlanOptions, budget: float, deadline: float | None) -> PlanOptions:
    return replace(options, time_budget_s=max(min(budget, _left(deadline)), 0.01))


@dataclass(frozen=True, slots=True)
class _Problem:
    """What every search of one call shares: the robot, the start and the rules."""

    design: Design
    start: JointPosture
    obstacles: Sequence[Obstacle]
    margins: Margins | None

    def plan(self, goal: JointPosture | CartesianTarget, options: PlanOptions) -> PlanResult:
        from planner.planning.modes import plan

        return plan(
            self.design, self.start, goal,
            obstacles=self.obstacles, margins=self.margins, options=options,
        )  # fmt: skip


def _plan_preferring(
    problem: _Problem,
    goal: JointPosture | CartesianTarget,
    prefer: str,
    options: PlanOptions,
    deadline: float | None,
) -> tuple[PlanResult, str]:
    """One exact goal: the plan and a sentence on the working mode chosen ("" for a joint
    goal or a given mode)."""
    first = problem.plan(goal, options)
    if not isinstance(goal, CartesianTarget) or goal.working_mode != "any" or not first.solved:
        return first, ""
    mode = _goal_mode(first)
    if prefer == "shortest":
        return first, (
            f"working mode {mode} chosen (shortest: the planner's shortest joint path, "
            f"{first.diagnostics.path_length:.4g} rad)"
        )
    reach = Manipulator(problem.design).inverse(goal.p)
    others = sorted(
        {
            p.working_mode
            for p in reach
            if p.assembly_mode == problem.start.assembly_mode
            and p.working_mode in WORKING_MODES
            and p.working_mode != mode
        }
    )
    candidates = {mode: first}
    for i, m in enumerate(others):
        share = options.time_budget_s / len(others)
        if _left(deadline) <= 0.01 * (len(others) - i):
            break
        res = problem.plan(CartesianTarget(goal.p, m), _with_budget(options, share, deadline))
        if res.solved and _goal_mode(res) == m:
            candidates[m] = res
    choice = choose_plan(problem.design, candidates, "best_conditioned")
    assert choice is not None  # the first plan is solved
    return choice.result, choice.message


def plan_with_goal_options(
    design: Design,
    start: JointPosture,
    goal: JointPosture | CartesianTarget,
    *,
    obstacles: Sequence[Obstacle] = (),
    margins: Margins | None = None,
    options: PlanOptions | None = None,
    prefer: str = "shortest",
    tolerance: float = 0.0,
    deadline: float | None = None,
) -> PlanResult:
    """Plan to ``goal`` as :func:`planner.planning.plan` does, with the goal options: the
    :class:`~planner.planning.PlanResult` whose ``message`` also says which working mode was
    chosen and why (Cartesian "any" goals) and, when a goal within ``tolerance`` was used,
    how far from the asked one the path ends.

    Parameters
    ----------
    prefer : "shortest" | "best_conditioned"
        For a Cartesian target with working mode "any" (ignored otherwise).
    tolerance : float >= 0
        m for a Cartesian target, rad (Euclidean in joint space) for a joint goal; 0: exact.
    deadline : float or None
        A :func:`time.monotonic` value every search is cut to; None: only the budgets.

    ``options.time_budget_s`` is the budget of the exact goal's search; ``best_conditioned``
    and the tolerance's alternatives each share one more such budget.
    """
    if prefer not in PREFERENCES:
        raise InputError(f"prefer must be one of {PREFERENCES}, got {prefer!r}", field="prefer")
    if not (math.isfinite(tolerance) and tolerance >= 0.0):
        raise InputError(
            f"tolerance must be a finite number >= 0, got {tolerance!r}", field="tolerance"
        )
    options = options or PlanOptions()
    problem = _Problem(design, start, obstacles, margins)
    result, note = _plan_preferring(problem, goal, prefer, options, deadline)
    if tolerance > 0.0 and result.status.value in RETRIED_STATUSES:
        cartesian = isinstance(goal, CartesianTarget)
        if cartesian:
            fb = forward_batch(design, start.q, start.assembly_mode)
            towards = fb.p[0] if fb.ok[0] else goal.p
            anchor = goal.p
        else:
            towards, anchor = start.q, goal.q
        alternatives = goal_alternatives(anchor, towards, tolerance)
        share = options.time_budget_s / len(alternatives)
        for alt in alternatives:
            if _left(deadline) <= 0.01:
                break
            target = (
                CartesianTarget(alt, goal.working_mode)
                if cartesian
                else JointPosture(alt, goal.assembly_mode)
            )
            res, alt_note = _plan_preferring(
                problem, target, prefer, _with_budget(options, share, deadline), deadline
            )
            if res.solved:
                unit, field = ("m", "goal.p") if cartesian else ("rad", "goal.q")
                dist = float(np.linalg.norm(alt - anchor))
                why = result.message.rstrip(".")
                within = (
                    f"the path ends {dist:.3g} {unit} from {field}, within goal.tolerance = "
                    f"{tolerance:g} {unit} (the exact goal: {result.status.value}: {why})"
                )
                result, note = res, "; ".join(x for x in (within, alt_note) if x)
                break
    if note:
        result = replace(result, message="; ".join(x for x in (result.message, note) if x))
    return result
