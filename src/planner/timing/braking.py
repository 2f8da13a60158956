"""A stop: the braking trajectory to rest from any state of a running trajectory.

The running trajectory (:class:`~planner.timing.running.RunningTrajectory`, read as a
controller reads it) is at state x(at). :func:`stop_trajectory` brings it to rest, in this
order of preference:

1. **Along the running path** (a time scaling): ``q_stop(t) = q_run(sigma(t))`` with
   ``sigma(0) = at``, ``sigma' = 1 - S(t / D)``, ``S(x) = 10 x^3 - 15 x^4 + 6 x^5`` (the
   quintic smoothstep) for ``0 <= t <= D``: the path speed falls from 1 to 0 with
   ``sigma'' = sigma''' = 0`` at both ends, so the stop starts in exactly x(at) (q, qd, qdd
   and the jerk continuous) and ends at rest with zero acceleration, after ``D / 2`` of
   running time. Its rates are
   ``qd = qd_run sigma'``, ``qdd = qdd_run sigma'^2 + qd_run sigma''`` and
   ``jerk = jerk_run sigma'^3 + 3 qdd_run sigma' sigma'' + qd_run sigma'''``: the velocity
   never exceeds the running one; acceleration and jerk (by differences of qdd: the
   quintic reading's own jerk overshoots between samples where the running jerk switches,
   its mean over an interval does not) are checked on a grid for
   ``CANDIDATES`` durations D (geometric, from a lower bound of the limits) in one
   vectorised pass, and the shortest that keeps them (with ``GRID_MARGIN`` to spare between
   grid points) is taken. The postures are the running path's own, re-checked against the
   request's scene (the non-serial rules: joint limits, assembly, kappa(A), clearance; the
   path's own serial crossings were planned).
2. **Off the path** (when the path's curvature or the running acceleration leaves no room,
   e.g. already braking at the acceleration limit): the quickest Ruckig brake from x(at)
   (:func:`~planner.timing.lead_in.brake_move`, phase-synchronised: along the tangent when qd
   and qdd are parallel), checked against every rule of the working mode at ``at``.
3. Neither valid: status ``invalid_start`` with the rule, time and posture.

Method ``ruckig`` keeps the jerk limit (q, qd and qdd continuous); ``toppra`` is second order
(no jerk limit: the acceleration may jump, as in a toppra trajectory). The answer's samples
(at ``sample_rate_hz`` from ``at``, the end included) are verified against the limits before
it is returned. Computed in well under a millisecond (``benchmarks/execution.py``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from planner.design import Design
from planner.exceptions import TimingInfeasibleError
from planner.timing.checks import LIMIT_RTOL, StateChecker
from planner.timing.lead_in import StartState, _first_failure, _speed, brake_move
from planner.timing.limits import JointLimits
from planner.timing.running import RunningTrajectory
from planner.timing.trajectory import sample_times

__all__ = ["CANDIDATES", "GRID", "GRID_MARGIN", "StopResult", "stop_trajectory"]

#: Durations D tried for the time scaling (geometric, ratio ``_RATIO``).
CANDIDATES = 16
#: Candidates checked in one vectorised pass (the shortest first).
CHUNK = 4
_RATIO = 1.2
#: Points of the grid in x = t / D on which each candidate's rates are checked.
GRID = 64
#: Relative room kept at the grid points (the rates are smooth between them).
GRID_MARGIN = 0.01


@dataclass(frozen=True, eq=False)
class StopResult:
    """A stop (module docstring): ``status`` "solved" or "invalid_start", the ``message``,
    the samples ``t`` (on the running clock, from ``at``), ``q``, ``qd``, ``qdd`` (M, 3),
    ``along_path``, the time to rest ``stop_time`` (s) and the ``computation_time_s``."""

    status: str
    message: str
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    along_path: bool
    stop_time: float
    computation_time_s: float


def _scaling(x: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, ...]:
    """sigma - at, sigma', sigma'' at x = t / D (..., N) for durations d (..., 1)."""
    g = d * (x - 2.5 * x**4 + 3 * x**5 - x**6)
    s1 = 1.0 - x**3 * (10 - 15 * x + 6 * x**2)
    s2 = -30 * x**2 * (1 - x) ** 2 / d
    return g, s1, s2


def _rates(
    running: RunningTrajectory, at: float, x: np.ndarray, d: np.ndarray
) -> tuple[np.ndarray, ...]:
    """q, qd, qdd of the scaled stops (K, N, 3) for durations d (K, 1) at x (N,)."""
    g, s1, s2 = _scaling(x[None, :], d)
    q, v, a, _ = running.evaluate((at + g).ravel())
    shape = (*g.shape, 3)
    q, v, a = (y.reshape(shape) for y in (q, v, a))
    s1, s2 = s1[..., None], s2[..., None]
    return q, v * s1, a * s1**2 + v * s2


def _durations(qd: np.ndarray, limits: JointLimits, jerk_limited: bool, room: float) -> np.ndarray:
    """Candidate durations D, s: from a lower bound (|qd sigma''| <= a at x = 1/2, where
    |sigma''| = 1.875 / D; |qd sigma'''| <= j where it peaks, 5.77 / D^2) up, geometric,
    those whose stop fits in the running time left (``room`` = end - at: D / 2 <= room)."""
    low = max(1e-3, 1.875 * float(np.max(np.abs(qd) / limits.acceleration_array)))
    jerk = limits.jerk_array
    if jerk_limited and jerk is not None:
        low = max(low, float(np.sqrt(5.77 * np.max(np.abs(qd) / jerk))))
    d = low * _RATIO ** np.arange(CANDIDATES)
    return d[d / 2 <= room]


def _along_path(
    running: RunningTrajectory, at: float, qd0: np.ndarray, limits: JointLimits, jerk_limited: bool
) -> float | None:
    """The shortest duration D of a time-scaled stop within the limits, or None."""
    d = _durations(qd0, limits, jerk_limited, running.end - at)
    if d.size == 0:
        return None
    x = np.linspace(0.0, 1.0, GRID)
    # the longest first: its scaling is the mildest, and where even it breaks a limit the
    # running trajectory is itself at that limit near at (a time-optimal one mostly is), and
    # no shorter one keeps it either (then the brake, without the other chunks' cost)
    if _fitting(running, at, x, d[-1:], limits, jerk_limited) is None:
        return None
    for first in range(0, d.size, CHUNK):  # the shortest first: most stops end in the first
        found = _fitting(running, at, x, d[first : first + CHUNK], limits, jerk_limited)
        if found is not None:
            return found
    return None


def _fitting(
    running: RunningTrajectory,
    at: float,
    x: np.ndarray,
    d: np.ndarray,
    limits: JointLimits,
    jerk_limited: bool,
) -> float | None:
    """The shortest of durations ``d`` whose scaled stop keeps the limits on grid ``x``."""
    _, qd, qdd = _rates(running, at, x, d[:, None])
    inside = np.full((x.size, 1), 1.0 - GRID_MARGIN)
    inside[0] = 1.0 + LIMIT_RTOL  # x = 0: the running state itself, kept as it is
    ok = np.all(np.abs(qdd) <= limits.acceleration_array * inside, axis=(1, 2))
    ok &= np.all(np.abs(qd) <= limits.velocity_array * (1.0 + LIMIT_RTOL), axis=(1, 2))
    j_max = limits.jerk_array
    if jerk_limited and j_max is not None:  # by differences: what a controller sees
        fd = np.diff(qdd, axis=1) / (d[:, None, None] / (x.size - 1))
        ok &= np.all(np.abs(fd) <= j_max * (1.0 + LIMIT_RTOL), axis=(1, 2))
    return float(d[int(np.argmax(ok))]) if np.any(ok) else None


def _sampled_scaling(
    running: RunningTrajectory, at: float, d: float, rate: float
) -> tuple[np.ndarray, ...]:
    """t (from 0), q, qd, qdd of the time-scaled stop of duration d at ``rate``."""
    t = sample_times(d, rate)
    q, qd, qdd = _rates(running, at, t / d, np.array([[d]]))
    return t, q[0], qd[0], qdd[0]


def _within(
    t: np.ndarray, qd: np.ndarray, qdd: np.ndarray, limits: JointLimits, jerk_limited: bool
) -> bool:
    """The samples keep velocity and acceleration, and (jerk-limited) the jerk by finite
    differences of qdd between them."""
    tol = 1.0 + LIMIT_RTOL
    ok = bool(
        np.all(np.abs(qd) <= limits.velocity_array * tol)
        and np.all(np.abs(qdd) <= limits.acceleration_array * tol)
    )
    j_max = limits.jerk_array
    if ok and jerk_limited and j_max is not None and len(t) > 1:
        fd = np.diff(qdd, axis=0) / np.diff(t)[:, None]
        ok = bool(np.all(np.abs(fd) <= j_max * tol))
    return ok


def stop_trajectory(
    running: RunningTrajectory,
    at: float,
    *,
    design: Design,
    assembly_mode: str,
    limits: JointLimits,
    path_rules: StateChecker | None,
    brake_rules: StateChecker | None,
    jerk_limited: bool = True,
    sample_rate_hz: float = 100.0,
    resolution: float = 0.01,
) -> StopResult:
    """The stop of ``running`` from its state at ``at`` (module docstring).

    Parameters
    ----------
    running, at : the running trajectory and the time on its clock (inside it), s.
    design, assembly_mode : the robot (joint limits, assembly).
    limits : velocity, acceleration (and jerk, with ``jerk_limited``) kept by the stop.
    path_rules : validity of postures on the running path, Q (M, 3) -> (M,) bool.
    brake_rules : validity of postures off it (a Ruckig brake).
    sample_rate_hz, resolution : output rate (Hz) and the dense check's step (rad).
    """
    if jerk_limited:  # ruckig's moves: the asked jerk, else RUCKIG_DEFAULT_JERK (as time_path)
        limits = limits.with_ruckig_jerk()
    t0 = time.perf_counter()
    at = running.check_time(at)
    q0, qd0, qdd0 = running.state_at(at)
    if not (np.any(qd0 != 0.0) or np.any(qdd0 != 0.0)):
        z = np.zeros((1, 3))
        return StopResult(
            "solved",
            "at rest",
            np.array([at]),
            q0[None],
            z,
            z.copy(),
            True,
            0.0,
            time.perf_counter() - t0,
        )
    d = _along_path(running, at, qd0, limits, jerk_limited)
    why_path = "no time scaling of the running path keeps the limits"
    if d is not None:
        t, q, qd, qdd = _sampled_scaling(running, at, d, sample_rate_hz)
        n = max(2, int(np.ceil(float(np.max(np.linalg.norm(qd, axis=1))) * d / resolution)) + 1)
        dense = running.evaluate(at + _scaling(np.linspace(0, 1, n), np.array(d))[0])[0]
        bad = _bad_postures(design, assembly_mode, dense, path_rules)
        if bad is None and _within(t, qd, qdd, limits, jerk_limited):
            q[0], qd[0], qdd[0] = q0, qd0, qdd0
            qd[-1] = qdd[-1] = 0.0
            return StopResult(
                "solved",
                "along the running path",
                at + t,
                q,
                qd,
                qdd,
                True,
                float(t[-1]),
                time.perf_counter() - t0,
            )
        why_path = f"the running path fails {bad}" if bad else why_path
    state = StartState(q0, qd0, qdd0)
    return _braked(
        state,
        at,
        design,
        assembly_mode,
        limits,
        brake_rules,
        jerk_limited,
        sample_rate_hz,
        resolution,
        why_path,
        t0,
    )


def _bad_postures(
    design: Design, assembly_mode: str, q: np.ndarray, rules: StateChecker | None
) -> str | None:
    """The first rule postures q (M, 3) break (joint limits, assembly, ``rules``), or None."""
    from planner.kinematics import forward_batch

    lo, hi = np.asarray(design.joint_min), np.asarray(design.joint_max)
    checks = (
        ("joint_limits", lambda: ~np.any((q < lo) | (q > hi), axis=1)),
        ("assembly", lambda: forward_batch(design, q, assembly_mode).ok),
        ("validity", lambda: np.ones(len(q), bool) if rules is None else rules(q)),
    )
    for rule, ok in checks:
        good = np.asarray(ok(), dtype=bool)
        if not np.all(good):
            i = int(np.argmin(good))
            return f"{rule} at q = {np.round(q[i], 6).tolist()}"
    return None


def _braked(
    state: StartState,
    at: float,
    design: Design,
    assembly_mode: str,
    limits: JointLimits,
    rules: StateChecker | None,
    jerk_limited: bool,
    rate: float,
    resolution: float,
    why_path: str,
    t0: float,
) -> StopResult:
    """Step 2 of the module docstring: the quickest Ruckig brake, checked; or step 3."""
    empty = np.empty((0, 3))
    try:
        chain = brake_move(state, limits, jerk_limited=jerk_limited)
    except TimingInfeasibleError as exc:
        why = f"no braking move: {exc}"
    else:
        speed = _speed(limits, state)
        failed = _first_failure(
            chain, design, assembly_mode, limits, rules, resolution, state, speed
        )
        why = failed or ""
        if not why:
            t = sample_times(chain.duration, rate)
            q, qd, qdd, _ = chain.evaluate(t, jerk=False)
            q[0], qd[0], qdd[0] = state.q, state.qd, state.qdd
            qd[-1] = qdd[-1] = 0.0
            message = f"braked off the running path ({why_path})"
            return StopResult(
                "solved",
                message,
                at + t,
                q,
                qd,
                qdd,
                False,
                chain.duration,
                time.perf_counter() - t0,
            )
    return StopResult(
        "invalid_start",
        f"no stop keeps the motion valid: {why_path}; braking off it fails {why}",
        np.array([at]),
        empty,
        empty,
        empty,
        False,
        0.0,
        time.perf_counter() - t0,
    )
