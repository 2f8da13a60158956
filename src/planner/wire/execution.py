"""Execution on the wire: replacing a running trajectory mid-motion, and stopping it.

``replace`` (on ``POST /v1/plan`` and ``/v1/sequence``): ``{"trajectory": {"t", "q", "qd",
"qdd"}, "at": s}``, the trajectory the controller is running and the time on its clock where
the new one takes over. The running trajectory is read as a controller reads it
(:class:`planner.timing.running.RunningTrajectory`: quintic Hermite between samples, the
samples exact); its state at ``at`` is the new request's start (``start`` may be omitted;
given, it must equal that state to :data:`START_MATCH_TOL`, else a 422 at ``start``), and the
answer's times are on the running clock (``t[0] = at``). ``POST /v1/stop``: the braking
trajectory to rest from the running state at ``at`` (:mod:`planner.timing.braking`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, Literal

from pydantic import ConfigDict, Field

from planner.wire.common import (
    _MAX_SAMPLES,
    MAX_OBSTACLES,
    AssemblyModeLabel,
    DesignModel,
    Finite,
    JointPostureModel,
    MarginsModel,
    Obstacle,
    Vec3,
    _DesignField,
    _Request,
    _Response,
    located,
)
from planner.wire.diagnostics import LeadInModel
from planner.wire.timing import AnyTrajectory, Limits, TrajectoryFormat

if TYPE_CHECKING:
    from planner.timing.running import RunningTrajectory

__all__ = [
    "START_MATCH_TOL",
    "ReplaceModel",
    "RunningTrajectoryModel",
    "StartPostureModel",
    "StopRequest",
    "StopResponse",
    "StreamAck",
    "StreamMessage",
    "StreamReplace",
    "StreamStart",
    "StreamStop",
    "fill_start_from_replace",
    "lead_in_model",
    "on_running_clock",
    "replace_start",
    "running_model",
    "running_trajectory",
    "shifted",
]

#: How closely a given ``start`` must match the running state at ``replace.at`` (absolute,
#: rad, rad/s, rad/s^2): the running state itself is what the new trajectory starts from.
START_MATCH_TOL = 1e-9

_Samples = Annotated[list[Vec3], Field(max_length=_MAX_SAMPLES)]


#: Joint rates of a start state: finite numbers (the limits bound them: a 422 at the field).
Rate3 = Annotated[list[Finite], Field(min_length=3, max_length=3)]


class StartPostureModel(JointPostureModel):
    """A motion's start: a joint posture, and the state it is moving in (default: at rest)."""

    qd: Rate3 = Field(
        default_factory=lambda: [0.0, 0.0, 0.0],
        description="Joint velocity at the start, rad/s (default zeros). Within "
        "limits.velocity; the trajectory begins in exactly this state (docs/execution.md).",
    )
    qdd: Rate3 = Field(
        default_factory=lambda: [0.0, 0.0, 0.0],
        description="Joint acceleration at the start, rad/s^2 (default zeros). Within "
        "limits.acceleration (and, with ruckig, reachable under limits.jerk).",
    )


def lead_in_model(trajectory: Any) -> LeadInModel | None:
    """The :class:`LeadInModel` of a timed trajectory with a moving start (None: at rest)."""
    lead = getattr(getattr(trajectory, "curve", None), "lead_in", None)
    if lead is None:
        return None
    return LeadInModel(duration=lead.duration, joins_at=lead.joins_at, kind=lead.kind)


class RunningTrajectoryModel(_Request):
    """A running trajectory (the arrays form of an answer's ``trajectory``; further fields of
    an answer, such as ``duration`` or ``p``, are ignored): M >= 2 samples, ``t`` strictly
    increasing, on any clock."""

    model_config = ConfigDict(extra="ignore")

    t: Annotated[list[Finite], Field(min_length=2, max_length=_MAX_SAMPLES)]
    q: _Samples
    qd: _Samples
    qdd: _Samples


class ReplaceModel(_Request):
    """``replace`` of a plan or sequence request: the new trajectory starts from the running
    one's state at ``at`` (docs/execution.md)."""

    trajectory: RunningTrajectoryModel
    at: Finite = Field(description="Time on the running trajectory's clock, s, inside it.")
    assembly_mode: AssemblyModeLabel = Field(
        "+",
        description="Assembly mode of the running trajectory, when `start` is omitted "
        "(given, `start.assembly_mode` is used).",
    )


def running_model(trajectory: Any) -> RunningTrajectoryModel:
    """The running trajectory of an answer's ``trajectory`` (arrays or points form, a model
    or its dict: a client passes back what it was given)."""
    from planner.wire.timing import TrajectoryModel, TrajectoryPointsModel, trajectory_arrays

    if isinstance(trajectory, RunningTrajectoryModel):
        return trajectory
    if isinstance(trajectory, dict) and "points" in trajectory:
        trajectory = TrajectoryPointsModel.model_validate(trajectory)
    if isinstance(trajectory, TrajectoryModel | TrajectoryPointsModel):
        trajectory = trajectory_arrays(trajectory).model_dump(include={"t", "q", "qd", "qdd"})
    return RunningTrajectoryModel.model_validate(trajectory)


def running_trajectory(
    model: RunningTrajectoryModel, loc: tuple[str | int, ...]
) -> RunningTrajectory:
    """The library's checked running trajectory, an error located at ``loc`` + its field."""
    from planner.timing.running import RunningTrajectory

    with located(*loc):
        return RunningTrajectory.of(model.t, model.q, model.qd, model.qdd, prefix="trajectory")


def fill_start_from_replace(data: Any) -> Any:
    """A request body (before validation) with ``start`` taken from the running state at
    ``replace.at`` when ``start`` is absent: the posture, its velocity and acceleration. A
    body it cannot read is left for the conversion (:func:`replace_start`), which names the
    field; ``start`` then holds a placeholder that is never used."""
    if not isinstance(data, dict) or "start" in data or not isinstance(data.get("replace"), dict):
        return data
    replace = data["replace"]
    asm = replace.get("assembly_mode", "+")
    try:
        from planner.timing.running import RunningTrajectory

        raw = replace["trajectory"]
        running = RunningTrajectory.of(raw["t"], raw["q"], raw["qd"], raw["qdd"])
        q, qd, qdd = running.state_at(running.check_time(replace["at"]))
        start = {"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist(), "assembly_mode": asm}
    except Exception:
        start = {"q": [0.0, 0.0, 0.0], "assembly_mode": asm if asm in ("+", "-") else "+"}
    return {**data, "start": start}


def replace_start(request: Any) -> tuple[float, Any, Any, Any] | None:
    """``(at, q, qd, qdd)`` of a request's ``replace`` (None without one): the running
    state at ``at``, checked against ``start`` (a 422 at ``start`` when it differs by more
    than :data:`START_MATCH_TOL`; at ``replace.at`` outside the running trajectory; at
    ``replace.trajectory.<field>`` for a malformed one)."""
    import numpy as np

    from planner.exceptions import InputError

    replace: ReplaceModel | None = getattr(request, "replace", None)
    if replace is None:
        return None
    running = running_trajectory(replace.trajectory, ("body", "replace"))
    with located("body", "replace"):
        at = running.check_time(replace.at, "at")
    q, qd, qdd = running.state_at(at)
    start = request.start
    for name, given, state in (("q", start.q, q), ("qd", start.qd, qd), ("qdd", start.qdd, qdd)):
        gap = float(np.max(np.abs(np.asarray(given, dtype=float) - state)))
        if gap > START_MATCH_TOL:
            with located("body"):
                raise InputError(
                    f"start.{name} = {list(given)} is not the running state at replace.at = "
                    f"{at!r} ({state.tolist()}; off by {gap:.3g}): omit start, or give that state",
                    field="start",
                )
    return at, q, qd, qdd


def shifted(trajectory: Any, at: float) -> Any:
    """A response's trajectory (arrays or points form) on the running clock: every time
    plus ``at``, so ``t[0] = at`` (None stays None)."""
    if trajectory is None or at == 0.0:
        return trajectory
    if hasattr(trajectory, "points"):
        points = [
            p.model_copy(update={"time_from_start": p.time_from_start + at})
            for p in trajectory.points
        ]
        return trajectory.model_copy(update={"points": points})
    return trajectory.model_copy(update={"t": [x + at for x in trajectory.t]})


def on_running_clock(response: Any, request: Any) -> Any:
    """A plan or sequence response with its times on the running clock of the request's
    ``replace`` (unchanged without one): the trajectory's times, and a sequence's legs'
    ``start_time``, ``end_time`` and ``transit_times``, plus ``replace.at``."""
    replace: ReplaceModel | None = getattr(request, "replace", None)
    if replace is None:
        return response
    at = float(replace.at)
    update: dict[str, Any] = {"trajectory": shifted(response.trajectory, at)}
    legs = getattr(response, "legs", None)
    if legs:

        def later(x: float | None) -> float | None:
            return None if x is None else x + at

        update["legs"] = [
            leg.model_copy(
                update={
                    "start_time": later(leg.start_time),
                    "end_time": later(leg.end_time),
                    "transit_times": [x + at for x in leg.transit_times],
                }
            )
            for leg in legs
        ]
    return response.model_copy(update=update)


# ---------------------------------------------------------------------------- stop
class StopRequest(_Request):
    """Body of ``POST /v1/stop``: brake the running ``trajectory`` to rest from its state at
    ``at``, along its own path where the limits allow (docs/execution.md)."""

    design: DesignModel = _DesignField
    trajectory: RunningTrajectoryModel
    at: Finite = Field(description="Time on the running trajectory's clock, s, inside it.")
    assembly_mode: AssemblyModeLabel = Field("+", description="Assembly mode of the motion.")
    limits: Limits = Field(default_factory=Limits)
    margins: MarginsModel | None = Field(
        None, description="Validity margins the stop keeps (absent: the defaults)."
    )
    obstacles: list[Obstacle] = Field(default_factory=list, max_length=MAX_OBSTACLES)
    format: TrajectoryFormat = Field("arrays", description="'arrays' or 'points'.")
    method: Literal["ruckig", "toppra"] = Field(
        "ruckig",
        description="'ruckig' (default): the stop keeps limits.jerk, q, qd and qdd continuous; "
        "'toppra': second order, the acceleration may jump (as the running trajectory's).",
    )
    sample_rate_hz: Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=10_000.0)] = Field(
        100.0, description="Rate of the answer's samples, Hz (from `at`, the end included)."
    )


StopStatus = Literal["solved", "invalid_start"]


class StopResponse(_Response):
    """Answer of ``POST /v1/stop``. ``solved``: ``trajectory`` comes to rest, within the
    limits and valid; ``along_path`` says whether it keeps to the running path (a time
    scaling of it) or brakes off it (a Ruckig brake: the path's curvature could not be
    followed within the limits). ``invalid_start``: no braking keeps the motion valid
    (``message`` names the rule). Times on the running clock (``t[0] = at``)."""

    status: StopStatus
    message: str = ""
    trajectory: AnyTrajectory | None = None
    along_path: bool = False
    stop_time: float | None = Field(None, description="Time from `at` to rest, s.")
    computation_time_s: float = 0.0


# ---------------------------------------------------------------------------- stream
class StreamStart(_Request):
    """The first message of ``/v1/stream``: a plan or sequence request to stream."""

    type: Literal["plan", "sequence"]
    request: dict[str, Any] = Field(description="A plan or sequence request body.")
    rate_hz: Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=10_000.0)] = Field(
        1000.0, description="Setpoints per second."
    )
    lookahead_s: Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=10.0)] = Field(
        0.05, description="How far ahead of the acknowledged time the service sends, s."
    )


class StreamAck(_Request):
    """The client's clock on the trajectory, s."""

    type: Literal["ack"]
    t: Finite


class StreamReplace(_Request):
    """A new goal (a plan or sequence request of the stream's kind), spliced at the next
    chunk boundary."""

    type: Literal["replace"]
    request: dict[str, Any]


class StreamStop(_Request):
    """Brake to rest from the next chunk boundary."""

    type: Literal["stop"]


#: A client message after the first.
StreamMessage = Annotated[StreamAck | StreamReplace | StreamStop, Field(discriminator="type")]
