"""The work of ``/v1/stream`` without the socket: a trajectory cut into chunks of setpoints,
paced by the client's acknowledged clock, and spliced by a replacement or a stop.

The service's WebSocket route (:mod:`planner_api.routes.stream`) does the I/O; this module
holds the rules, so they are the same wherever a stream is served and testable without a
socket:

* **Setpoints.** The trajectory is read as a controller reads it
  (:class:`planner.timing.running.RunningTrajectory`, quintic between samples) on the grid
  ``t0 + i / rate_hz`` of the stream's own clock (the trajectory's: a replacement's answer is
  on the running clock already). A chunk holds ``CHUNK_S`` of it (at least one setpoint);
  past the trajectory's end the grid holds its last state (at rest).
* **Pacing.** The session sends chunks until it has covered ``ack + lookahead_s`` (``ack``
  the latest time the client acknowledged, its clock on the trajectory), then waits for the
  next acknowledgement: a client that stops reading or acknowledging gets nothing more (and
  the route closes it after its idle timeout), so the service never queues unbounded data.
* **Splices.** A replacement or a stop is computed while the current trajectory keeps
  streaming (a controller cannot wait for a planner), so it is planned from a splice time
  ahead of what will have been sent when its answer is ready: :meth:`StreamSession.splice_time`,
  the first chunk boundary at or after the send horizon (``ack + lookahead_s``, or what was
  already sent if more) plus a margin (:meth:`StreamSession.margin`: twice this session's last
  computing time of the same kind, a plan for a replacement, a brake for a stop, at least
  :data:`MIN_MARGIN_S`). The new trajectory starts from the current
  one's state there (``replace.at`` of a plan or sequence request, or ``at`` of a stop), so
  the setpoints stay continuous in q, qd and qdd; it takes over at that boundary. If the
  answer comes back after its splice time has been sent (planning slower than the margin),
  it is thrown away and the replacement is planned again from a later splice time (with the
  margin from the planning time just seen), up to :data:`REPLANS` times; the last try holds
  the stream at its splice time until the answer is ready (late setpoints rather than a
  discontinuity or a lost replacement). While a replacement is pending, chunks are full
  (so its splice time is a chunk boundary) and past the current trajectory's end they hold
  its final state (no ``done``); the running trajectory it is planned from then has that
  final sample repeated at the splice time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from planner.endpoints import UNBOUNDED, JobBudget
from planner.timing.running import RunningTrajectory

__all__ = ["CHUNK_S", "MIN_MARGIN_S", "REPLANS", "StreamSession", "plan", "sequence", "stop"]

#: Time covered by one chunk of setpoints, s (10 setpoints at 1 kHz).
CHUNK_S = 0.01
#: Least margin between the send horizon and a replacement's splice time, s.
MIN_MARGIN_S = 0.02
#: Plans of one replacement that may come back too late before the stream waits for one.
REPLANS = 3


@dataclass(eq=False)
class StreamSession:
    """One stream's state: the trajectory (arrays form, on its own clock), the rate and the
    lookahead, what has been sent and acknowledged."""

    trajectory: dict[str, Any]
    rate_hz: float
    lookahead_s: float
    running: RunningTrajectory = field(init=False)
    sent: int = 0  # setpoints sent since t0
    t0: float = 0.0
    ack: float = -math.inf
    finished: bool = False
    plan_s: float = 0.0  # wall time of this session's last plan, s (a replacement's margin)
    stop_s: float = 0.0  # wall time of this session's last stop, s (a stop's margin)
    holding: bool = False  # a replacement is pending: hold the rest state past the end
    # the trajectory switched from, still streamed before ``switch_at``
    previous: RunningTrajectory | None = None
    switch_at: float = -math.inf

    def __post_init__(self) -> None:
        self._load(self.trajectory)
        self.t0 = self.running.start

    def _load(self, trajectory: dict[str, Any]) -> None:
        self.trajectory = trajectory
        self.running = RunningTrajectory.of(
            trajectory["t"], trajectory["q"], trajectory["qd"], trajectory["qdd"]
        )

    @property
    def dt(self) -> float:
        return 1.0 / self.rate_hz

    @property
    def boundary(self) -> float:
        """The first time not yet sent (where a splice takes effect), s."""
        return self.t0 + self.sent * self.dt

    @property
    def end(self) -> float:
        """The current trajectory's last time, s."""
        return self.running.end

    @property
    def chunk_len(self) -> int:
        """Setpoints in a full chunk."""
        return max(1, round(CHUNK_S * self.rate_hz))

    @property
    def horizon(self) -> float:
        """How far the stream sends: the client's clock plus the lookahead, s."""
        return max(self.ack, self.t0) + self.lookahead_s

    def margin(self, kind: str = "replace") -> float:
        """The splice time's margin over the send horizon: twice the last computing time of
        the same kind (a ``"stop"``'s brake takes about a millisecond, a replacement a plan:
        a stop is never delayed by how long the plans took; the first stop has the least
        margin, :data:`MIN_MARGIN_S`, and is re-planned later if it comes back too late)."""
        seconds = self.stop_s if kind == "stop" else self.plan_s
        return max(MIN_MARGIN_S, 2.0 * seconds)

    def acknowledge(self, t: float) -> None:
        """The client's clock on the trajectory reached ``t`` (s)."""
        self.ack = max(self.ack, float(t))

    def pending(self, until: float = math.inf) -> list[dict[str, Any]]:
        """The messages due now: chunks until ``ack + lookahead_s`` is covered (the first
        chunk at once, whatever the ack) and none starting at or past ``until``, then
        ``done`` once the end has been sent (not while :attr:`holding`)."""
        out: list[dict[str, Any]] = []
        per_chunk = self.chunk_len
        while not self.finished:
            if self.sent > 0 and self.boundary > self.horizon:
                break
            if self.boundary >= until - 1e-9:
                break
            if self.holding:  # full chunks (the splice is a chunk boundary), rest past the end
                out.append(self._chunk(per_chunk))
                continue
            if self.sent > 0 and self.boundary - self.dt >= self.end - 1e-12:
                out.append({"type": "done", "t": self.end})
                self.finished = True
                break
            # up to the first grid time at or past the end, which holds the final rest state
            left = math.ceil((self.end - self.boundary) * self.rate_hz - 1e-9) + 1
            n = max(1, min(per_chunk, left))
            out.append(self._chunk(n))
        return out

    def _chunk(self, n: int) -> dict[str, Any]:
        t = self.t0 + (self.sent + np.arange(n)) * self.dt
        q, qd, qdd, _ = self.running.evaluate(np.minimum(t, self.end))
        before = t < self.switch_at - 1e-9  # not yet at the splice: the old trajectory
        if self.previous is not None and np.any(before):
            old = self.previous.evaluate(np.minimum(t[before], self.previous.end))
            q[before], qd[before], qdd[before] = old[0], old[1], old[2]
        chunk = {
            "type": "setpoints",
            "t0": float(t[0]),
            "dt": self.dt,
            "q": q.tolist(),
            "qd": qd.tolist(),
            "qdd": qdd.tolist(),
        }
        self.sent += n
        return chunk

    def splice_time(self, margin_s: float = 0.0) -> float:
        """Where a replacement or stop starts: the first chunk boundary at or after the send
        horizon (or what was sent, if more) plus ``margin_s``, on the stream's grid."""
        chunk = self.chunk_len * self.dt
        target = max(self.boundary, self.horizon, self.switch_at) + margin_s
        return self.boundary + max(0, math.ceil((target - self.boundary) / chunk - 1e-9)) * chunk

    def too_late(self, at: float) -> bool:
        """Whether setpoints at or past ``at`` were sent (a splice there would jump)."""
        return self.boundary > at + 1e-9

    def _running(self, at: float) -> dict[str, Any]:
        """The current trajectory as a running one reaching ``at``: past its end, its final
        sample (at rest) repeated at ``at``, which is what the stream sends there."""
        running = {k: list(self.trajectory[k]) for k in ("t", "q", "qd", "qdd")}
        if at > self.end + 1e-12:
            running["t"].append(at)
            for k in ("q", "qd", "qdd"):
                running[k].append(running[k][-1])
        return running

    def switch(self, trajectory: dict[str, Any], at: float) -> dict[str, Any]:
        """Continue with ``trajectory`` (starting at ``at`` on the stream's clock): the
        ``switched`` message. The grid goes on where it was (``at`` is a grid time): the
        setpoints before ``at`` still come from the current trajectory."""
        if len(trajectory["t"]) < 2:  # a stop from rest (past the end): that state, held
            held = {k: [trajectory[k][0]] * 2 for k in ("q", "qd", "qdd")}
            trajectory = {**trajectory, **held, "t": [at, at + self.dt]}
        self.previous, self.switch_at = self.running, at
        self._load(trajectory)
        self.finished = self.holding = False
        return {"type": "switched", "at": at}

    def replace_request(self, request: dict[str, Any], at: float) -> dict[str, Any]:
        """A plan or sequence request body replacing the current trajectory at ``at``, its
        answer sampled at the stream's rate."""
        running = self._running(at)
        timing = {**request.get("timing", {}), "sample_rate_hz": self.rate_hz}
        body = {**request, "timing": timing, "replace": {"trajectory": running, "at": at}}
        body.pop("start", None)  # the running state at ``at`` is the start
        return body

    def stop_request(self, request: dict[str, Any], at: float) -> dict[str, Any]:
        """A stop request body braking the current trajectory from ``at`` (the design,
        limits, margins and obstacles of the stream's ``request``), sampled at the rate."""
        keep = ("design", "limits", "margins", "obstacles")
        body = {k: request[k] for k in keep if k in request}
        method = request.get("timing", {}).get("method", "toppra")
        return {
            **body,
            "trajectory": self._running(at),
            "at": at,
            "assembly_mode": request.get("start", {}).get("assembly_mode", "+"),
            "method": "ruckig" if method == "ruckig" else "toppra",
            "sample_rate_hz": self.rate_hz,
        }


# the jobs a stream runs in the worker pool (module-level: they cross to a worker)
def plan(request: Any, budget: JobBudget = UNBOUNDED) -> Any:
    """A streamed plan (and its replacements): :func:`planner.endpoints.plan.plan`."""
    from planner.endpoints.plan import plan as job

    return job(request, budget)


def sequence(request: Any, budget: JobBudget = UNBOUNDED) -> Any:
    """A streamed sequence: :func:`planner.endpoints.sequence.sequence`."""
    from planner.endpoints.sequence import sequence as job

    return job(request, budget)


def stop(request: Any, budget: JobBudget = UNBOUNDED) -> Any:
    """A stream's stop: :func:`planner.endpoints.stop.stop`."""
    from planner.endpoints.stop import stop as job

    return job(request, budget)
