"""Plan and time a motion to a goal: the goal kind of :mod:`planner.motion` (:class:`GoalMotion`)
and :func:`solve`, the library's keyword call for it.

A motion for a robot is a path that the planner certified *and* a trajectory that respects
the actuators' limits and was checked again, densely, against the path's own rules. The
planning step of this kind is :func:`planner.planning.plan_with_goal_options` (the goal
options ``prefer`` and ``tolerance`` included), its search cut to the problem's budget; the
rest (the gravity check at the start, the timing of the path under its own rules per piece,
:func:`planner.motion.path_timing`, the dense re-check, the one deadline policy) is the
pipeline's, :func:`planner.motion.run`, shared with the straight paths and the sequences.

:func:`solve` builds the :class:`~planner.motion.MotionProblem` from its keywords and runs the
pipeline; a caller holding a problem already (the wire, a sequence's legs) runs
``run(problem, GoalMotion(goal, prefer, tolerance))`` itself.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from planner.design import Design
from planner.dynamics import DEFAULT_GRAVITY, Inertia
from planner.exceptions import TimingDeadlineError, TimingError
from planner.geometry import Obstacle
from planner.motion import MotionProblem, Planned, Timed, path_timing, run
from planner.planning import (
    CartesianTarget,
    JointPosture,
    PlanOptions,
    PlanPath,
    PlanResult,
    PlanStatus,
    plan_with_goal_options,
)
from planner.planning.result import Diagnostics
from planner.timing.limits import JointLimits
from planner.timing.options import TimingOptions
from planner.timing.trajectory import Trajectory
from planner.validity import Margins

__all__ = ["GoalMotion", "Solution", "solve"]


@dataclass(frozen=True, slots=True)
class Solution:
    """What :func:`solve` returns: the plan and, when it was timed, its checked trajectory.

    Attributes
    ----------
    plan : the :class:`~planner.planning.PlanResult` (status, message, path, diagnostics).
    trajectory : the :class:`~planner.timing.Trajectory` of the path, re-checked densely
        against the path's rules; None when not asked (``timing.method = "none"``), when no
        path was found, or when the timing failed.
    timing_error : the :class:`~planner.exceptions.TimingError` that stopped the timing (a
        passed deadline: :class:`~planner.exceptions.TimingDeadlineError`; no profile, or
        the dense re-check failed after the repairs), else None. The path is kept.
    """

    plan: PlanResult
    trajectory: Trajectory | None = None
    timing_error: TimingError | None = None

    @property
    def status(self) -> PlanStatus:
        """The answer's status: the plan's, except that a path the timing could not turn into
        a checked trajectory is ``no_path``, and one whose timing ran past the deadline is
        ``timeout`` (the one timeout answer of the motion pipeline)."""
        if self.timing_error is None:
            return self.plan.status
        if isinstance(self.timing_error, TimingDeadlineError):
            return PlanStatus.TIMEOUT
        return PlanStatus.NO_PATH

    @property
    def message(self) -> str:
        return self.plan.message

    @property
    def path(self) -> PlanPath | None:
        return self.plan.path

    @property
    def solved(self) -> bool:
        """A certified path, timed when timing was asked."""
        return self.plan.solved and self.timing_error is None


@dataclass(frozen=True, slots=True, eq=False)
class GoalMotion:
    """A motion to one goal (a joint posture, or a Cartesian target in a working mode or
    "any") with the goal options ``prefer`` and ``tolerance``
    (:func:`planner.planning.plan_with_goal_options`): a :class:`planner.motion.Motion` whose
    answer is a :class:`Solution`."""

    goal: JointPosture | CartesianTarget
    prefer: str = "shortest"
    tolerance: float = 0.0

    def plan(self, problem: MotionProblem) -> Planned[PlanResult]:
        """The search, cut to the budget's search deadline; the path timed under its own
        rules (:func:`planner.motion.path_timing`)."""
        budget = problem.budget
        result = plan_with_goal_options(
            problem.design,
            problem.start,
            self.goal,
            obstacles=problem.obstacles,
            margins=problem.margins,
            options=budget.search_options(problem.options),
            prefer=self.prefer,
            tolerance=self.tolerance,
            deadline=budget.search_deadline,
        )
        timing = None if result.path is None else path_timing(problem, result.path)
        return Planned(result.status, result.message, result, timing)

    def answer(
        self, problem: MotionProblem, planned: Planned[PlanResult], timed: Timed
    ) -> Solution:
        """The plan, its trajectory or the timing's error."""
        plan = planned.detail
        if plan is None:  # stopped before planning
            plan = PlanResult(planned.status, planned.message, None, Diagnostics(0.0))
        return Solution(plan, timed.trajectory, timed.error)


def solve(
    design: Design,
    start: JointPosture,
    goal: JointPosture | CartesianTarget,
    *,
    obstacles: Sequence[Obstacle] = (),
    margins: Margins | None = None,
    options: PlanOptions | None = None,
    timing: TimingOptions | None = None,
    limits: JointLimits | None = None,
    prefer: str = "shortest",
    tolerance: float = 0.0,
    deadline: float | None = None,
    inertia: Inertia | None = None,
    gravity: tuple[float, float, float] = DEFAULT_GRAVITY,
) -> Solution:
    """Plan a valid path from ``start`` to ``goal`` and time it: the library's one call for
    a timed motion (see the module docstring).

    Parameters
    ----------
    design, start, goal, obstacles, margins, options :
        As for :func:`planner.planning.plan` (a joint goal, or a Cartesian target in a working
        mode or ``"any"``; ``options.time_budget_s`` bounds the search).
    timing : :class:`~planner.timing.TimingOptions`; default TOPPRA at 100 Hz.
    limits : :class:`~planner.timing.JointLimits`; default
        :meth:`~planner.timing.JointLimits.default`.
    prefer, tolerance :
        The goal options of :func:`planner.planning.plan_with_goal_options`.
    deadline : a :func:`time.monotonic` value for the whole answer, or None.
    inertia, gravity :
        The robot's inertial model (:class:`~planner.dynamics.Inertia`; default
        :meth:`~planner.dynamics.Inertia.default` when ``limits.torque`` is given) and gravity
        (m/s^2, base frame): with either an inertia or torque limits, the trajectory carries
        its torques, and torque limits bound them (:func:`planner.timing.time_path`). A start
        where gravity alone needs more than a joint's torque limit is ``invalid_start``,
        naming the joint and the torque.

    Returns
    -------
    Solution
        ``solution.plan`` as :func:`plan_with_goal_options` answers it; ``trajectory`` or
        ``timing_error`` when a path was found and timing was asked.

    Raises
    ------
    InputError
        A bad argument; an error of the timing step names its field under ``timing.``
        (e.g. ``timing.sample_rate_hz`` when the trajectory would have more samples than
        ``timing.max_samples``).

    >>> import numpy as np
    >>> from planner import Design, solve
    >>> from planner.planning import JointPosture
    >>> s = solve(Design.default(), JointPosture([0.0, 2.0, 1.0]), JointPosture([0.4, 2.2, 1.1]))
    >>> s.solved, s.trajectory.q[-1].round(6).tolist()
    (True, [0.4, 2.2, 1.1])
    """
    problem = MotionProblem.of(
        design,
        start,
        obstacles=obstacles,
        margins=margins,
        options=options,
        timing=timing,
        limits=limits,
        inertia=inertia,
        gravity=gravity,
        deadline=deadline,
    )
    return run(problem, GoalMotion(goal, prefer, tolerance))
