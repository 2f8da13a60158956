"""One trajectory from the pieces of a sequence with moving targets
(:mod:`planner.sequence.moving`): the static runs' timed curves, the waits, the moves into and
out of each tracking span and the spans themselves, one after the other on one time axis,
sampled at the timing's rate as a timed path is (:func:`planner.timing.parameterize.time_path`'s
last step: the output rate's samples plus every rest instant, the rest state exact there),
plus the start and the end of every tracking span: the samples hold the tool at the leg's
``meet_point`` at its ``meet_time`` (a client, or the viewer's belt view, reads the meeting
from the samples, not between two of them: at 100 Hz and 0.5 m/s those are 5 mm apart).

Every piece has been checked densely already (the static runs by their own timing, the rest
by :meth:`planner.sequence.interception.Interception.build`), so this step only joins and
samples; its measures are the pieces' (the largest deviation from a plan, the repairs and
checked samples summed).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from planner.motion import MotionProblem
from planner.sequence.belt import ChainCurve, TrackingCurve
from planner.sequence.problem import SequenceResult
from planner.timing.job import MAX_OUTPUT_SAMPLES
from planner.timing.torque import TorqueModel
from planner.timing.trajectory import Trajectory, p_velocity, sample_times

__all__ = ["joined_trajectory"]


def joined_trajectory(
    problem: MotionProblem,
    pieces: Sequence[object],
    static: Sequence[SequenceResult],
    torque: TorqueModel | None,
    t0: float,
) -> Trajectory:
    """The pieces joined (:class:`~planner.sequence.belt.ChainCurve`, zero-length pieces
    dropped) and sampled at ``timing.sample_rate_hz`` (``timing.max_samples`` bounds the
    count: an :class:`~planner.exceptions.InputError` at ``timing.sample_rate_hz``)."""
    from planner.exceptions import InputError

    started = time.monotonic()
    curve = ChainCurve(tuple(c for c in pieces if c.duration > 0.0))  # type: ignore[attr-defined]
    rate = problem.timing.sample_rate_hz
    count = int(np.floor(curve.duration * rate)) + 1
    asked = problem.timing.max_samples
    cap = MAX_OUTPUT_SAMPLES if asked is None else min(asked, MAX_OUTPUT_SAMPLES)
    if count > cap:
        raise InputError(
            f"sample_rate_hz = {rate:g} Hz would produce {count} samples over the "
            f"trajectory's {curve.duration:.4g} s, more than the limit of "
            f"{cap}: lower the rate",
            field=("timing", "sample_rate_hz"),
        )
    rests = curve.rest_times()
    starts = curve.starts  # the tracking spans' ends (a meeting and the end of its dwell)
    tracked = [
        starts[k + j]
        for k, c in enumerate(curve.pieces)
        if isinstance(c, TrackingCurve)
        for j in (0, 1)
    ]
    t = np.union1d(sample_times(curve.duration, rate), rests)
    # an instant within a nanosecond of a sample is that sample (no pair of samples 1e-16 s
    # apart, whose differences would mean nothing)
    extra = [x for x in np.clip(tracked, 0.0, curve.duration) if np.min(np.abs(t - x)) > 1e-9]
    t = np.union1d(t, extra)
    q, qd, qdd, jerk = curve.evaluate(t)
    rest = np.isin(t, rests)
    rest[0] = rest[-1] = True
    qd[rest] = 0.0
    qdd[rest] = 0.0
    if problem.timing.method == "toppra" or (jerk is not None and not np.all(np.isfinite(jerk))):
        jerk = None  # second-order moves and toppra: the acceleration jumps, no jerk
    asm = problem.start.assembly_mode
    p, v_p, _ = p_velocity(problem.design, q, qd, asm)
    tau = None if torque is None else torque.torques(q, qd, qdd)
    trajs = [r.trajectory for r in static if r.trajectory is not None]
    ratio = None
    if tau is not None and problem.limits.torque is not None:
        ratio = float(np.max(np.nan_to_num(np.abs(tau)) / problem.limits.torque_array))
    return Trajectory(
        method=problem.timing.method,
        duration=curve.duration,
        t=t,
        q=q,
        qd=qd,
        qdd=qdd,
        jerk=jerk,
        p=p,
        p_speed=np.linalg.norm(v_p, axis=1),
        max_deviation_q=max((tr.max_deviation_q for tr in trajs), default=0.0),
        max_deviation_p=max((tr.max_deviation_p for tr in trajs), default=0.0),
        repairs=sum(tr.repairs for tr in trajs),
        checked_samples=sum(tr.checked_samples for tr in trajs),
        computation_time_s=time.monotonic() - started + sum(tr.computation_time_s for tr in trajs),
        curve=curve,
        tau=tau,
        max_torque_ratio=ratio,
    )
