"""The product's exceptions.

Every error the library raises on purpose derives from :class:`PlannerError`, so a caller
can catch the product's errors apart from bugs. The web layer maps them to HTTP answers in
one place.

::

    PlannerError
    ├── DesignError            (ValueError)  a design's numbers break a rule
    ├── InputError             (ValueError)  an argument has the wrong shape or a non-finite value
    ├── DeadlineError                        the caller's deadline passed (:func:`check_deadline`)
    ├── KinematicsError
    │   ├── AssemblyError                    q does not close the five-bar loop
    │   └── SingularPostureError             the asked quantity is undefined at a singularity
    └── TimingError                          a path could not be turned into a trajectory
        ├── TimingInfeasibleError            the solver (toppra, ruckig) found no profile
        ├── TrajectoryCheckError             the timed trajectory fails the dense re-check
        └── TimingDeadlineError              the request's deadline passed during timing

    InputError
    └── LimitsError                          velocity/acceleration/jerk limits break a rule
"""

from __future__ import annotations

import time

__all__ = [
    "AssemblyError",
    "DeadlineError",
    "DesignError",
    "InputError",
    "KinematicsError",
    "LimitsError",
    "PlannerError",
    "SingularPostureError",
    "TimingDeadlineError",
    "TimingError",
    "TimingInfeasibleError",
    "TrajectoryCheckError",
    "check_deadline",
]


class PlannerError(Exception):
    """Base of every error the product raises on purpose.

    ``field`` names the argument the error is about, where the raising function knows it:
    a name (``"sample_rate_hz"``), a dotted name into an argument (``"limits.jerk"``) or a
    path with indices (``("waypoints", 3, 1)``). Callers that know where that argument came
    from (the wire: which part of the request body, :func:`planner.wire.located`) prefix it.
    None when not known.
    """

    def __init__(self, *args: object, field: str | tuple[str | int, ...] | None = None) -> None:
        super().__init__(*args)
        self.field = field

    @property
    def field_path(self) -> tuple[str | int, ...]:
        """``field`` as a path: a dotted name split at its dots, a tuple as it is; () when
        the field is not known."""
        if self.field is None:
            return ()
        if isinstance(self.field, tuple):
            return self.field
        return tuple(self.field.split("."))

    def __reduce__(self):  # keep ``field`` across processes (pickling drops keyword args)
        return (_rebuild_error, (type(self), self.args, self.__dict__))


def _rebuild_error(cls: type[PlannerError], args: tuple, state: dict) -> PlannerError:
    exc = cls.__new__(cls)
    Exception.__init__(exc, *args)
    exc.__dict__.update(state)
    return exc


class DesignError(PlannerError, ValueError):
    """A design's link lengths, radius or joint limits break a rule (the message names it)."""


class InputError(PlannerError, ValueError):
    """An argument has the wrong shape, or holds NaN or an infinity."""


class KinematicsError(PlannerError):
    """A kinematic quantity cannot be computed for the given posture."""


class AssemblyError(KinematicsError):
    """The actuated joints do not close the loop: |CD| > 2 L2, C = D, or the asked assembly
    mode does not exist there."""


class SingularPostureError(KinematicsError):
    """The quantity asked for is undefined at this posture (a parallel singularity for a
    Cartesian velocity, a degenerate point for inverse kinematics)."""


class LimitsError(InputError):
    """Joint velocity, acceleration or jerk limits break a rule: each is 3 positive finite
    numbers (the message names the field and the rule)."""


class TimingError(PlannerError):
    """A joint path could not be turned into a timed trajectory."""


class TimingInfeasibleError(TimingError):
    """The time-parameterisation solver found no profile (toppra's return code, a ruckig
    error code or ``RuckigError``), translated into the product's error."""


class TrajectoryCheckError(TimingError):
    """The timed trajectory fails the dense re-check (validity, joint limits, or a velocity,
    acceleration, jerk or Cartesian-speed limit) and the bounded repair could not fix it.

    Attributes
    ----------
    rule : str
        Which check failed: ``"validity"``, ``"joint_limits"``, ``"velocity"``,
        ``"acceleration"``, ``"jerk"``, ``"cartesian_speed"`` or ``"assembly"``.
    time : float or None
        Time of the first failing sample, s (None when the failure is on the planned path).
    q : tuple of 3 floats or None
        Joints of the first failing sample, rad.
    """

    def __init__(
        self,
        message: str,
        *,
        rule: str,
        time: float | None = None,
        q: tuple[float, float, float] | None = None,
    ) -> None:
        super().__init__(message)
        self.rule = rule
        self.time = time
        self.q = q


class DeadlineError(PlannerError):
    """The caller's deadline passed before the work finished (a long computation checks it
    in its loops, :func:`check_deadline`): nothing is answered, the work is abandoned."""


def check_deadline(deadline: float | None, what: str) -> None:
    """:class:`DeadlineError` naming ``what`` was under way if :func:`time.monotonic` is past
    ``deadline`` (None: no deadline). Cheap enough for every round of a long loop."""
    if deadline is not None and time.monotonic() > deadline:
        raise DeadlineError(f"the deadline passed {what}")


class TimingDeadlineError(TimingError):
    """The request's deadline passed before the trajectory was computed and checked (the
    service answers with status ``timeout``)."""
