"""One motion problem: what every kind of motion shares, built once and carried by every step.

A plan to a goal, a straight tool path and a task sequence all need the same things: the robot
(its design and its inertial model), where it starts, the scene (obstacles, packed once), the
rules (margins), the actuators (limits), gravity, the options of the search and of the timing,
and one budget of time. :class:`MotionProblem` holds them, frozen; the wire builds it once
from a request (:func:`planner.wire.motion_problem`), a library user builds it directly (or
through the keyword helpers :func:`planner.solve`, :func:`planner.solve_sequence`,
:func:`planner.cartesian.plan_cartesian`), and :func:`planner.motion.run` hands it to every step.

:class:`Budget` is the one deadline policy, on one clock (:func:`time.monotonic`, the same value
in every process of a machine, so a service can hand a request's deadline to a worker):
the searches may run until ``deadline -`` :data:`~planner.constants.ANSWER_RESERVE_S` (a search
that runs out ends as ``no_path`` with time left to answer), the rest (the timing, its dense
re-check, a straight path's certification) until ``deadline`` itself; past it, the answer's
status is ``timeout``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

from planner.constants import ANSWER_RESERVE_S
from planner.design import Design
from planner.dynamics import DEFAULT_GRAVITY, Inertia, check_gravity
from planner.exceptions import InputError, check_deadline
from planner.geometry import Obstacle, PackedObstacles, pack_obstacles
from planner.planning.problem import JointPosture, PlanOptions
from planner.timing.limits import JointLimits
from planner.timing.options import TimingOptions
from planner.validity import Margins

__all__ = ["UNBOUNDED", "Budget", "MotionProblem"]


@dataclass(frozen=True, slots=True)
class Budget:
    """The time one answer may take: a deadline on :func:`time.monotonic`, or None (no
    deadline). See the module docstring for the policy."""

    deadline: float | None = None

    def __post_init__(self) -> None:
        if self.deadline is not None and not (
            isinstance(self.deadline, int | float) and math.isfinite(self.deadline)
        ):
            raise InputError(
                f"deadline must be a finite time.monotonic() value, got {self.deadline!r}"
            )

    @classmethod
    def within(cls, seconds: float | None) -> Budget:
        """A budget ending ``seconds`` from now (None: unbounded)."""
        return cls(None if seconds is None else time.monotonic() + float(seconds))

    def left(self) -> float:
        """Seconds until the deadline (inf without one; negative once passed)."""
        return math.inf if self.deadline is None else self.deadline - time.monotonic()

    @property
    def search_deadline(self) -> float | None:
        """The searches' deadline: the answer's less the reserve that leaves time to answer."""
        return None if self.deadline is None else self.deadline - ANSWER_RESERVE_S

    def search_options(self, options: PlanOptions) -> PlanOptions:
        """``options`` with the search budget cut to what remains before
        :attr:`search_deadline` (at least 10 ms); unchanged without a deadline."""
        if self.deadline is None:
            return options
        left = self.deadline - time.monotonic() - ANSWER_RESERVE_S
        if left >= options.time_budget_s:
            return options
        return replace(options, time_budget_s=max(left, 0.01))

    def check(self, doing: str) -> None:
        """:class:`~planner.exceptions.DeadlineError` naming ``doing`` once the deadline has
        passed (cheap: for every round of a long loop)."""
        check_deadline(self.deadline, doing)


#: No deadline: the budget of a call that may take as long as it needs.
UNBOUNDED = Budget()


def _packed(obstacles: tuple[Obstacle, ...]) -> PackedObstacles:
    return pack_obstacles(obstacles)


@dataclass(frozen=True, slots=True, eq=False)
class MotionProblem:
    """What every kind of motion shares (see the module docstring), checked once here.

    Parameters
    ----------
    design : the robot's :class:`~planner.design.Design`.
    start : the :class:`~planner.planning.JointPosture` the motion starts from, at rest.
    obstacles : the scene (spheres, boxes, capsules, point clouds of
        :mod:`planner.geometry`), kept as one tuple and packed once: every validity checker of
        every step is built from this same tuple and finds its packing in the geometry's cache.
    margins : the validity rules' :class:`~planner.validity.Margins` (default: the defaults).
    options : the search's :class:`~planner.planning.PlanOptions` (per leg for a sequence).
    timing : the :class:`~planner.timing.TimingOptions` (method, rate, corner allowance,
        tool speed, the sample bound ``max_samples``).
    limits : the actuators' :class:`~planner.timing.JointLimits` (default
        :meth:`~planner.timing.JointLimits.default`).
    inertia : the robot's :class:`~planner.dynamics.Inertia`, or None: the default model is
        used where torques are asked (``limits.torque``).
    gravity : m/s^2 in the base frame, 3 finite numbers.
    budget : the answer's :class:`Budget`.
    start_qd, start_qdd : the start's joint velocity (rad/s) and acceleration (rad/s^2), 3
        numbers each, default zeros (at rest). A moving start (:mod:`planner.timing.lead_in`):
        the trajectory begins in exactly that state, through a lead-in onto the planned
        path; it must lie within ``limits`` (a :class:`~planner.exceptions.LimitsError` at
        ``start.qd`` / ``start.qdd``), needs a timed answer, and is refused (at
        ``start.qd``) with ``limits.torque`` or ``timing.max_cartesian_speed``, which the
        lead-in does not bound.
    """

    design: Design
    start: JointPosture
    obstacles: tuple[Obstacle, ...] = ()
    margins: Margins = field(default_factory=Margins)
    options: PlanOptions = field(default_factory=PlanOptions)
    timing: TimingOptions = field(default_factory=TimingOptions)
    limits: JointLimits = field(default_factory=JointLimits.default)
    inertia: Inertia | None = None
    gravity: tuple[float, float, float] = DEFAULT_GRAVITY
    budget: Budget = UNBOUNDED
    start_qd: tuple[float, float, float] = (0.0, 0.0, 0.0)
    start_qdd: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        checks: tuple[tuple[str, Any, type | tuple[type, ...]], ...] = (
            ("design", self.design, Design),
            ("start", self.start, JointPosture),
            ("margins", self.margins, Margins),
            ("options", self.options, PlanOptions),
            ("timing", self.timing, TimingOptions),
            ("limits", self.limits, JointLimits),
            ("budget", self.budget, Budget),
        )
        for name, value, kind in checks:
            if not isinstance(value, kind):
                raise InputError(
                    f"{name} must be a {kind.__name__}, got {type(value).__name__}",  # type: ignore[union-attr]
                    field=name,
                )
        if self.inertia is not None and not isinstance(self.inertia, Inertia):
            raise InputError(
                f"inertia must be an Inertia or None, got {type(self.inertia).__name__}",
                field="inertia",
            )
        g = check_gravity(self.gravity)
        object.__setattr__(self, "gravity", (float(g[0]), float(g[1]), float(g[2])))
        obstacles = tuple(self.obstacles)
        object.__setattr__(self, "obstacles", obstacles)
        self._check_moving_start()
        _packed(obstacles)  # packed once, here: every later checker finds it in the cache

    def _check_moving_start(self) -> None:
        """``start_qd``, ``start_qdd`` as float triples, and a moving start's rules."""
        from planner.timing.lead_in import StartState, check_start_rates

        state = StartState.of(self.start.q, self.start_qd, self.start_qdd)
        object.__setattr__(self, "start_qd", tuple(float(x) for x in state.qd))
        object.__setattr__(self, "start_qdd", tuple(float(x) for x in state.qdd))
        if not state.moving:
            return
        refused = (
            (self.timing.method == "none", "a timed answer (timing.method toppra or ruckig)"),
            (
                self.limits.torque is not None,
                "no limits.torque (the lead-in is not torque-limited)",
            ),
            (
                self.timing.max_cartesian_speed is not None,
                "no timing.max_cartesian_speed (the lead-in does not bound the speed of P)",
            ),
        )
        for refuse, needs in refused:
            if refuse:
                raise InputError(f"a moving start needs {needs}", field="start.qd")
        check_start_rates(state, self.limits, jerk_limited=self.timing.method == "ruckig")

    @property
    def start_state(self) -> Any:
        """The start as a :class:`planner.timing.lead_in.StartState` (q, qd, qdd)."""
        from planner.timing.lead_in import StartState

        return StartState.of(self.start.q, self.start_qd, self.start_qdd)

    @property
    def moving_start(self) -> bool:
        """The start is not at rest (``start_qd`` or ``start_qdd`` is not zero)."""
        return any(x != 0.0 for x in (*self.start_qd, *self.start_qdd))

    @classmethod
    def of(
        cls,
        design: Design,
        start: JointPosture,
        *,
        obstacles: Any = (),
        margins: Margins | None = None,
        options: PlanOptions | None = None,
        timing: TimingOptions | None = None,
        limits: JointLimits | None = None,
        inertia: Inertia | None = None,
        gravity: Any = DEFAULT_GRAVITY,
        deadline: float | None = None,
        start_qd: Any = (0.0, 0.0, 0.0),
        start_qdd: Any = (0.0, 0.0, 0.0),
    ) -> MotionProblem:
        """The problem of the library's keyword calls (None: a field's default)."""
        return cls(
            design,
            start,
            tuple(obstacles),
            margins if margins is not None else Margins(),
            options if options is not None else PlanOptions(),
            timing if timing is not None else TimingOptions(),
            limits if limits is not None else JointLimits.default(),
            inertia,
            gravity,
            Budget(deadline),
            start_qd,
            start_qdd,
        )

    def with_(self, **changes: Any) -> MotionProblem:
        """A copy with ``changes`` (e.g. another start, or timing options), checked again.
        A new ``start`` or ``timing`` starts at rest unless ``start_qd``/``start_qdd`` are
        given too (a sequence plans its legs from rest, untimed; the joined path is timed
        from the moving start)."""
        if ("start" in changes or "timing" in changes) and not (
            {"start_qd", "start_qdd"} & changes.keys()
        ):
            changes = {**changes, "start_qd": (0.0, 0.0, 0.0), "start_qdd": (0.0, 0.0, 0.0)}
        return replace(self, **changes)
