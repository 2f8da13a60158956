"""Time-optimal parameterisation of a :class:`BlendedPath` with toppra (seidel solver).

toppra computes the fastest path velocity ``sd(s)`` on a grid of path positions under the
joint velocity and acceleration limits (and optionally a bound on the speed of P). We use only
that profile: between two grid points the path acceleration is constant (toppra's
``ParametrizeConstAccel`` model), and we evaluate the trajectory ourselves from it
(:class:`PathProfile`), so the times, velocities and accelerations are exactly those the
solver certified at the grid points. Between grid points on an arc the joint velocity
``q'(s) sd`` and acceleration ``q'(s) sdd + q''(s) sd^2`` vary with ``s``, so a limit can be
exceeded slightly there: the caller re-checks densely and, if needed, repairs with a finer grid
and slightly scaled limits. On straight pieces ``q'`` is constant and ``q'' = 0``, so the
limits hold exactly at every instant.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import toppra
import toppra.algorithm
import toppra.constraint
from numba import njit
from toppra._CythonUtils import _create_velocity_constraint
from toppra.constraint.linear_constraint import canlinear_colloc_to_interpolate
from toppra.interpolator import AbstractGeometricPath

from planner import _kernels
from planner.caching import cached
from planner.exceptions import TimingDeadlineError, TimingInfeasibleError
from planner.timing.limits import JointLimits
from planner.timing.path import ARC, BlendedPath
from planner.timing.topp_compiled import topp_profile
from planner.timing.torque import TorqueModel

__all__ = [
    "PathProfile",
    "SectionCache",
    "check_deadline",
    "min_blend_radius",
    "read_at_path",
    "read_at_time",
    "section_grid",
    "section_key",
    "solve_toppra",
]

logger = logging.getLogger(__name__)

#: Grid step on straight pieces, rad of joint-space arc length (at least LINE_MIN_INTERVALS
#: intervals per piece: the accelerate/decelerate switch point is quantised by the grid).
LINE_STEP = 0.1
LINE_MIN_INTERVALS = 4
#: Grid step on arcs, rad of turning angle (q' turns by at most this between grid points).
ARC_STEP = 0.2
#: Length of the short line interval next to each line/arc junction, as a fraction of the
#: line: toppra sees the arc's curvature at the junction grid point (see ``_SectionPath``),
#: which would needlessly slow a whole line interval; a short one costs almost nothing.
JUNCTION_INTERVAL = 1e-3
#: Smallest path velocity squared through a blend, in normalised units (see min_blend_radius).
MIN_BLEND_X = 1e-3
#: Upper bound used for sd^2 where a constraint does not bound it (toppra needs finite bounds).
_X_UNBOUNDED = 1e12


class _SectionPath(AbstractGeometricPath):
    """One rest-to-rest section of a :class:`BlendedPath`, in toppra's path interface."""

    def __init__(self, path: BlendedPath, s_start: float, s_end: float) -> None:
        self._path = path
        self._interval = np.array([s_start, s_end])
        self._lo, self._hi = path.section_pieces(s_start, s_end)

    def __call__(self, path_positions: float | np.ndarray, order: int = 0) -> np.ndarray:
        """q, q' or q'' at ``path_positions``. At a line/arc junction q'' jumps; toppra takes one
        value per grid point for the intervals on both sides, so the larger one (the arc's) is
        given: the constraint then holds on both sides of the junction."""
        s = np.atleast_1d(np.asarray(path_positions, dtype=float))
        out = self._path.evaluate(s, order, self._lo, self._hi)
        if order == 2:
            left = self._path.evaluate(s, order, self._lo, self._hi, side="left")
            use_left = np.sum(left**2, axis=1) > np.sum(out**2, axis=1)
            out[use_left] = left[use_left]
        return out if np.ndim(path_positions) else out[0]

    @property
    def dof(self) -> int:
        return 3

    @property
    def path_interval(self) -> np.ndarray:
        return self._interval

    @property
    def pieces(self) -> tuple[int, int]:
        return self._lo, self._hi


class _SpeedAlongPathConstraint(toppra.constraint.LinearConstraint):
    """``|dP/ds| sd <= v_max``: a bound on the speed of P, i.e. on ``sd^2`` alone.

    ``dP/ds = J(q) q'(s)`` is given by ``speed_gain(s)`` (m per rad of path), so the bound is
    ``x = sd^2 <= (v_max / |dP/ds|)^2`` at each grid point (a velocity-type constraint).
    """

    def __init__(self, v_max: float, speed_gain: Callable[[np.ndarray], np.ndarray]) -> None:
        super().__init__()
        self.dof = 3
        self._v_max = v_max
        self._gain = speed_gain

    def x_upper(self, gridpoints: np.ndarray) -> np.ndarray:
        """The bound on ``sd^2`` at each grid point (finite: toppra needs finite bounds)."""
        gain = self._gain(np.asarray(gridpoints, dtype=float))
        upper = np.where(gain > 0, (self._v_max / np.maximum(gain, 1e-300)) ** 2, _X_UNBOUNDED)
        return np.minimum(upper, _X_UNBOUNDED)

    def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
        upper = self.x_upper(gridpoints)
        xbound = np.stack([np.zeros_like(upper), upper], axis=1)
        return None, None, None, None, None, None, xbound


class _TorqueConstraint(toppra.constraint.LinearConstraint):
    """``|tau_j| <= limit_j`` with ``tau = a(s) sdd + b(s) sd^2 + c(s)``
    (:meth:`~planner.timing.torque.TorqueModel.path_coefficients`, vectorised over the grid;
    toppra's own ``JointTorqueConstraint`` calls the inverse dynamics once per grid point and
    term). In the solver's normalised time unit (time scaled by ``scale``: sd^2 and sdd are
    ``scale^2`` times the real ones) the bound reads ``|a u + b x + scale^2 c| <= scale^2
    limit``. Interpolation (toppra's first-order scheme): the bound holds at both ends of each
    grid interval with that interval's path acceleration (collocation would leave the left
    end free, where the acceleration jumps: 35 % overshoots were measured); between grid
    points the fit and the dense re-check see to it."""

    def __init__(self, model: TorqueModel, limit: np.ndarray, scale: float) -> None:
        super().__init__()
        self.dof = 3
        self.identical = True
        self.set_discretization_type(toppra.constraint.DiscretizationType.Interpolation)
        self._model = model
        self._limit = np.asarray(limit, dtype=float)
        self._scale2 = scale**2

    def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
        s = np.asarray(gridpoints, dtype=float)
        a, b, c = self._model.path_coefficients(path(s, 0), path(s, 1), path(s, 2))
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b)) and np.all(np.isfinite(c))):
            raise TimingInfeasibleError(
                "the path passes a parallel singularity: its torques are undefined"
            )
        self._check_held(path(s, 0), a, b, c)
        f = np.vstack([np.eye(3), -np.eye(3)])
        g = np.concatenate([self._limit, self._limit]) * self._scale2
        return canlinear_colloc_to_interpolate(
            a, b, c * self._scale2, f, g, None, None, s, identical=True
        )

    def _check_held(self, q: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> None:
        """Raise :class:`TimingInfeasibleError` where a joint's torque does not depend on
        the motion at all (``a_j = b_j = 0``: e.g. theta1 on a piece that moves only theta2
        and theta3, whose dynamics do not couple into it) and gravity alone needs more than
        its limit: no speed along the path holds that posture. toppra's seidel LP cannot
        say so (it divides by the zero row's norm: a ZeroDivisionError, once a 500)."""
        scale = np.maximum(np.abs(a).max(axis=0), 1e-300)  # (3,): per-joint size of a
        still = (np.abs(a) <= 1e-12 * scale) & (
            np.abs(b) <= 1e-12 * np.maximum(np.abs(b).max(axis=0), scale)
        )
        over = still & (np.abs(c) > self._limit)
        if not over.any():
            return
        i, j = (int(k) for k in np.argwhere(over)[0])
        raise TimingInfeasibleError(
            f"gravity alone needs |tau{j + 1}| = {abs(c[i, j]):.6g} N m at q = "
            f"{np.round(q[i], 6).tolist()} on the path, above the torque limit "
            f"{self._limit[j]:.6g} N m, and no motion along the path changes that torque "
            "there: no timing can hold it"
        )


@dataclass(frozen=True, eq=False)
class PathProfile:
    """Path velocity on a grid, constant path acceleration between grid points.

    Attributes
    ----------
    s : shape (G,), rad -- grid points, increasing (sections joined at rest).
    sd : shape (G,), rad/s -- path velocity at the grid points (0 at every stop).
    time : shape (G,), s -- time at each grid point, ``time[0] = 0``.
    sdd : shape (G - 1,), rad/s^2 -- path acceleration on each interval,
        ``(sd[i+1]^2 - sd[i]^2) / (2 (s[i+1] - s[i]))``.
    """

    s: np.ndarray
    sd: np.ndarray
    time: np.ndarray
    sdd: np.ndarray

    @classmethod
    def from_grid(cls, s: np.ndarray, sd: np.ndarray) -> PathProfile:
        ds = np.diff(s)
        x = sd**2
        sdd = (x[1:] - x[:-1]) / (2 * ds)
        dt = 2 * ds / np.maximum(sd[1:] + sd[:-1], 1e-300)
        return cls(s, sd, np.concatenate([[0.0], np.cumsum(dt)]), sdd)

    @property
    def duration(self) -> float:
        return float(self.time[-1])

    def time_scaled(self, c: float) -> PathProfile:
        """The same motion slowed uniformly in time by ``c`` (0 < c <= 1): path velocities
        times c, path accelerations times c^2, so joint velocities scale by c and joint
        accelerations by c^2 at every path position."""
        return PathProfile(self.s, self.sd * c, self.time / c, self.sdd * c**2)

    def at_time(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(s, sd, sdd) at times ``t`` (clipped to [0, duration]), each of t's shape: on the
        grid interval ``i`` holding t, ``tau = t - time[i]``, ``s = s[i] + sd[i] tau +
        a tau^2 / 2`` (at most ``s[i + 1]``), ``sd[i] + a tau``, ``a = sdd[i]``."""
        return self._compiled(t, forward=True)

    def at_path(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(time, sd, sdd) at path positions ``s`` (clipped to the grid), each of s's shape:
        on the grid interval ``i`` holding s, ``sd = sqrt(sd[i]^2 + 2 a (s - s[i]))``,
        ``time[i] + 2 (s - s[i]) / (sd + sd[i])``, ``a = sdd[i]``."""
        return self._compiled(s, forward=False)

    def _compiled(self, x: object, *, forward: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`at_time` (``forward``) or :meth:`at_path` in one compiled pass
        (:func:`_profile_at`; the dense re-check reads thousands of positions, several
        times a timing)."""
        if self.sdd.shape[0] == 0:
            raise IndexError("a profile of one grid point has no interval to read")
        arr = np.asarray(x, dtype=float)
        flat = np.ascontiguousarray(arr.ravel())
        out = np.empty((3, flat.shape[0]))
        ro = _kernels.read_only
        grid = (ro(self.s), ro(self.sd), ro(self.time), ro(self.sdd))
        _profile_at(ro(flat), *grid, forward, out)
        if arr.ndim == 0:
            return out[0, 0], out[1, 0], out[2, 0]
        return out[0].reshape(arr.shape), out[1].reshape(arr.shape), out[2].reshape(arr.shape)


@njit(cache=True, nogil=True, error_model="numpy")
def _profile_at(x, s, sd, time, sdd, forward, out):  # pragma: no cover - compiled
    """:meth:`PathProfile.at_time` (``forward``: x are times) or :meth:`PathProfile.at_path`
    (x are path positions) into ``out`` (3, M), by :func:`read_at_time` and
    :func:`read_at_path`."""
    hint = 0
    for m in range(x.shape[0]):
        if forward:
            out[0, m], out[1, m], out[2, m], hint = read_at_time(x[m], s, sd, time, sdd, hint)
        else:
            out[0, m], out[1, m], out[2, m], hint = read_at_path(x[m], s, sd, time, sdd, hint)


@njit(cache=True, nogil=True, error_model="numpy")
def read_at_time(v, s, sd, time, sdd, hint):  # pragma: no cover - compiled
    """(s, sd, sdd) of the profile (its arrays) at the time v, as :meth:`PathProfile.at_time`
    reads them, and the grid count found (the next read's ``hint``,
    :func:`planner._kernels.count_at_most_from`): the interval ``i`` of v clipped to
    [0, duration] as ``np.searchsorted(time, v, "right") - 1`` clipped to the intervals,
    then its formulas in the order numpy evaluated them (the same values bit for bit, NaN
    kept NaN; ``tests/timing/test_timing_toppra.py``)."""
    v = _clipped(v, 0.0, time[-1])
    count = _kernels.count_at_most_from(time, v, hint)
    i = min(max(count - 1, 0), sdd.shape[0] - 1)
    tau = v - time[i]
    a = sdd[i]
    pos = s[i] + sd[i] * tau + 0.5 * a * tau**2
    if pos > s[i + 1]:
        pos = s[i + 1]
    return pos, sd[i] + a * tau, a, count


@njit(cache=True, nogil=True, error_model="numpy")
def read_at_path(v, s, sd, time, sdd, hint):  # pragma: no cover - compiled
    """(time, sd, sdd) of the profile (its arrays) at the path position v, as
    :meth:`PathProfile.at_path` reads them, and the grid count (see :func:`read_at_time`)."""
    v = _clipped(v, s[0], s[-1])
    count = _kernels.count_at_most_from(s, v, hint)
    i = min(max(count - 1, 0), sdd.shape[0] - 1)
    a = sdd[i]
    inner = sd[i] ** 2 + 2 * a * (v - s[i])
    rate = math.sqrt(inner) if not inner < 0.0 else 0.0
    total = rate + sd[i]
    return time[i] + 2 * (v - s[i]) / (total if not total < 1e-300 else 1e-300), rate, a, count


@njit(cache=True, nogil=True)
def _clipped(v, low, high):  # pragma: no cover - compiled
    """``np.clip(v, low, high)`` for a number (NaN stays NaN)."""
    if v < low:
        v = low
    if v > high:
        v = high
    return v


def section_grid(
    path: BlendedPath,
    lo: int,
    hi: int,
    refine: float = 1,
    *,
    arc_junctions: bool = False,
    arc_refine: float = 1,
) -> np.ndarray:
    """Grid points of the pieces ``lo..hi``: every piece boundary, lines cut every
    ``LINE_STEP / refine`` (at least ``LINE_MIN_INTERVALS * refine``), arcs every
    ``ARC_STEP / (refine arc_refine)`` of turning (the profile's loss to the grid comes
    mostly from the blends, where the velocity and acceleration bounds dip and turn).

    ``arc_junctions`` (with torque limits): where two arcs meet, q'' jumps from one arc's to
    the other's, and toppra sees one of them at the junction grid point (the larger, see
    ``_SectionPath``): the torques of the other side were unconstrained there and overshot
    by up to 37 % on the benchmark paths (the joint limits, bounded per |q''|, do not suffer
    it the same way). A short interval (``JUNCTION_INTERVAL`` of each arc) on both sides
    of such a junction puts a grid point on each arc next to it, so both sides are bounded."""
    k = np.arange(lo, hi + 1)
    a, b = path.s0[k], path.s0[k + 1]
    arc = path.kind[k] == ARC
    with np.errstate(divide="ignore", invalid="ignore"):
        turn = np.where(arc, (b - a) / np.where(arc, path.radius[k], 1.0), 0.0)
    n = np.where(
        arc,
        np.maximum(2, np.ceil(turn * refine * arc_refine / ARC_STEP)),
        np.maximum(int(LINE_MIN_INTERVALS * refine), np.ceil((b - a) * refine / LINE_STEP)),
    ).astype(int)
    # every piece's np.linspace(a, b, n + 1)[:-1], as linspace computes it: a + i (b - a) / n
    piece = np.repeat(np.arange(k.shape[0]), n)
    i = np.arange(piece.shape[0]) - np.repeat(np.cumsum(n) - n, n)
    pts = i * ((b - a) / n)[piece] + a[piece]
    # a point JUNCTION_INTERVAL of the piece inside each end that meets an arc of the section
    # (lines; arcs too with arc_junctions), so the arc's side of the junction is bounded
    beside = ~arc | arc_junctions
    before = beside & (k > lo) & (path.kind[np.maximum(k - 1, 0)] == ARC)
    after = beside & (k < hi) & (path.kind[np.minimum(k + 1, path.kind.shape[0] - 1)] == ARC)
    eps = JUNCTION_INTERVAL * (b - a)
    extra = np.concatenate([(a + eps)[before], (b - eps)[after]])
    grid = np.sort(np.concatenate([pts, extra])) if extra.shape[0] else pts
    return np.concatenate([grid, path.s0[hi + 1 : hi + 2]])


def check_deadline(deadline: float | None, what: str) -> None:
    """:class:`TimingDeadlineError` if ``time.monotonic()`` is past ``deadline``."""
    if deadline is not None and time.monotonic() > deadline:
        raise TimingDeadlineError(f"the deadline passed {what}")


def min_blend_radius(limits: JointLimits) -> float:
    """Smallest corner blend worth keeping, rad: below it the path speed through the blend,
    at most ``sqrt(a r)``, gives ``sd^2`` under ``MIN_BLEND_X`` in the solver's normalised
    units (velocity limit 1), near toppra's absolute tolerances; such a corner is a stop."""
    v_min = float(np.min(limits.velocity_array))
    return MIN_BLEND_X * v_min**2 / float(np.min(limits.acceleration_array))


def _straight_rest_to_rest(
    s_start: float, s_end: float, direction: np.ndarray, v: np.ndarray, a: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Exact time-optimal profile of a straight section from rest to rest, as grid points and
    path velocities: a trapezoid (or a triangle) under the path speed bound
    ``min_j v_j / |u_j|`` and path acceleration bound ``min_j a_j / |u_j|``."""
    u = np.abs(direction)
    with np.errstate(divide="ignore"):
        v_s = float(np.min(np.where(u > 0, v / u, np.inf)))
        a_s = float(np.min(np.where(u > 0, a / u, np.inf)))
    length = s_end - s_start
    ramp = v_s**2 / (2 * a_s)
    if 2 * ramp < length:
        grid = np.array([s_start, s_start + ramp, s_end - ramp, s_end])
        return grid, np.array([0.0, v_s, v_s, 0.0])
    peak = np.sqrt(a_s * length)
    return np.array([s_start, s_start + length / 2, s_end]), np.array([0.0, peak, 0.0])


@cached("timing.joint_constraints")
def _joint_constraints(v: tuple[float, ...], a: tuple[float, ...]) -> tuple:
    """toppra's joint velocity and acceleration constraints (cached: their constructors
    format the limits into strings, about 2 ms; the objects hold no path state)."""
    v_arr, a_arr = np.asarray(v), np.asarray(a)
    return (
        toppra.constraint.JointVelocityConstraint(np.stack([-v_arr, v_arr], axis=1)),
        toppra.constraint.JointAccelerationConstraint(np.stack([-a_arr, a_arr], axis=1)),
    )


#: A cache of section profiles (:func:`solve_toppra`'s ``cache``): key -> (grid - s_start, sd).
SectionCache = dict[tuple, tuple[np.ndarray, np.ndarray]]


def section_key(path: BlendedPath, s_start: float, s_end: float) -> tuple:
    """What fixes a rest-to-rest section's geometry, independent of where it lies along the
    path: its vertices (joint values) and their blend deviations (which fix every arc, the
    vertices given). A repair that shrinks a blend
    elsewhere shifts this section's ``s`` but leaves its key, hence its profile, unchanged."""
    at = np.flatnonzero((path.vertex_s >= s_start) & (path.vertex_s <= s_end))
    i0, i1 = int(at[0]), int(at[-1])
    return (
        path.waypoints[i0 : i1 + 1].tobytes(),
        path.blend_deviation[i0 : i1 + 1].tobytes(),
    )


def _shifted_grid(path: BlendedPath, lo: int, hi: int, grid: np.ndarray) -> np.ndarray:
    """A cached section grid moved to where the section now lies, its piece boundaries set
    to the path's own (``path.s0``) exactly, as :func:`section_grid` makes them: a through-state
    on a boundary then takes the same interval's acceleration as after a fresh solve."""
    bounds = path.s0[lo : hi + 2]
    at = np.clip(np.searchsorted(grid, bounds), 1, grid.shape[0] - 1)
    nearer = np.abs(grid[at - 1] - bounds) < np.abs(grid[at] - bounds)
    grid[at - nearer] = bounds
    return grid


def _compiled_profile(
    section: _SectionPath,
    grid: np.ndarray,
    v: np.ndarray,
    a: np.ndarray,
    v_cart: float | None,
    speed_gain: Callable[[np.ndarray], np.ndarray] | None,
) -> np.ndarray | None:
    """toppra's profile of a section without torque limits, from the compiled passes of
    :func:`planner.timing.topp_compiled.topp_profile` on the same constraints (q', q'' as
    :class:`_SectionPath` gives them to toppra, toppra's own velocity bounds, the speed
    bound of :class:`_SpeedAlongPathConstraint`); None when they find no profile (toppra then
    solves it, and says why if it fails too)."""
    d1, d2 = section(grid, 1), section(grid, 2)
    _, _, xb = _create_velocity_constraint(d1, np.stack([-v, v], axis=1))
    xmax = np.minimum(-np.asarray(xb)[:, 0], _X_UNBOUNDED)
    if v_cart is not None and speed_gain is not None:
        xmax = np.minimum(xmax, _SpeedAlongPathConstraint(v_cart, speed_gain).x_upper(grid))
    sd, _ = topp_profile(grid, d1, d2, a, xmax)
    return sd


def _toppra_profile(
    section: _SectionPath,
    grid: np.ndarray,
    joint_constraints: tuple,
    v_cart: float | None,
    speed_gain: Callable[[np.ndarray], np.ndarray] | None,
    torque: _TorqueConstraint | None,
) -> np.ndarray:
    """toppra's own profile of a section (seidel), in the solver's normalised unit."""
    constraints = list(joint_constraints)
    if v_cart is not None and speed_gain is not None:
        constraints.append(_SpeedAlongPathConstraint(v_cart, speed_gain))
    if torque is not None:
        constraints.append(torque)
    instance = toppra.algorithm.TOPPRA(
        constraints, section, gridpoints=grid, solver_wrapper="seidel"
    )
    s_start, s_end = section.path_interval
    try:
        _, sd, _ = instance.compute_parameterization(0.0, 0.0)
    except ZeroDivisionError as exc:  # the seidel LP met a zero constraint row
        raise TimingInfeasibleError(
            f"toppra found no profile for the path section s in [{s_start:.4g}, "
            f"{s_end:.4g}] rad: its LP solver met a degenerate constraint ({exc})"
        ) from exc
    code = instance.problem_data.return_code
    if sd is None or np.any(~np.isfinite(sd)):
        raise TimingInfeasibleError(
            f"toppra found no profile for the path section s in [{s_start:.4g}, "
            f"{s_end:.4g}] rad: {code}"
        )
    return np.asarray(sd, dtype=float)


def solve_toppra(
    path: BlendedPath,
    limits: JointLimits,
    *,
    speed_gain: Callable[[np.ndarray], np.ndarray] | None = None,
    max_cartesian_speed: float | None = None,
    refine: float = 1,
    arc_refine: float = 1,
    deadline: float | None = None,
    torque_model: TorqueModel | None = None,
    cache: SectionCache | None = None,
) -> PathProfile:
    """Time-optimal rest-to-rest profile of every section of ``path``, joined in time.

    Parameters
    ----------
    path : BlendedPath
    limits : JointLimits
        Velocity and acceleration bounds (jerk is ignored).
    speed_gain : callable s (G,) -> |dP/ds| (G,), m/rad, optional
        Needed with ``max_cartesian_speed``.
    max_cartesian_speed : float, m/s, optional
    refine : int
        Grid refinement factor (repairs use 2, 4, ...; below 1 a coarser grid).
    arc_refine : float
        A further refinement of the blends' grid (:func:`section_grid`).
    deadline : float, optional
        ``time.monotonic()`` value checked before each section.
    torque_model : TorqueModel, optional
        With ``limits.torque``: the actuator torques bounded too (a second-order constraint).
    cache : dict, optional
        Profiles of sections already solved (filled here): a section whose key
        (:func:`section_key`: its vertices and blends, and these settings) is in it is not
        solved again but shifted to where it lies. :func:`planner.timing.time_path` passes
        one per call, so that a repair round re-solves only the sections its repair changed
        (the rounds' work is then linear in the waypoints, not rounds x waypoints). Only
        valid for one ``speed_gain`` (one design and assembly mode).

    Raises
    ------
    TimingInfeasibleError
        toppra reports a failure (uncontrollable instance, numerical failure).
    TimingDeadlineError
        ``deadline`` passed.
    """
    # Solve in a normalised time unit where the slowest joint's velocity limit is 1: toppra's
    # tolerances are absolute (1e-5 on sd^2), and slowing a profile by c scales velocities by
    # c and accelerations by c^2, so the solution in real time is sd / c.
    c = 1.0 / float(np.min(limits.velocity_array))
    v = limits.velocity_array * c
    a = limits.acceleration_array * c**2
    v_cart = None if max_cartesian_speed is None else max_cartesian_speed * c
    joint_constraints = _joint_constraints(tuple(v.tolist()), tuple(a.tolist()))
    torque = None
    tau_max = limits.torque_array
    if torque_model is not None and tau_max is not None:
        torque = _TorqueConstraint(torque_model, tau_max, c)
    s_all, sd_all = [np.zeros(1)], [np.zeros(1)]
    for s_start, s_end in zip(path.stops[:-1], path.stops[1:], strict=True):
        check_deadline(deadline, "while timing the path with toppra")
        if s_end - s_start <= 0.0:
            continue
        section = _SectionPath(path, float(s_start), float(s_end))
        lo, hi = section.pieces
        if lo == hi and path.kind[lo] != ARC and v_cart is None and torque is None:
            grid, sd = _straight_rest_to_rest(
                float(s_start), float(s_end), path.direction[lo], v, a
            )
            s_all.append(grid[1:])
            sd_all.append(sd[1:] / c)
            continue
        key = None
        if cache is not None:
            settings = (refine, arc_refine, *v.tolist(), *a.tolist(), v_cart)
            key = (section_key(path, float(s_start), float(s_end)), settings)
            hit = cache.get(key)
            if hit is not None:
                grid = _shifted_grid(path, lo, hi, float(s_start) + hit[0])
                s_all.append(grid[1:])
                sd_all.append(hit[1][1:])
                continue
        grid = section_grid(
            path, lo, hi, refine=refine, arc_junctions=torque is not None, arc_refine=arc_refine
        )
        section_sd = (
            None
            if torque is not None
            else _compiled_profile(section, grid, v, a, v_cart, speed_gain)
        )
        if section_sd is None:
            section_sd = _toppra_profile(
                section, grid, joint_constraints, v_cart, speed_gain, torque
            )
        sd = section_sd / c
        sd[0] = sd[-1] = 0.0
        if cache is not None and key is not None:
            cache[key] = (grid - float(s_start), sd)
        s_all.append(grid[1:])
        sd_all.append(sd[1:])
    s = np.concatenate(s_all)
    sd = np.concatenate(sd_all)
    if s.shape[0] == 1:  # a path of zero length
        s, sd = np.zeros(2), np.zeros(2)
    return PathProfile.from_grid(s, sd)
