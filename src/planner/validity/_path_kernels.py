"""The compiled kernels over a whole waypoint path (numba): its certificate
(:func:`certify_path`, every motion by :func:`planner.validity._certificate.certify_motion`) and
its diagnostics (:func:`path_extremes`). Private, as :mod:`planner.validity._kernels`, whose
per-posture kernels they call (inlined: after editing one of those, touch this file so that
numba's cache, keyed on this file, compiles these again).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from planner.validity._certificate import certify_motion
from planner.validity._kernels import (
    M_AXIS,
    M_CLEAR_RAW,
    M_DMARGIN,
    M_KAPPA,
    M_SERIAL_RAW,
    N_MEASURES,
    evaluate_bounded,
    rates,
    rates_at,
    sin_apex_min,
)

__all__ = ["EXTREMES_STRIDE", "certify_path", "path_extremes"]


@njit(cache=True)
def certify_path(
    q,
    prm,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    coarse_step,
    min_step,
    reasons,
    ts,
):  # pragma: no cover
    """Certify every motion of a waypoint path (N, 3); stops at the first broken motion."""
    for i in range(q.shape[0] - 1):
        r, t = certify_motion(
            q[i],
            q[i + 1],
            prm,
            spheres,
            capsules,
            boxes,
            sphere_nodes,
            capsule_nodes,
            box_nodes,
            sphere_grid,
            coarse_step,
            min_step,
            False,
        )
        reasons[i] = r
        ts[i] = t
        if r != 0:
            return i
    return -1


#: Every how many samples of a motion :func:`path_extremes` measures first.
EXTREMES_STRIDE = 16
#: How many samples ahead a sample measured in :func:`path_extremes`'s second pass is
#: measured for (its clearance exact up to the running minimum plus the rate bound over
#: them). Measured on the fair scenes' plans (``benchmarks/planning.py --fair``, 40 each,
#: CPU p50 of the kernel, ms; without the skip / ahead 1 / 2 / 4 / 8): 10k-point cloud
#: 0.639 / 0.604 / 0.474 / 0.461 / 0.505, 100k 0.820 / 0.797 / 0.687 / 0.663 / 0.690, 1,000
#: spheres 0.119 / 0.169 / 0.140 / 0.149 / 0.150, narrow window 0.146 / 0.154 / 0.145 /
#: 0.147 / 0.150.
EXTREMES_AHEAD = 4
#: Least lead (m) of a clearance bound over the running minimum for :func:`path_extremes`
#: to skip a sample's clearance: far above the rounding of a measured clearance.
_SKIP_LEAD = 1e-9


@njit(cache=True)
def path_extremes(
    q, step, prm, spheres, capsules, boxes, sphere_nodes, capsule_nodes, box_nodes, sphere_grid, out
):  # pragma: no cover
    """(min clearance, max kappa_A, min signed serial) over the waypoints of q (N, 3) and
    samples every ``step`` rad (max-norm) on the motions between them, into out (3,); NaN
    when no sample closes the loop.

    The samples are visited in two passes, every :data:`EXTREMES_STRIDE`-th of each motion
    (and its end: the anchors) first, the others then: the extremes are the same over the
    same samples in any order, but the running minimum of the clearance, below which alone
    an obstacle is measured exactly, falls near its final value early, so the obstacle trees
    are walked within a smaller reach at most samples (among 100k points the exact clearance
    is most of a straight plan's time). In the second pass a sample's clearance is not
    measured at all where the certificate's Lipschitz bound (:func:`rates_at`, with the
    apex sine bounded from the anchors' d-margins as :func:`certify_motion` does) keeps it
    above the running minimum from the nearest measured samples on either side: it could not
    lower the minimum, so the extremes are those of every sample, to the bit; its kappa and
    serial measures are taken as before."""
    nq = q.shape[0]
    ns = np.ones(nq, dtype=np.int64)  # samples of motion i (ending at waypoint i); 1 at i = 0
    n_anchors = 1
    for i in range(1, nq):
        length = 0.0
        for j in range(3):
            length = max(length, abs(q[i, j] - q[i - 1, j]))
        ns[i] = max(1, math.ceil(length / step))
        n_anchors += (ns[i] + EXTREMES_STRIDE - 1) // EXTREMES_STRIDE
    anchors = np.empty((n_anchors, 3))  # (d-margin, clearance lower bound, axis), path order
    m = np.empty(N_MEASURES)
    ext = np.array([np.inf, -np.inf, np.inf, 0.0])  # running extremes; [3]: a loop closed
    a = 0
    for i in range(nq):
        n = ns[i]
        for k in range(1, n + 1):
            if k % EXTREMES_STRIDE == 0 or k == n:
                _extremes_sample(
                    q,
                    i,
                    k,
                    n,
                    prm,
                    spheres,
                    capsules,
                    boxes,
                    sphere_nodes,
                    capsule_nodes,
                    box_nodes,
                    sphere_grid,
                    ext[0],
                    m,
                    ext,
                )
                anchors[a, 0], anchors[a, 1], anchors[a, 2] = (
                    m[M_DMARGIN],
                    m[M_CLEAR_RAW],
                    m[M_AXIS],
                )
                a += 1
    a = 0  # the anchor at the start of the piece
    for i in range(1, nq):
        n = ns[i]
        dq0, dq1, dq2 = q[i, 0] - q[i - 1, 0], q[i, 1] - q[i - 1, 1], q[i, 2] - q[i - 1, 2]
        rate_cd = rates(dq0, dq1, dq2, prm)[0]
        ka = 0
        while ka < n:
            kb = min(ka + EXTREMES_STRIDE, n)
            lb_cd = 0.5 * (anchors[a, 0] + anchors[a + 1, 0] - rate_cd * (kb - ka) / n)
            rate = np.inf  # no bound on the clearance's rate: every sample measured
            if lb_cd >= 0.0:
                s_min = sin_apex_min(prm, lb_cd)
                w = (kb - ka) / n
                rate = rates_at(dq0, dq1, dq2, prm, s_min, anchors[a, 2], anchors[a + 1, 2], w)[2]
                rate /= n
            kl, cl, cb = ka, anchors[a, 1], anchors[a + 1, 1]
            for k in range(ka + 1, kb):
                bound = max(cl - rate * (k - kl), cb - rate * (kb - k))
                skip = bound > ext[0] + _SKIP_LEAD
                # measured exactly up to what lets the next EXTREMES_AHEAD samples be
                # skipped (a bound that only says ">= the minimum" lets nothing be skipped;
                # a farther reach walks many more obstacles)
                upper = -np.inf if skip else ext[0]
                if not skip and rate < np.inf:
                    upper = ext[0] + rate * min(kb - k, EXTREMES_AHEAD)
                _extremes_sample(
                    q,
                    i,
                    k,
                    n,
                    prm,
                    spheres,
                    capsules,
                    boxes,
                    sphere_nodes,
                    capsule_nodes,
                    box_nodes,
                    sphere_grid,
                    upper,
                    m,
                    ext,
                )
                if not skip:
                    kl, cl = k, m[M_CLEAR_RAW]
            a += 1
            ka = kb
    if ext[3] == 0.0:
        out[0] = out[1] = out[2] = np.nan
    else:
        out[0], out[1], out[2] = ext[0], ext[1], ext[2]


@njit(cache=True, inline="always")
def _extremes_sample(
    q,
    i,
    k,
    n,
    prm,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    clear_upper,
    m,
    ext,
):  # pragma: no cover - compiled
    """One sample of :func:`path_extremes`: posture k / n of motion i (waypoint 0 for i = 0)
    measured into m with the clearance exact below ``clear_upper`` (-inf: not measured),
    folded into the running extremes ``ext``."""
    if i == 0:
        a0, a1, a2 = q[0, 0], q[0, 1], q[0, 2]
    else:
        t = k / n
        a0 = q[i - 1, 0] + t * (q[i, 0] - q[i - 1, 0])
        a1 = q[i - 1, 1] + t * (q[i, 1] - q[i - 1, 1])
        a2 = q[i - 1, 2] + t * (q[i, 2] - q[i - 1, 2])
    evaluate_bounded(
        a0,
        a1,
        a2,
        prm,
        spheres,
        capsules,
        boxes,
        sphere_nodes,
        capsule_nodes,
        box_nodes,
        sphere_grid,
        True,
        clear_upper,
        m,
    )
    if m[M_KAPPA] > -np.inf:
        ext[3] = 1.0
        if clear_upper > -np.inf:
            ext[0] = min(ext[0], m[M_CLEAR_RAW])
        ext[1] = max(ext[1], m[M_KAPPA])
        ext[2] = min(ext[2], m[M_SERIAL_RAW])
