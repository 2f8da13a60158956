"""Goal options on top of :func:`planner.planning.plan`: ``prefer`` and ``tolerance``
(MoveIt's goal tolerance, and the paper's choice of working mode for the task, section 3.3).

:func:`planner.planning.plan` plans to one exact goal; :func:`plan_with_goal_options` calls it
once, or a few times, and :func:`planner.planning.preference.choose_plan` chooses among the
candidates. It is the library's function behind ``goal.prefer`` and ``goal.tolerance`` of
``POST /v1/plan`` (the wire converts, :mod:`planner.endpoints.plan` calls this), so a library
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
planned first; when it is answered ``invalid_goal``, ``unreachable`` or ``no_path``, every goal
within the tolerance is searched as a set, and a proof is claimed only when it covers that
whole set (:func:`planner.planning.tolerance.plan_within_tolerance`). ``prefer`` chooses among
the exact goal's working modes; a goal found within the tolerance is the first path the set
search finds (its message names the mode and the distance from the asked goal).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from functools import partial

import numpy as np

from planner.design import Design
from planner.exceptions import InputError
from planner.geometry import Obstacle
from planner.kinematics import WORKING_MODES, Manipulator
from planner.planning.preference import PREFERENCES, choose_plan
from planner.planning.problem import CartesianTarget, JointPosture, PlanOptions
from planner.planning.result import PlanResult
from planner.planning.tolerance import plan_within_tolerance
from planner.validity import Margins

__all__ = ["RETRIED_STATUSES", "plan_with_goal_options"]

#: A search of :func:`planner.planning.plan` with the call's robot, start and rules bound.
Search = Callable[..., PlanResult]

#: Statuses of the exact goal after which the goals within ``goal.tolerance`` are tried.
RETRIED_STATUSES = frozenset({"invalid_goal", "unreachable", "no_path"})


def _left(deadline: float | None) -> float:
    return np.inf if deadline is None else deadline - time.monotonic()


def _unclaimed(result: PlanResult, tolerance: float) -> PlanResult:
    """``result`` without a proof that covers the exact goal only (the deadline left no
    time to search or prove the rest of the tolerance)."""
    if not result.diagnostics.proven_infeasible:
        return result
    return replace(
        result,
        message=(
            f"{result.message.rstrip('.')}; the deadline left no time for the other goals "
            f"within goal.tolerance = {tolerance:g}, so no proof is claimed"
        ),
        diagnostics=replace(result.diagnostics, proven_infeasible=False),
    )


def _goal_mode(result: PlanResult) -> str:
    assert result.path is not None, "the working mode of a solved plan only"
    return result.path.segments[-1].working_mode if result.path.segments else ""


def _with_budget(options: PlanOptions, budget: float, deadline: float | None) -> PlanOptions:
    return replace(options, time_budget_s=max(min(budget, _left(deadline)), 0.01))


def _plan_preferring(
    design: Design,
    start: JointPosture,
    search: Search,
    goal: JointPosture | CartesianTarget,
    prefer: str,
    options: PlanOptions,
    deadline: float | None,
) -> tuple[PlanResult, str]:
    """One exact goal: the plan and a sentence on the working mode chosen ("" for a joint
    goal or a given mode)."""
    first = search(goal, options=options)
    if not isinstance(goal, CartesianTarget) or goal.working_mode != "any" or not first.solved:
        return first, ""
    mode = _goal_mode(first)
    if prefer == "shortest":
        return first, (
            f"working mode {mode} chosen (shortest: the planner's shortest joint path, "
            f"{first.diagnostics.path_length:.4g} rad)"
        )
    reach = Manipulator(design).inverse(goal.p)
    others = sorted(
        {
            p.working_mode
            for p in reach
            if p.assembly_mode == start.assembly_mode
            and p.working_mode in WORKING_MODES
            and p.working_mode != mode
        }
    )
    candidates = {mode: first}
    for i, m in enumerate(others):
        share = options.time_budget_s / len(others)
        if _left(deadline) <= 0.01 * (len(others) - i):
            break
        res = search(CartesianTarget(goal.p, m), options=_with_budget(options, share, deadline))
        if res.solved and _goal_mode(res) == m:
            candidates[m] = res
    choice = choose_plan(design, candidates, "best_conditioned")
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
        A :func:`time.monotonic` value every search is cut to (the searches' own deadline:
        :func:`planner.solve` keeps its answer reserve back before passing it); None: only
        the budgets.

    ``options.time_budget_s`` is the budget of the exact goal's search; ``best_conditioned``
    and the tolerance's alternatives each share one more such budget.
    """
    if prefer not in PREFERENCES:
        raise InputError(f"prefer must be one of {PREFERENCES}, got {prefer!r}", field="prefer")
    if not (math.isfinite(tolerance) and tolerance >= 0.0):
        raise InputError(
            f"tolerance must be a finite number >= 0, got {tolerance!r}", field="tolerance"
        )
    t0 = time.monotonic()
    options = options or PlanOptions()
    from planner.planning.dispatch import plan

    # every search of this call shares the robot, the start and the rules: bound once
    search = partial(plan, design, start, obstacles=obstacles, margins=margins)
    result, note = _plan_preferring(design, start, search, goal, prefer, options, deadline)
    if tolerance > 0.0 and result.status.value in RETRIED_STATUSES and _left(deadline) > 0.01:
        result = plan_within_tolerance(
            design,
            start,
            goal,
            tolerance,
            result,
            obstacles=obstacles,
            margins=margins,
            options=_with_budget(options, options.time_budget_s, deadline),
            t0=t0,
        )
        note = ""
    elif tolerance > 0.0 and result.status.value in RETRIED_STATUSES:
        # no time left for the set: the exact goal's proof covers its point only
        result = _unclaimed(result, tolerance)
    if note:
        result = replace(result, message="; ".join(x for x in (result.message, note) if x))
    return result
