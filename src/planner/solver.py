"""Plan and time in one call: :func:`solve`, the library's plan-and-time step.

A motion for a robot is a path that the planner certified *and* a trajectory that respects
the actuators' limits and was checked again, densely, against the path's own rules. Both
steps live in their rooms (:mod:`planner.planning` searches with OMPL, :mod:`planner.timing`
times with TOPPRA or Ruckig); :func:`solve` is the one call that joins them, so that a
library user, the service's plan job, the CLI, the warm-up and the benchmarks all take the
same route:

1. the plan: :func:`planner.planning.plan_with_goal_options` (the goal options ``prefer`` and
   ``tolerance`` included), its search cut to the deadline policy below;
2. the timing (unless ``timing.method`` is ``"none"`` or no path was found):
   :func:`planner.timing.time_path` on the path's waypoints, with the path's own validity
   rules per piece (:func:`planner.planning.path_state_checker`: each segment's working mode,
   serial rules off next to a transit, within ``timing.max_deviation`` of the path) re-checked
   densely, coming to rest at the transits when asked.

The deadline policy (one, here): ``deadline`` is a :func:`time.monotonic` value by which the
whole answer must be ready. The searches may run until ``deadline -``
:data:`planner.constants.ANSWER_RESERVE_S` (the
search budget ``options.time_budget_s`` is cut to what remains), so that a search that runs
out ends as ``no_path`` with time left to answer, not as a missed deadline; the timing runs
until ``deadline`` itself (past it, :class:`~planner.exceptions.TimingDeadlineError`: the
service's status ``timeout``).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from planner.constants import ANSWER_RESERVE_S
from planner.design import Design
from planner.dynamics import DEFAULT_GRAVITY, Inertia
from planner.exceptions import InputError, TimingError
from planner.geometry import Obstacle
from planner.planning import (
    CartesianTarget,
    JointPosture,
    PlanOptions,
    PlanPath,
    PlanResult,
    PlanStatus,
    path_state_checker,
    plan_with_goal_options,
)
from planner.planning.result import Diagnostics
from planner.timing.limits import JointLimits
from planner.timing.options import TimingOptions
from planner.timing.torque import gravity_at_start
from planner.timing.trajectory import Trajectory
from planner.validity import Margins

__all__ = ["Solution", "search_budget", "solve", "time_plan"]


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
        return self.plan.status

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


def search_budget(options: PlanOptions, deadline: float | None) -> PlanOptions:
    """``options`` with its search budget cut to what remains before ``deadline`` less
    :data:`~planner.constants.ANSWER_RESERVE_S` (at least 10 ms); unchanged without a deadline."""
    if deadline is None:
        return options
    left = deadline - time.monotonic() - ANSWER_RESERVE_S
    if left >= options.time_budget_s:
        return options
    return replace(options, time_budget_s=max(left, 0.01))


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
    margins = margins if margins is not None else Margins()
    options = options if options is not None else PlanOptions()
    timing = timing if timing is not None else TimingOptions()
    held = gravity_at_start(design, start.q, start.assembly_mode, limits, inertia, gravity)
    if held is not None and timing.method != "none":
        return Solution(PlanResult(PlanStatus.INVALID_START, held, None, Diagnostics(0.0)))
    result = plan_with_goal_options(
        design,
        start,
        goal,
        obstacles=obstacles,
        margins=margins,
        options=search_budget(options, deadline),
        prefer=prefer,
        tolerance=tolerance,
        deadline=None if deadline is None else deadline - ANSWER_RESERVE_S,
    )
    if timing.method == "none" or result.path is None:
        return Solution(result)
    try:
        trajectory = time_plan(
            design,
            result.path,
            obstacles=obstacles,
            margins=margins,
            timing=timing,
            limits=limits,
            stop_at_transits=options.stop_at_transits,
            deadline=deadline,
            inertia=inertia,
            gravity=gravity,
        )
    except TimingError as exc:  # deadline, no profile, or the dense re-check failed
        return Solution(result, timing_error=exc)
    return Solution(result, trajectory)


def time_plan(
    design: Design,
    path: PlanPath,
    *,
    obstacles: Sequence[Obstacle] = (),
    margins: Margins | None = None,
    timing: TimingOptions | None = None,
    limits: JointLimits | None = None,
    stop_at_transits: bool = False,
    deadline: float | None = None,
    inertia: Inertia | None = None,
    gravity: tuple[float, float, float] = DEFAULT_GRAVITY,
    max_deviation: float | np.ndarray | None = None,
    stop_at: Sequence[int] = (),
    via_at: Sequence[int] = (),
) -> Trajectory:
    """The timing step of :func:`solve` for a planned path: :func:`planner.timing.time_path`
    under the path's own rules per piece (:func:`planner.planning.path_state_checker`),
    coming to rest at the transits when ``stop_at_transits`` or ``timing.stop_at_transits``.
    A sequence (:func:`planner.sequence.solve_sequence`) times its joined legs here too, with
    its own corner allowance per waypoint (``max_deviation``, shape (N,), rad; default
    ``timing.max_deviation`` everywhere) and its stop targets (``stop_at``: waypoint indices
    where the trajectory comes to rest, besides the transits) and its pass-through targets
    (``via_at``: waypoints passed as free via states within their ``max_deviation``,
    :mod:`planner.timing.vias`). Raises :class:`~planner.exceptions.TimingError` as ``time_path`` does; an
    :class:`~planner.exceptions.InputError` names its field under ``timing.``."""
    from planner.timing import time_path

    margins = margins if margins is not None else Margins()
    timing = timing if timing is not None else TimingOptions()
    limits = limits if limits is not None else JointLimits.default()
    check = path_state_checker(design, margins, obstacles, path, near=timing.max_deviation)
    stop = stop_at_transits or timing.stop_at_transits
    rests = sorted({*(t.index for t in path.transits if stop), *(int(i) for i in stop_at)})
    deviation = timing.max_deviation if max_deviation is None else max_deviation
    try:
        return time_path(
            design,
            np.asarray(path.waypoints, dtype=float),
            limits,
            method=timing.method,
            assembly_mode=path.segments[0].assembly_mode if path.segments else "+",
            sample_rate_hz=timing.sample_rate_hz,
            max_cartesian_speed=timing.max_cartesian_speed,
            max_deviation=deviation,
            stop_at=rests,
            check_states=check,
            deadline=deadline,
            max_samples=timing.max_samples,
            inertia=inertia,
            gravity=gravity,
            via_at=[int(i) for i in via_at],
        )
    except InputError as exc:
        if exc.field is not None and not exc.field_path[:1] == ("timing",):
            exc.field = ("timing", *exc.field_path)
        raise
