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
* **Splices.** A replacement or a stop takes effect at the *next chunk boundary*
  (:attr:`StreamSession.boundary`: the first time not yet sent): the new trajectory starts
  from the current one's state there (``replace.at`` of a plan or sequence request, or
  ``at`` of a stop), so the setpoints stay continuous in q, qd and qdd.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from planner.endpoints import UNBOUNDED, JobBudget
from planner.timing.running import RunningTrajectory

__all__ = ["CHUNK_S", "StreamSession", "plan", "sequence", "stop"]

#: Time covered by one chunk of setpoints, s (10 setpoints at 1 kHz).
CHUNK_S = 0.01


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

    def acknowledge(self, t: float) -> None:
        """The client's clock on the trajectory reached ``t`` (s)."""
        self.ack = max(self.ack, float(t))

    def pending(self) -> list[dict[str, Any]]:
        """The messages due now: chunks until ``ack + lookahead_s`` is covered (the first
        chunk at once, whatever the ack), then ``done`` once the end has been sent."""
        out: list[dict[str, Any]] = []
        per_chunk = max(1, round(CHUNK_S * self.rate_hz))
        while not self.finished:
            horizon = max(self.ack, self.t0) + self.lookahead_s
            if self.sent > 0 and self.boundary > horizon:
                break
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

    def splice_time(self) -> float:
        """Where a replacement or stop starts: the next chunk boundary, inside the current
        trajectory (its end once the end has been sent)."""
        return min(self.boundary, self.end)

    def switch(self, trajectory: dict[str, Any], at: float) -> dict[str, Any]:
        """Continue with ``trajectory`` (starting at ``at`` on the stream's clock): the
        ``switched`` message. The grid goes on where it was (``at`` is a grid time)."""
        self._load(trajectory)
        self.finished = False
        return {"type": "switched", "at": at}

    def replace_request(self, request: dict[str, Any], at: float) -> dict[str, Any]:
        """A plan or sequence request body replacing the current trajectory at ``at``, its
        answer sampled at the stream's rate."""
        running = {k: self.trajectory[k] for k in ("t", "q", "qd", "qdd")}
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
            "trajectory": {k: self.trajectory[k] for k in ("t", "q", "qd", "qdd")},
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
