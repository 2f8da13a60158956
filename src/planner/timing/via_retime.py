"""A via chain re-timed along its own path under the torque limits (toppra).

A via chain (:mod:`planner.timing.vias`) is a chain of Ruckig moves timed under the joint
velocity and acceleration limits only. With ``limits.torque`` the chain used to be slowed
uniformly in time until every torque held: the whole chain then pays for the one instant
where a torque binds (on the Adept cycle under the benchmark's motors, 1.13-1.20 x the
optimal-control optimum, ``docs/sequences.md``). Here the chain's own path, ``q(s)`` with
the chain's time as the path parameter (so ``q'`` and ``q''`` are the chain's velocity and
acceleration, exact), is timed again by toppra under the velocity, acceleration and torque
constraints: the fastest timing of the same postures. It slows the chain only where a limit
binds. The uniform slow-down is a feasible timing of the same path (``sd = c``), so toppra's
optimum is never slower than it but for its grid; the caller keeps the quicker of the two.

The grid: a uniform one (:data:`GRID_INTERVALS`) plus both sides of every phase switch of
every move (where the chain's acceleration jumps: the constraints of the interval around a
switch then hold on both of its sides). Between grid points q'' varies (a jerk-limited
move) or stays constant, so the limits are re-measured at the chain's check positions and
the profile slowed uniformly by any excess, as toppra's own method does on its blends
(:func:`planner.timing.parameterize.time_path`); the dense re-check has the last word.
Jerk is not defined on the result (its path acceleration is piecewise constant): it is
used only when no jerk is asked.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import toppra
import toppra.algorithm
import toppra.constraint
from toppra.interpolator import AbstractGeometricPath

from planner.exceptions import TimingInfeasibleError
from planner.timing.limits import JointLimits
from planner.timing.ruckig_method import RuckigCurve
from planner.timing.toppra_method import PathProfile, _TorqueConstraint
from planner.timing.torque import TorqueModel, torque_time_scale
from planner.timing.trajectory import SUBSAMPLES, Curve

__all__ = ["GRID_INTERVALS", "RetimedChain", "quicker_retimed", "retime_chain"]

#: Uniform grid intervals over a chain (its phase switches come on top).
GRID_INTERVALS = 120
#: Half the gap of the grid points put on both sides of a phase switch, s.
_SWITCH_GAP = 1e-7
#: The fit aims this far (relative) inside the limits, as toppra's own.
_FIT_MARGIN = 1e-3


class _ChainPath(AbstractGeometricPath):
    """A chain of moves as toppra's path: s is the chain's time, q' its velocity, q'' its
    acceleration."""

    def __init__(self, chain: Curve) -> None:
        self._chain = chain
        self._interval = np.array([0.0, chain.duration])

    def __call__(self, path_positions: float | np.ndarray, order: int = 0) -> np.ndarray:
        s = np.atleast_1d(np.asarray(path_positions, dtype=float))
        q, qd, qdd, _ = self._chain.evaluate(s)
        out = (q, qd, qdd)[order]
        return out if np.ndim(path_positions) else out[0]

    @property
    def dof(self) -> int:
        return 3

    @property
    def path_interval(self) -> np.ndarray:
        return self._interval


@dataclass(frozen=True, eq=False)
class RetimedChain:
    """q(t) = chain(s(t)) for a toppra profile over the chain's own time."""

    chain: Curve
    profile: PathProfile

    @property
    def duration(self) -> float:
        return self.profile.duration

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, None]:
        s, sd, sdd = self.profile.at_time(t)
        q, d1, d2, _ = self.chain.evaluate(s)
        return q, d1 * sd[:, None], d1 * sdd[:, None] + d2 * (sd**2)[:, None], None

    def _positions(self, resolution: float) -> np.ndarray:
        """The chain's check positions, the profile's grid points and both sides of each,
        and :data:`SUBSAMPLES` points inside every grid interval."""
        prof = self.profile
        ds = np.diff(prof.s)
        frac = np.concatenate([[1e-9], np.arange(1, SUBSAMPLES + 1) / (SUBSAMPLES + 1), [1 - 1e-9]])
        sub = (prof.s[:-1, None] + ds[:, None] * frac[None, :]).ravel()
        return np.unique(np.concatenate([self.chain.check_times(resolution), sub, prof.s]))

    def check_times(self, resolution: float) -> np.ndarray:
        t, _, _ = self.profile.at_path(self._positions(resolution))
        return np.unique(np.clip(t, 0.0, self.duration))

    def rest_times(self) -> np.ndarray:
        return np.empty(0)

    def plan_segments(self, t: np.ndarray) -> np.ndarray:
        s, _, _ = self.profile.at_time(np.atleast_1d(np.asarray(t, dtype=float)))
        return self.chain.plan_segments(s)


def _grid(chain: RuckigCurve) -> np.ndarray:
    """Uniform points and both sides of every phase switch of every move."""
    d = chain.duration
    switches = [chain.start[k] + m.cum.ravel() for k, m in enumerate(chain.moves)]
    sw = np.concatenate([chain.start, *switches])
    pts = np.concatenate(
        [np.linspace(0.0, d, GRID_INTERVALS + 1), sw - _SWITCH_GAP, sw + _SWITCH_GAP]
    )
    pts = np.unique(np.clip(pts, 0.0, d))
    keep = np.concatenate([[True], np.diff(pts) > 1e-12])
    pts = pts[keep]
    pts[-1] = d
    return pts


def retime_chain(
    chain: Curve, limits: JointLimits, model: TorqueModel, resolution: float
) -> RetimedChain | None:
    """``chain`` (a :class:`~planner.timing.ruckig_method.RuckigCurve`) timed again by toppra
    along its own path under ``limits`` (velocity, acceleration, torque) and fitted so that
    they hold at its check positions (module docstring); None when it cannot be (no torque
    limit, not a chain of moves, or toppra finds no profile)."""
    tau_max = limits.torque_array
    if tau_max is None or not isinstance(chain, RuckigCurve) or chain.duration <= 0.0:
        return None
    path = _ChainPath(chain)
    grid = _grid(chain)
    interp = toppra.constraint.DiscretizationType.Interpolation
    v, a = limits.velocity_array, limits.acceleration_array
    constraints = [
        toppra.constraint.JointVelocityConstraint(np.stack([-v, v], axis=1)),
        toppra.constraint.JointAccelerationConstraint(
            np.stack([-a, a], axis=1), discretization_scheme=interp
        ),
        _TorqueConstraint(model, tau_max, 1.0),
    ]
    instance = toppra.algorithm.TOPPRA(constraints, path, gridpoints=grid, solver_wrapper="seidel")
    try:
        _, sd, _ = instance.compute_parameterization(0.0, 0.0)
    except (ZeroDivisionError, TimingInfeasibleError):
        return None
    if sd is None or not np.all(np.isfinite(sd)):
        return None
    sd = np.maximum(np.asarray(sd, dtype=float), 0.0)
    sd[0] = sd[-1] = 0.0
    curve = RetimedChain(chain, PathProfile.from_grid(grid, sd))
    return _fitted(curve, limits, model, tau_max, resolution)


def _fitted(
    curve: RetimedChain,
    limits: JointLimits,
    model: TorqueModel,
    tau_max: np.ndarray,
    resolution: float,
) -> RetimedChain:
    """``curve``'s profile slowed uniformly just enough that velocity, acceleration and
    torques hold at its check positions (velocities scale by c, accelerations by c^2, the
    dynamic part of the torques by c^2)."""
    s = curve._positions(resolution)
    _, sd, sdd = curve.profile.at_path(s)
    q, d1, d2, _ = curve.chain.evaluate(s)
    qd = d1 * sd[:, None]
    qdd = d1 * sdd[:, None] + d2 * (sd**2)[:, None]
    target = 1.0 - _FIT_MARGIN
    r_v = float(np.max(np.abs(qd) / limits.velocity_array))
    r_a = float(np.max(np.abs(qdd) / limits.acceleration_array))
    c = min(1.0, target / max(r_v, 1e-300), float(np.sqrt(target / max(r_a, 1e-300))))
    dyn, grav = model.split(q, qd, qdd)
    c = min(c, torque_time_scale(dyn, grav, tau_max, target))
    return curve if c >= 1.0 else RetimedChain(curve.chain, curve.profile.time_scaled(c))


def quicker_retimed(
    chain: Curve,
    uniform: Curve,
    limits: JointLimits,
    model: TorqueModel | None,
    resolution: float,
    refit,
) -> Curve:
    """The quicker of ``uniform`` (the chain slowed uniformly until its torques hold) and the
    chain re-timed along its path under the torque limits (then ``refit``: the uniform
    slow-downs of the Cartesian speed bound and the torque limits, a no-op when they hold).
    Only without a jerk limit (the re-timed chain's jerk is not defined)."""
    if model is None or limits.torque is None or limits.jerk is not None:
        return uniform
    retimed = retime_chain(chain, limits, model, resolution)
    if retimed is None:
        return uniform
    fitted = refit(retimed)
    return fitted if fitted.duration < uniform.duration else uniform
