"""The goal options of ``POST /v1/plan`` (``goal.prefer``, ``goal.tolerance``): the wire's
side is the conversion (:func:`planner.wire.plan_inputs` puts them on
:class:`~planner.wire.plan.PlanInputs`); the planning is the library's
:func:`planner.planning.goal_options.plan_with_goal_options`."""

from __future__ import annotations

from typing import Any

from planner.wire.plan import PlanInputs

__all__ = ["plan_goal"]


def plan_goal(inputs: PlanInputs, *, deadline: float | None = None) -> Any:
    """:func:`~planner.planning.goal_options.plan_with_goal_options` of a converted plan
    request (its goal options included); ``deadline`` a :func:`time.monotonic` value."""
    from planner.planning.goal_options import plan_with_goal_options

    return plan_with_goal_options(
        inputs.design, inputs.start, inputs.goal,
        obstacles=inputs.obstacles, margins=inputs.margins, options=inputs.options,
        prefer=inputs.prefer, tolerance=inputs.tolerance, deadline=deadline,
    )  # fmt: skip
