"""The goal options of ``POST /v1/plan``: ``goal.prefer`` and ``goal.tolerance``.

A thin adapter over the library, which has the pieces but not these two options:
:func:`planner.planning.plan` plans to one exact goal, and
:mod:`planner.planning.preference` chooses among candidate plans. :func:`plan_goal` is the
one place that combines them for the service and the CLI.

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

import time
from dataclasses import replace
from typing import Any

import numpy as np

from planner.wire.plan import PlanInputs

__all__ = ["RETRIED_STATUSES", "goal_alternatives", "plan_goal"]

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


def _goal_mode(result: Any) -> str:
    return result.path.segments[-1].working_mode if result.path.segments else ""


def _with_budget(options: Any, budget: float, deadline: float | None) -> Any:
    return replace(options, time_budget_s=max(min(budget, _left(deadline)), 0.01))


def _plan_preferring(
    inputs: PlanInputs, goal: Any, prefer: str, options: Any, deadline: float | None
) -> tuple[Any, str]:
    """One exact goal: the plan and a sentence on the working mode chosen ("" for a joint
    goal or a given mode)."""
    from planner.kinematics import WORKING_MODES, Manipulator
    from planner.planning import CartesianTarget, plan
    from planner.planning.preference import choose_plan

    def run(target: Any, opts: Any) -> Any:
        return plan(
            inputs.design, inputs.start, target,
            obstacles=inputs.obstacles, margins=inputs.margins, options=opts,
        )  # fmt: skip

    first = run(goal, options)
    if not isinstance(goal, CartesianTarget) or goal.working_mode != "any" or not first.solved:
        return first, ""
    mode = _goal_mode(first)
    if prefer == "shortest":
        return first, (
            f"working mode {mode} chosen (shortest: the planner's shortest joint path, "
            f"{first.diagnostics.path_length:.4g} rad)"
        )
    reach = Manipulator(inputs.design).inverse(goal.p)
    others = sorted(
        {
            p.working_mode
            for p in reach
            if p.assembly_mode == inputs.start.assembly_mode
            and p.working_mode in WORKING_MODES
            and p.working_mode != mode
        }
    )
    candidates = {mode: first}
    for i, m in enumerate(others):
        share = options.time_budget_s / len(others)
        if _left(deadline) <= 0.01 * (len(others) - i):
            break
        res = run(CartesianTarget(goal.p, m), _with_budget(options, share, deadline))
        if res.solved and _goal_mode(res) == m:
            candidates[m] = res
    choice = choose_plan(inputs.design, candidates, "best_conditioned")
    assert choice is not None  # the first plan is solved
    return choice.result, choice.message


def plan_goal(
    inputs: PlanInputs,
    *,
    prefer: str = "shortest",
    tolerance: float = 0.0,
    deadline: float | None = None,
) -> Any:
    """Plan to ``inputs.goal`` with the goal options: the
    :class:`planner.planning.PlanResult` whose ``message`` also says which working mode was
    chosen and why (Cartesian "any" goals) and, when a goal within ``tolerance`` was used,
    how far from the asked one the path ends.

    ``inputs.options.time_budget_s`` is the budget of the exact goal's search;
    ``best_conditioned`` and the tolerance's alternatives each share one more such budget,
    all cut to ``deadline`` (a :func:`time.monotonic` value) when given.
    """
    from planner.planning import CartesianTarget, JointPosture

    exact = _plan_preferring
    goal = inputs.goal
    result, note = exact(inputs, goal, prefer, inputs.options, deadline)
    if tolerance > 0.0 and result.status.value in RETRIED_STATUSES:
        cartesian = isinstance(goal, CartesianTarget)
        if cartesian:
            from planner.kinematics import forward_batch

            fb = forward_batch(inputs.design, inputs.start.q, inputs.start.assembly_mode)
            towards = fb.p[0] if fb.ok[0] else goal.p
            anchor = goal.p
        else:
            towards, anchor = inputs.start.q, goal.q
        alternatives = goal_alternatives(anchor, towards, tolerance)
        share = inputs.options.time_budget_s / len(alternatives)
        for alt in alternatives:
            if _left(deadline) <= 0.01:
                break
            target = (
                CartesianTarget(alt, goal.working_mode)
                if cartesian
                else JointPosture(alt, goal.assembly_mode)
            )
            res, alt_note = exact(
                inputs, target, prefer, _with_budget(inputs.options, share, deadline), deadline
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
