"""The inputs and the answer of a task sequence (:func:`planner.sequence.solve_sequence`):
plain data classes, light to import (the wire converts to and from them without loading the
planner or the timing)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from planner.constants import MAX_SEQUENCE_TARGETS
from planner.exceptions import InputError
from planner.kinematics import WORKING_MODES
from planner.planning.problem import CartesianTarget, JointPosture
from planner.planning.result import PlanPath, PlanResult, PlanStatus

__all__ = [
    "MAX_BELT_SPEED",
    "MAX_SEQUENCE_TARGETS",
    "OBJECTIVES",
    "BlendUse",
    "Leg",
    "MovingTarget",
    "SequenceDiagnostics",
    "SequenceResult",
    "SequenceTarget",
]

#: ``"time"``: choose each Cartesian "any" target's working mode for the shortest cycle;
#: ``"fixed"``: each target as given ("any" is the single plan's rule).
OBJECTIVES = ("time", "fixed")
#: Fastest belt a moving target may ride, m/s (``velocity``'s norm): conveyors of picking
#: lines run at 0.1-1 m/s; above 2 m/s the tool of a 0.8 m-reach five-bar cannot keep up
#: with the part for long under its default joint limits (2 rad/s), so a faster one is refused.
MAX_BELT_SPEED = 2.0


def _finite_vector(name: str, value: object) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be 3 finite numbers, got {value!r}", field=name)
    return arr


@dataclass(frozen=True, slots=True, eq=False)
class MovingTarget:
    """A part riding a belt (a sequence target only): at sequence time ``t`` the part is at
    ``p + velocity (t - t0)`` (m), a straight line at constant speed; the tool meets it in
    ``working_mode`` ("any": chosen by the interception search, :mod:`planner.sequence.
    moving`). ``velocity``: m/s, its norm at most :data:`MAX_BELT_SPEED`; ``t0``: s."""

    p: np.ndarray
    working_mode: str = "any"
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    t0: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "p", _finite_vector("p", self.p))
        v = _finite_vector("velocity", self.velocity)
        object.__setattr__(self, "velocity", v)
        if self.working_mode != "any" and self.working_mode not in WORKING_MODES:
            raise InputError(
                f"working_mode must be 'any' or one of {', '.join(WORKING_MODES)}, "
                f"got {self.working_mode!r}",
                field="working_mode",
            )
        speed = float(np.linalg.norm(v))
        if speed > MAX_BELT_SPEED:
            raise InputError(
                f"the belt speed |velocity| = {speed:.4g} m/s is above the bound of "
                f"{MAX_BELT_SPEED:g} m/s",
                field="velocity",
            )
        t0 = self.t0
        if isinstance(t0, bool) or not isinstance(t0, int | float) or not math.isfinite(t0):
            raise InputError(f"t0 must be a finite number of seconds, got {t0!r}", field="t0")

    def at(self, t: np.ndarray | float) -> np.ndarray:
        """Where the part is at sequence times ``t`` (M,), shape (M, 3), m."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return self.p[None, :] + (t - self.t0)[:, None] * self.velocity[None, :]


@dataclass(frozen=True, slots=True)
class SequenceTarget:
    """One target of a sequence: ``goal`` (a joint posture, a Cartesian target or a part on
    a belt, :class:`MovingTarget`: then ``dwell``, s >= 0, is how long the tool moves with the
    part once it has met it; ``stop`` and the blends do not apply to it), ``stop``
    (at rest there; else passed at speed) and how far the trajectory may pass from it when
    it does not stop: ``blend`` (rad, >= 0, in joint space from the target's posture) or
    ``blend_radius`` (m, >= 0, from the target's tool point; None: ``blend`` is the one),
    at most one of them; 0 passes exactly through. A blend that does not fit its legs
    shrinks (:mod:`planner.sequence.blends`)."""

    goal: JointPosture | CartesianTarget | MovingTarget
    stop: bool = True
    blend: float = 0.0
    blend_radius: float | None = None
    dwell: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.goal, JointPosture | CartesianTarget | MovingTarget):
            raise InputError(
                f"goal must be a joint posture, a Cartesian target or a moving target, "
                f"got {self.goal!r}",
                field="goal",
            )
        d = self.dwell
        if isinstance(d, bool) or not isinstance(d, int | float) or not math.isfinite(d) or d < 0:
            raise InputError(f"dwell must be a finite number >= 0 s, got {d!r}", field="dwell")
        if d != 0 and not isinstance(self.goal, MovingTarget):
            raise InputError(
                "dwell applies to a moving target (a goal with velocity)", field="dwell"
            )
        if isinstance(self.goal, MovingTarget):
            if not self.stop:
                raise InputError(
                    "a moving target is met at the part's speed, not passed: stop does not "
                    "apply (leave it true)",
                    field="stop",
                )
            if self.blend != 0 or self.blend_radius is not None:
                which = "blend" if self.blend != 0 else "blend_radius"
                raise InputError("a moving target takes no blend: it is met exactly", field=which)
        b = self.blend
        if isinstance(b, bool) or not isinstance(b, int | float) or not math.isfinite(b):
            raise InputError(f"blend must be a finite number, got {b!r}", field="blend")
        if b < 0:
            raise InputError(f"blend must be >= 0 rad, got {b!r}", field="blend")
        r = self.blend_radius
        if r is None:
            return
        if isinstance(r, bool) or not isinstance(r, int | float) or not math.isfinite(r):
            raise InputError(
                f"blend_radius must be a finite number, got {r!r}", field="blend_radius"
            )
        if r < 0:
            raise InputError(f"blend_radius must be >= 0 m, got {r!r}", field="blend_radius")
        if b != 0:
            raise InputError("give blend (rad) or blend_radius (m), not both", field="blend_radius")


@dataclass(frozen=True, slots=True)
class BlendUse:
    """One passed target's blend (``diagnostics.blends``): ``asked`` and ``used`` (after
    shrinking to fit) in ``unit``, "m" (``blend_radius``) or "rad" (``blend``)."""

    target_index: int
    asked: float
    used: float
    unit: str


@dataclass(frozen=True, slots=True)
class Leg:
    """One leg of a sequence: the plan from the previous target (or the start) to target
    ``target_index`` (``len(targets)`` for a cycle's return to the start).

    Attributes
    ----------
    target_index : int
    plan : the leg's :class:`~planner.planning.PlanResult` (its ``path`` as planned).
    working_mode : the working mode at arrival ("" when not solved).
    start_time, end_time : s, on the sequence's trajectory: when the trajectory leaves the
        previous target (0 for the first leg) and reaches this one (at rest for a stop;
        the instant of closest approach for a pass-through); NaN when not timed.
    waypoint_index : the target's waypoint in the joined path (-1 when not solved).
    pass_distance : rad, joint-space distance of the trajectory from the target's posture
        at ``end_time`` (0 at a stop; at most the blend); NaN when not timed.
    pass_speed : rad/s, joint speed there (0 at a stop); NaN when not timed.
    transit_times : s, on the sequence's trajectory: when it crosses each working-mode
        transit of the leg's path (``plan.path.transits``, in order); empty when not timed.
    meet_time, meet_point : for a moving target, when (s, sequence time) and where (m) the
        tool meets the part; NaN and None for any other target.
    """

    target_index: int
    plan: PlanResult
    working_mode: str = ""
    start_time: float = math.nan
    end_time: float = math.nan
    waypoint_index: int = -1
    pass_distance: float = math.nan
    pass_speed: float = math.nan
    transit_times: tuple[float, ...] = ()
    meet_time: float = math.nan
    meet_point: tuple[float, float, float] | None = None


@dataclass(frozen=True, slots=True)
class SequenceDiagnostics:
    """Measures of a sequence: ``planning_time_s`` (every leg's search, s),
    ``timing_time_s`` (the one timing of the joined path, s), ``modes`` (the working mode
    chosen at each target, "" for a joint goal), ``runner_up`` (the second best assignment's
    modes and cycle time, s, when the objective compared several), ``estimates`` (the
    assignments the mode search planned and timed), ``stopped_targets`` (pass-through
    targets where the trajectory comes to rest: the path turns back there, or the timing's
    repairs had to stop), ``blends`` (each passed target's blend, asked and used:
    :class:`BlendUse`), ``extra``: ``turning`` (those where the path turns back), and from
    the mode search ``gap_s`` (what it proves: no assignment of modes, planned and timed, is
    more than this much shorter, s; 0 when the choice is proven the best; absent without
    timing, where only bounds were compared) and ``bound_s`` (the least lower bound of any
    assignment, s: no motion through the targets is faster)."""

    planning_time_s: float = 0.0
    timing_time_s: float = 0.0
    modes: tuple[str, ...] = ()
    runner_up: tuple[tuple[str, ...], float] | None = None
    estimates: int = 0
    stopped_targets: tuple[int, ...] = ()
    blends: tuple[BlendUse, ...] = ()
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class SequenceResult:
    """What :func:`planner.sequence.solve_sequence` returns.

    ``status`` is solved only when every leg is (and the joined path was timed when timing
    was asked); else the status of the first leg that failed, its index in ``message``.
    ``path`` is the joined path the trajectory follows (the legs' waypoints, and for an
    exact pass-through two short straight pieces around the target so that the path is
    smooth there); ``trajectory`` the one :class:`~planner.timing.Trajectory` through every
    leg; ``timing_error`` what stopped the timing, if anything.
    """

    status: PlanStatus
    message: str
    legs: tuple[Leg, ...]
    path: PlanPath | None = None
    trajectory: Any = None
    timing_error: Exception | None = None
    diagnostics: SequenceDiagnostics = field(default_factory=SequenceDiagnostics)

    @property
    def solved(self) -> bool:
        return self.status is PlanStatus.SOLVED and self.timing_error is None

    @property
    def cycle_time(self) -> float:
        """Duration of the whole trajectory, s (NaN when not timed)."""
        return math.nan if self.trajectory is None else float(self.trajectory.duration)
