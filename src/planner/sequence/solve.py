"""Task sequences: one trajectory through many targets, the sequence kind of :mod:`planner.motion`.

A robot cell runs a cycle (pick, lift, move, place, return), and its figure of merit is the
cycle time. :func:`plan_sequence` answers a :class:`~planner.motion.MotionProblem` and its
targets (:func:`solve_sequence` is its keyword call); the steps:

1. the targets checked (:func:`_checked_targets`: at least one, at most
   :data:`~planner.sequence.problem.MAX_SEQUENCE_TARGETS`, each blend >= 0);
2. with ``objective="time"``, each Cartesian target in working mode "any" gets the mode
   that makes the whole cycle shortest (:func:`planner.sequence.mode_search.choose_modes`,
   which runs step 3-6 for each assignment it evaluates);
3-6. :class:`SequenceMotion` through the pipeline (:func:`planner.motion.run`): its planning
   step plans every leg in turn from the previous arrival posture as a single plan is
   (:class:`planner.solver.GoalMotion`, timing off; the first leg that fails gives the
   sequence its status, its index in the message), joins the legs into one path
   (:mod:`planner.sequence.joining`: an exact pass-through made smooth by two short straight
   pieces around the target; each blend, in rad or m, shrunk to at most half the shorter
   adjacent leg, :mod:`planner.sequence.blends`) and asks
   the pipeline to time it once under the path's own rules (:func:`planner.motion.path_timing`:
   the stops at rest and the pass-through targets passed within their ``blend``, as free via
   states, ``via_at``, where a stretch between stops holds only pass-throughs, else on arcs,
   :mod:`planner.timing.vias`): one trajectory, one time axis, strictly increasing, no stamp
   repeated between legs; its answer reads each leg's time span from the trajectory
   (:mod:`planner.sequence.leg_times`).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from planner.design import Design
from planner.dynamics import DEFAULT_GRAVITY, Inertia
from planner.exceptions import InputError
from planner.geometry import Obstacle
from planner.motion import MotionProblem, run
from planner.planning import (
    CartesianTarget,
    JointPosture,
    PlanOptions,
)
from planner.sequence.motion import SequenceMotion
from planner.sequence.problem import (
    MAX_SEQUENCE_TARGETS,
    OBJECTIVES,
    MovingTarget,
    SequenceResult,
    SequenceTarget,
)
from planner.timing.limits import JointLimits
from planner.timing.options import TimingOptions
from planner.validity import Margins

__all__ = ["plan_sequence", "solve_sequence"]


def _checked_targets(targets: Sequence[SequenceTarget]) -> list[SequenceTarget]:
    """Step 1: at least one target, at most :data:`MAX_SEQUENCE_TARGETS`, each a
    :class:`SequenceTarget` (its own checks: goal, blend >= 0)."""
    targets = list(targets)
    if not targets:
        raise InputError("targets must hold at least one target", field="targets")
    if len(targets) > MAX_SEQUENCE_TARGETS:
        raise InputError(
            f"at most {MAX_SEQUENCE_TARGETS} targets per sequence, got {len(targets)}",
            field="targets",
        )
    for i, t in enumerate(targets):
        if not isinstance(t, SequenceTarget):
            raise InputError(
                f"targets[{i}] must be a SequenceTarget, got {t!r}", field=("targets", i)
            )
    return targets


def solve_sequence(
    design: Design,
    start: JointPosture,
    targets: Sequence[SequenceTarget],
    *,
    cycle: bool = False,
    objective: str = "time",
    obstacles: Sequence[Obstacle] = (),
    margins: Margins | None = None,
    options: PlanOptions | None = None,
    timing: TimingOptions | None = None,
    limits: JointLimits | None = None,
    inertia: Inertia | None = None,
    gravity: tuple[float, float, float] = DEFAULT_GRAVITY,
    deadline: float | None = None,
) -> SequenceResult:
    """Plan and time one trajectory from ``start`` through every target in order (and back
    to ``start`` with ``cycle``): at rest at each ``stop`` target, passing through each other
    one within its ``blend`` without stopping. See the module docstring for the steps; the
    keyword call of :func:`plan_sequence` (which takes a :class:`~planner.motion.MotionProblem`).

    Parameters
    ----------
    design, start, obstacles, margins, options :
        As for :func:`planner.solve`; every leg is planned with them (``options`` per leg).
    targets : at least one :class:`~planner.sequence.SequenceTarget`. The last one (without
        ``cycle``) is where the trajectory ends, at rest, whatever its ``stop``.
    cycle : return to ``start`` at the end (the return leg's ``target_index`` is
        ``len(targets)``).
    objective : "time" (default: each Cartesian target in working mode "any" gets the mode
        that makes the whole trajectory shortest, :mod:`planner.sequence.mode_search`) or "fixed"
        (each target as given; "any" is the single plan's rule).
    timing, limits : as for :func:`planner.solve`; ``timing.method="none"`` plans the legs
        only. ``timing.max_deviation`` is the corner allowance of the legs' own corners.
    inertia, gravity : as for :func:`planner.solve`: the joined trajectory's torques (with
        ``limits.torque``, bounded by them; the mode search's lower bounds stay lower bounds,
        since a torque limit only lengthens a motion).
    deadline : a :func:`time.monotonic` value for the whole answer, or None.

    Returns
    -------
    SequenceResult
        ``solved`` when every leg is planned and the joined path timed; else the status of
        the first leg that failed with "target i" (or "the return to the start") in its
        message, or ``no_path``/``timeout`` when the timing failed (``timing_error``).

    Raises
    ------
    InputError
        No targets, too many (``field`` = ``targets``), an unknown objective, or a timing
        input error (under ``timing.``). A blend too large for its legs shrinks, it is never
        refused; a negative one is refused by :class:`SequenceTarget`.
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
    return plan_sequence(problem, targets, cycle=cycle, objective=objective)


def plan_sequence(
    problem: MotionProblem,
    targets: Sequence[SequenceTarget],
    *,
    cycle: bool = False,
    objective: str = "time",
) -> SequenceResult:
    """The sequence of ``targets`` under ``problem`` (the arguments as for
    :func:`solve_sequence`): the mode search of ``objective="time"`` when a Cartesian target
    is in working mode "any", else :class:`SequenceMotion` through the pipeline."""
    t0 = time.monotonic()
    targets = _checked_targets(targets)
    if objective not in OBJECTIVES:
        raise InputError(
            f"objective must be one of {', '.join(OBJECTIVES)}, got {objective!r}",
            field="objective",
        )
    goals: list[JointPosture | CartesianTarget | MovingTarget] = [t.goal for t in targets]
    if cycle:
        goals.append(JointPosture(np.asarray(problem.start.q), problem.start.assembly_mode))
    # the end of the trajectory is at rest: the last target without a cycle, the start with one
    stops = [t.stop for t in targets] + ([True] if cycle else [])
    stops[-1] = True
    if any(isinstance(g, MovingTarget) for g in goals):  # a belt: planned piece by piece
        from planner.sequence.moving import plan_moving_sequence

        return plan_moving_sequence(problem, targets, goals, cycle, objective, t0)
    if objective == "time" and any(
        isinstance(g, CartesianTarget) and g.working_mode == "any" for g in goals
    ):
        from planner.sequence.mode_search import choose_modes

        return choose_modes(problem, targets, goals, stops, cycle, t0)  # type: ignore[arg-type]
    motion = SequenceMotion(tuple(targets), tuple(goals), tuple(stops), cycle, t0)  # type: ignore[arg-type]
    return run(problem, motion)
