"""What a simulation answers, and the measures taken of it: the tracking error, the time to
settle at each stop, the realised duration.

Definitions (``docs/simulation.md``):

- ``p_error_mm``: per recorded sample, the distance between the realised P (MuJoCo's, the
  midpoint of the two distal tips of the closed loop) and the reference's P (the product's
  forward kinematics of the reference q at that time), mm.
- ``tracking``: the largest and the RMS ``p_error_mm`` over every recorded sample (the motion
  and the hold after it), and per joint the largest |q_reference - q_realised|, rad.
- A stop's settle time: from the reference's arrival at rest, the time until P is within the
  settle tolerance of the reference at every sample until the stop's end (for a stop of one
  instant, the arrival sample alone decides: 0 or not settled). At the final stop the
  simulation holds the last posture until P has stayed within the tolerance for
  :data:`SETTLE_WINDOW_S` (or the hold's bound passes): settled when it has.
  None: not settled.
- ``realised_duration``: the reference's final arrival (its planned duration) plus the final
  stop's settle time: when the simulated robot is at its goal to the tolerance, for good.
  None when it did not settle within the hold.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.simulation.reference import Stop

__all__ = ["SETTLE_WINDOW_S", "Simulation", "Tracking", "settle_times", "tracking_of"]

#: How long P must stay within the settle tolerance at the final stop to count as settled, s.
SETTLE_WINDOW_S = 0.05


@dataclass(frozen=True, slots=True)
class Tracking:
    """The tracking error: ``p_max_mm``, ``p_rms_mm`` (mm, of P), ``q_max`` (3,), rad."""

    p_max_mm: float
    p_rms_mm: float
    q_max: tuple[float, float, float]


@dataclass(frozen=True, eq=False)
class Simulation:
    """A simulated run of a trajectory.

    Attributes
    ----------
    t : shape (K,), s -- the control instants, in the trajectory's clock (from its ``t[0]``)
    q, qd : shape (K, 3), rad, rad/s -- realised actuated joints
    tau : shape (K, 3), N m -- the torque applied from each instant to the next (clipped)
    p : shape (K, 3), m -- realised P (MuJoCo's)
    q_ref : shape (K, 3), rad -- the reference at each instant
    p_ref : shape (K, 3), m -- its P (the product's forward kinematics)
    p_error_mm : shape (K,), mm
    tracking : Tracking
    planned_duration : s -- the reference's duration
    realised_duration : s or None -- see the module docstring
    stops : the reference's stops; settle_times : s or None, one per stop
    engine : "mujoco x.y.z"
    controller : its kind; rate_hz : the control rate; physics_timestep : MuJoCo's, s
    saturated : samples where a torque was clipped to its limit
    assembly_kept : the loop stayed in the reference's assembly mode at every sample
    computation_time_s : CPU time of the run (the simulation loop), s
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray
    p: np.ndarray
    q_ref: np.ndarray
    p_ref: np.ndarray
    p_error_mm: np.ndarray
    tracking: Tracking
    planned_duration: float
    realised_duration: float | None
    stops: tuple[Stop, ...]
    settle_times: tuple[float | None, ...]
    engine: str
    controller: str
    rate_hz: float
    physics_timestep: float
    saturated: int
    assembly_kept: bool
    computation_time_s: float


def tracking_of(q: np.ndarray, q_ref: np.ndarray, p_error_mm: np.ndarray) -> Tracking:
    """The tracking measures of the recorded samples."""
    e = np.abs(q_ref - q)
    return Tracking(
        p_max_mm=float(np.max(p_error_mm)),
        p_rms_mm=float(np.sqrt(np.mean(p_error_mm**2))),
        q_max=(float(e[:, 0].max()), float(e[:, 1].max()), float(e[:, 2].max())),
    )


def settle_times(
    stops: list[Stop],
    t: np.ndarray,
    p_error_mm: np.ndarray,
    tolerance_mm: float,
    window: int,
) -> list[float | None]:
    """The settle time of each stop (s, or None), on the samples ``t`` (K,) with their
    errors; ``window``: the samples P must stay within the tolerance at the final stop."""
    within = p_error_mm <= tolerance_mm
    rate_dt = float(t[1] - t[0]) if t.size > 1 else 1.0
    out: list[float | None] = []
    for stop in stops:
        first = int(np.searchsorted(t, stop.arrive - 1e-9 * rate_dt))
        last = t.size - 1 if stop.final else int(np.searchsorted(t, stop.leave + 1e-9 * rate_dt))
        last = min(max(last - (0 if stop.final else 1), first), t.size - 1)
        if first >= t.size or not within[last]:
            out.append(None)
            continue
        i = last
        while i > first and within[i - 1]:
            i -= 1
        if stop.final and last - i + 1 < window:
            out.append(None)
            continue
        wait = float(t[i] - stop.arrive)
        out.append(wait if wait > 1e-9 else 0.0)  # the grid's rounding is no wait
    return out
