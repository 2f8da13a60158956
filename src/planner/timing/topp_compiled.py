"""TOPP-RA's two passes, compiled: the same discretised problem as toppra's seidel solver for
joint velocity and acceleration limits and a bound on ``sd^2`` (the speed of P), without a
Python call per grid point.

toppra (Pham and Pham 2018, "A new approach to time-optimal path parameterization based on
reachability analysis") solves, on a grid ``s_0 < ... < s_N`` with ``x_i = sd(s_i)^2`` and a
constant path acceleration ``u_i`` on each interval (``x_{i+1} = x_i + 2 d_i u_i``,
``d_i = s_{i+1} - s_i``):

* the backward pass: the controllable sets ``K_N = {x_end}``, ``K_i`` = the ``x_i`` in the
  stage's bounds from which some admissible ``u_i`` reaches ``K_{i+1}``;
* the forward pass from ``x_0``: the largest admissible ``u_i`` that stays in ``K_{i+1}``.

The joint acceleration ``q'(s) u + q''(s) x`` is bounded at both ends of every interval
(toppra's default *interpolation* scheme: at ``s_{i+1}`` with ``x_{i+1} = x_i + 2 d_i u_i``),
the joint velocities and the speed bound give ``x_i <= xmax_i``. Each stage is then a linear
program in two variables ``(u, x)`` with a dozen constraints; toppra solves it with Seidel's
algorithm, here it is solved exactly by eliminating ``u`` (Fourier-Motzkin): every constraint
``lo <= p u + r x <= hi`` with ``p != 0`` bounds ``u`` below and above by affine functions of
``x``, a ``u`` exists where every lower bound is at most every upper bound, and each such pair
is one linear inequality in ``x``. The forward pass takes the least upper bound at the given
``x``. toppra's numerical guards are kept as they are (``TINY`` off each forward step, the
retries with ``x`` reduced, ``SMALL`` on the start), so the profile equals toppra's to its
solver's round-off (``tests/timing/test_topp_compiled.py`` compares them on random paths).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["topp_profile"]

#: toppra's constants (``toppra.constants``): the forward step's margin, the start's tolerance
#: and the retries of a forward step that meets round-off.
TINY = 1e-8
SMALL = 1e-5
MAX_TRIES = 10
#: Relative slack under which an empty stage (lower end above upper end by round-off) is a
#: point, not a failure.
_FEAS_RTOL = 1e-12


@njit(cache=True)
def _stage_rows(i, a, b, acc, d, k_lo, k_hi, p, r, lo, hi):  # pragma: no cover
    """The constraint rows ``lo <= p u + r x <= hi`` of stage ``i`` into p, r, lo, hi (7 per
    joint count: the acceleration at s_i and at s_{i+1}, then the reach of K_{i+1});
    returns the row count."""
    n = 0
    two_d = 2.0 * d[i]
    for j in range(a.shape[1]):
        p[n], r[n], lo[n], hi[n] = a[i, j], b[i, j], -acc[j], acc[j]
        n += 1
        p[n] = a[i + 1, j] + two_d * b[i + 1, j]
        r[n], lo[n], hi[n] = b[i + 1, j], -acc[j], acc[j]
        n += 1
    p[n], r[n], lo[n], hi[n] = two_d, 1.0, k_lo, k_hi
    return n + 1


@njit(cache=True)
def _x_interval(n, p, r, lo, hi, x_lo, x_hi):  # pragma: no cover
    """The ``x`` in [x_lo, x_hi] for which some ``u`` meets the ``n`` rows: (lo, hi), NaN
    when there is none."""
    for k in range(n):  # rows without u bound x alone
        if p[k] == 0.0:
            if r[k] > 0.0:
                x_lo, x_hi = max(x_lo, lo[k] / r[k]), min(x_hi, hi[k] / r[k])
            elif r[k] < 0.0:
                x_lo, x_hi = max(x_lo, hi[k] / r[k]), min(x_hi, lo[k] / r[k])
            elif lo[k] > 0.0 or hi[k] < 0.0:
                return np.nan, np.nan
    for k in range(n):  # lower bound of u from row k: al + be x
        if p[k] == 0.0:
            continue
        al = (lo[k] if p[k] > 0.0 else hi[k]) / p[k]
        be = -r[k] / p[k]
        for m in range(n):  # upper bound of u from row m: ga + de x
            if p[m] == 0.0:
                continue
            ga = (hi[m] if p[m] > 0.0 else lo[m]) / p[m]
            de = -r[m] / p[m]
            c, rhs = be - de, ga - al  # al + be x <= ga + de x  <=>  c x <= rhs
            if c > 0.0:
                x_hi = min(x_hi, rhs / c)
            elif c < 0.0:
                x_lo = max(x_lo, rhs / c)
            elif rhs < 0.0:
                return np.nan, np.nan
    if x_lo > x_hi:
        if x_lo - x_hi > _FEAS_RTOL * max(1.0, abs(x_hi)):
            return np.nan, np.nan
        x_lo = x_hi
    return x_lo, x_hi


@njit(cache=True)
def _u_max(n, p, r, lo, hi, x):  # pragma: no cover
    """The largest ``u`` meeting the ``n`` rows at ``x``, NaN when none does."""
    u_lo, u_hi = -np.inf, np.inf
    for k in range(n):
        v_lo, v_hi = lo[k] - r[k] * x, hi[k] - r[k] * x
        if p[k] > 0.0:
            u_lo, u_hi = max(u_lo, v_lo / p[k]), min(u_hi, v_hi / p[k])
        elif p[k] < 0.0:
            u_lo, u_hi = max(u_lo, v_hi / p[k]), min(u_hi, v_lo / p[k])
        elif v_lo > _FEAS_RTOL * max(1.0, abs(lo[k])) or v_hi < -_FEAS_RTOL * max(1.0, abs(hi[k])):
            return np.nan
    if u_lo > u_hi + _FEAS_RTOL * max(1.0, abs(u_hi)):
        return np.nan
    return u_hi


@njit(cache=True)
def _passes(s, a, b, acc, xmax, x_start, x_end, xs):  # pragma: no cover
    """Both passes into xs (N + 1,); 0 on success, 1 uncontrollable (the backward pass),
    2 the start not controllable, 3 the forward pass failed."""
    n_grid = s.shape[0]
    d = s[1:] - s[:-1]
    k_lo = np.empty(n_grid)
    k_hi = np.empty(n_grid)
    k_lo[-1] = k_hi[-1] = x_end
    rows = 2 * a.shape[1] + 1
    p, r, lo, hi = np.empty(rows), np.empty(rows), np.empty(rows), np.empty(rows)
    for i in range(n_grid - 2, -1, -1):
        n = _stage_rows(i, a, b, acc, d, k_lo[i + 1], k_hi[i + 1], p, r, lo, hi)
        x_lo, x_hi = _x_interval(n, p, r, lo, hi, 0.0, xmax[i])
        if np.isnan(x_lo):
            return 1
        k_lo[i], k_hi[i] = max(x_lo, 0.0), x_hi
    if x_start + SMALL < k_lo[0] or k_hi[0] + SMALL < x_start:
        return 2
    xs[0] = x_start
    tries = 0
    i = 0
    while i < n_grid - 1:
        n = _stage_rows(i, a, b, acc, d, k_lo[i + 1], k_hi[i + 1], p, r, lo, hi)
        u = _u_max(n, p, r, lo, hi, xs[i])
        if np.isnan(u):
            if tries >= MAX_TRIES:
                return 3
            xs[i] = max(xs[i] - TINY, 0.999 * xs[i])
            tries += 1
            continue
        tries = 0
        x_next = xs[i] + 2.0 * d[i] * u
        x_next = max(x_next - TINY, 0.9999 * x_next)
        xs[i + 1] = min(k_hi[i + 1], max(k_lo[i + 1], x_next))
        i += 1
    return 0


def topp_profile(
    s: np.ndarray,
    d1: np.ndarray,
    d2: np.ndarray,
    acc: np.ndarray,
    xmax: np.ndarray,
    sd_start: float = 0.0,
    sd_end: float = 0.0,
) -> tuple[np.ndarray | None, int]:
    """The time-optimal path velocities ``sd`` (G,) on the grid ``s`` (G,), or None, and a
    code (0 solved; 1 uncontrollable, 2 start not controllable, 3 forward pass failed).

    Parameters
    ----------
    s : shape (G,), increasing grid.
    d1, d2 : shape (G, J) -- q'(s) and q''(s) at the grid points (as the solver sees them).
    acc : shape (J,) -- symmetric joint acceleration limits.
    xmax : shape (G,) -- upper bound on ``sd^2`` at each grid point (velocity limits, speed
        bound), finite.
    sd_start, sd_end : path velocities at the ends.
    """
    s = np.ascontiguousarray(s, dtype=float)
    xs = np.empty(s.shape[0])
    code = _passes(
        s,
        np.ascontiguousarray(d1, dtype=float),
        np.ascontiguousarray(d2, dtype=float),
        np.ascontiguousarray(acc, dtype=float),
        np.ascontiguousarray(xmax, dtype=float),
        float(sd_start) ** 2,
        float(sd_end) ** 2,
        xs,
    )
    if code != 0 or not np.all(np.isfinite(xs)):
        return None, code or 3
    return np.sqrt(np.maximum(xs, 0.0)), 0
