"""The compiled motion certificate (numba): a straight motion's postures all valid, proved
from measures at samples and Lipschitz bounds between them.

Private, as :mod:`planner.validity._kernels` (whose per-posture measures, layout ``M_*``, and
rates it uses): :func:`certify_motion` is what
:meth:`planner.validity.ValidityChecker.check_motion` runs (the proof is in its docstring);
:func:`certify_between` and :func:`certify_extension` are its variants for compiled loops
that already hold an end's measures (a search's tree nodes, a path's vertices). numba's cache
of these kernels is keyed on this file only: after editing a kernel of
:mod:`planner.validity._kernels` that they call, clear the cache (``__pycache__/*.nbi``,
``*.nbc``) or touch this file.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from planner.validity._kernels import (
    _KEPT,
    M_DMARGIN,
    M_REASON,
    N_MEASURES,
    R_CLEAR,
    R_KAPPA,
    R_SERIAL,
    evaluate,
    rates,
    rates_at,
    sin_apex_min,
)

__all__ = [
    "blocked_near",
    "certify_between",
    "certify_extension",
    "certify_motion",
    "measure_posture",
]


@njit(cache=True)
def certify_motion(
    qa,
    qb,
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
    skip_ends,
):  # pragma: no cover
    """Certify the straight motion qa -> qb. Returns (reason, t): reason 0 when every posture
    of the motion is valid, else the rule found broken (or not certifiable) near parameter t.
    Algorithm and proof: :meth:`ValidityChecker.check_motion`. Steps: :func:`_measure_ends`,
    the coarse samples and the pieces (:func:`_certify_samples`)."""
    ms, done = _samples(qa, qb, coarse_step)
    if skip_ends:
        _measure_ends(
            qa,
            qb,
            prm,
            spheres,
            capsules,
            boxes,
            sphere_nodes,
            capsule_nodes,
            box_nodes,
            sphere_grid,
            ms,
            done,
        )
    return _certify_samples(
        qa,
        qb,
        prm,
        spheres,
        capsules,
        boxes,
        sphere_nodes,
        capsule_nodes,
        box_nodes,
        sphere_grid,
        ms,
        done,
        min_step,
    )


@njit(cache=True)
def certify_between(
    qa,
    qb,
    ma,
    mb,
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
):  # pragma: no cover
    """:func:`certify_motion` (without ``skip_ends``) of the motion qa -> qb whose ends'
    measures ``ma`` and ``mb`` (layout ``M_*``, :func:`measure_posture` with this ``prm``)
    the caller has: a search's tree node and the new posture it has just evaluated, a path's
    vertices tried against several others. The verdict is certify_motion's; its (reason, t)
    can name another broken rule where several are, and qb's measures are its own, not those
    of its rounded copy qa + (qb - qa). Saves the ends' two evaluations per motion."""
    if ma[M_REASON] != 0.0:
        return int(ma[M_REASON]), 0.0
    if mb[M_REASON] != 0.0:
        return int(mb[M_REASON]), 1.0
    ms, done = _samples(qa, qb, coarse_step)
    n = ms.shape[0] - 1
    for k in range(N_MEASURES):
        ms[0, k] = ma[k]
        ms[n, k] = mb[k]
    done[0] = True
    done[n] = True
    return _certify_samples(
        qa,
        qb,
        prm,
        spheres,
        capsules,
        boxes,
        sphere_nodes,
        capsule_nodes,
        box_nodes,
        sphere_grid,
        ms,
        done,
        min_step,
    )


@njit(cache=True)
def measure_posture(
    q,
    prm,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    out,
):  # pragma: no cover
    """The measures (layout ``M_*``) of posture q (3,) into ``out`` as the certificate takes
    them (:func:`evaluate`, not ``full``): an end of :func:`certify_between`."""
    evaluate(
        q[0],
        q[1],
        q[2],
        prm,
        spheres,
        capsules,
        boxes,
        sphere_nodes,
        capsule_nodes,
        box_nodes,
        sphere_grid,
        False,
        out,
    )


@njit(cache=True)
def blocked_near(
    qa,
    qb,
    hint,
    prm,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    out,
):  # pragma: no cover
    """Whether the posture of the motion qa -> qb nearest to ``hint`` (3,) (Euclidean, in
    joint space) breaks a rule, measured into ``out`` (layout ``M_*``); False where that
    posture is an end (measured by the caller) or the motion has no length. True means the
    motion's certificate would refuse it (a motion with an invalid posture is never
    certified), so a caller can skip the certificate: a loop that tries many motions from
    or to one posture (a path's reduction, a remembered path's joins) gives ``hint`` the
    posture where the last one broke a rule, and in clutter the next one is mostly stopped
    by the same obstacle, which this one evaluation finds where the certificate's samples
    in bisection order take several."""
    d0, d1, d2 = qb[0] - qa[0], qb[1] - qa[1], qb[2] - qa[2]
    dd = d0 * d0 + d1 * d1 + d2 * d2
    if dd <= 0.0:
        return False
    t = ((hint[0] - qa[0]) * d0 + (hint[1] - qa[1]) * d1 + (hint[2] - qa[2]) * d2) / dd
    if not (0.0 < t < 1.0):
        return False
    evaluate(
        qa[0] + t * d0,
        qa[1] + t * d1,
        qa[2] + t * d2,
        prm,
        spheres,
        capsules,
        boxes,
        sphere_nodes,
        capsule_nodes,
        box_nodes,
        sphere_grid,
        False,
        out,
    )
    return out[M_REASON] != 0.0


@njit(cache=True, inline="always")
def _samples(qa, qb, coarse_step):  # pragma: no cover - compiled
    """The rows of measures (one per coarse sample, ends included) of the motion qa -> qb
    and their flags (measured yet)."""
    length = max(abs(qb[0] - qa[0]), max(abs(qb[1] - qa[1]), abs(qb[2] - qa[2])))
    n = max(1, math.ceil(length / coarse_step))
    return np.empty((n + 1, N_MEASURES)), np.zeros(n + 1, dtype=np.bool_)


# The coarse samples and the certification of the pieces are inlined into certify_motion and
# certify_between: as a function called once per motion they cost it 2-5 % of its time
# (measured in a compiled loop over 3000 motions, issue 38).
@njit(cache=True, inline="always")
def _certify_samples(
    qa,
    qb,
    prm,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    ms,
    done,
    min_step,
):  # pragma: no cover
    """The coarse samples (``ms`` rows not yet ``done``) in bisection order, then the pieces
    on a stack (:func:`_push_piece`), halved until certified: :func:`certify_motion`'s
    verdict (reason, t)."""
    dq0, dq1, dq2 = qb[0] - qa[0], qb[1] - qa[1], qb[2] - qa[2]
    length = max(abs(dq0), max(abs(dq1), abs(dq2)))
    n = ms.shape[0] - 1
    # coarse samples, in bisection order so an obstacle in the middle is met early
    stride = 1
    while stride < n:
        stride *= 2
    while stride >= 1:
        for k in range(0, n + 1, stride):
            if done[k]:
                continue
            done[k] = True
            t = k / n
            evaluate(
                qa[0] + t * dq0,
                qa[1] + t * dq1,
                qa[2] + t * dq2,
                prm,
                spheres,
                capsules,
                boxes,
                sphere_nodes,
                capsule_nodes,
                box_nodes,
                sphere_grid,
                False,
                ms[k],
            )
            if ms[k, M_REASON] != 0.0:
                return int(ms[k, M_REASON]), t
        stride //= 2
    rate_cd = rates(dq0, dq1, dq2, prm)[0]
    tiny = min_step / max(length, 1e-300)
    # depth-first certification with an explicit stack of intervals
    cap = n + 128
    st_t = np.empty((cap, 2))
    # per end (_KEPT): d-margin, serial margin, clearance margin, axis, distal clearance margin
    st_m = np.empty((cap, 2, _KEPT))
    top = 0
    k0, k1 = M_DMARGIN, M_DMARGIN + _KEPT
    for k in range(n):
        top = _push_piece(st_t, st_m, top, k / n, (k + 1) / n, ms[k, k0:k1], ms[k + 1, k0:k1])
    mid = np.empty(N_MEASURES)
    while top > 0:
        top -= 1
        ta, tb = st_t[top, 0], st_t[top, 1]
        w = tb - ta
        lb_cd, lb_se, lb_cl = _piece_bounds(dq0, dq1, dq2, prm, rate_cd, st_m[top], w)
        if lb_cd >= 0.0 and lb_se >= 0.0 and lb_cl >= 0.0:
            continue
        tm = 0.5 * (ta + tb)
        if w <= tiny or top + 2 > cap:
            if lb_cd < 0.0:
                return R_KAPPA, tm
            if lb_se < 0.0:
                return R_SERIAL, tm
            return R_CLEAR, tm
        evaluate(
            qa[0] + tm * dq0,
            qa[1] + tm * dq1,
            qa[2] + tm * dq2,
            prm,
            spheres,
            capsules,
            boxes,
            sphere_nodes,
            capsule_nodes,
            box_nodes,
            sphere_grid,
            False,
            mid,
        )
        if mid[M_REASON] != 0.0:
            return int(mid[M_REASON]), tm
        ma = st_m[top, 0].copy()
        mb = st_m[top, 1].copy()
        top = _push_piece(st_t, st_m, top, ta, tm, ma, mid[k0:k1])
        top = _push_piece(st_t, st_m, top, tm, tb, mid[k0:k1], mb)
    return 0, 1.0


@njit(cache=True)
def certify_extension(
    qa,
    qb,
    ma,
    mb,
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
):  # pragma: no cover
    """:func:`certify_motion`'s verdict (0: certified, else a broken rule's code) on the
    motion qa -> qb of a search's extension (a tree's node qa, its measures ``ma`` kept by
    the tree, to a new posture qb, whose measures go into ``mb`` for the tree to keep), with
    qb itself evaluated first: in clutter almost every rejected extension ends in an
    invalid posture (measured on ``benchmarks/planning.py``'s fair scenes, 40 queries each:
    14,033 of 14,474 rejected extensions among 1,000 spheres, 12,550 of 12,951 in the narrow
    window), which one evaluation finds where the motion's samples in bisection order (the
    end last but for a power of two) take several. A valid qb is then certified with the
    motion by :func:`certify_between`, neither end evaluated again."""
    measure_posture(
        qb,
        prm,
        spheres,
        capsules,
        boxes,
        sphere_nodes,
        capsule_nodes,
        box_nodes,
        sphere_grid,
        mb,
    )
    if mb[M_REASON] != 0.0:
        return int(mb[M_REASON])
    return certify_between(
        qa,
        qb,
        ma,
        mb,
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
    )[0]


@njit(cache=True, inline="always")
def _piece_bounds(dq0, dq1, dq2, prm, rate_cd, ends, w):  # pragma: no cover - compiled
    """The lower bounds (d-margin, serial margin, clearance margin) of :func:`certify_motion`
    on a piece of width w, ``ends`` (2, _KEPT) the measures kept at its ends (inlined: no
    call per piece). The margin's rates hold only while |CD| stays in its band: with the
    d-margin's bound negative the others are -inf."""
    lb_cd = 0.5 * (ends[0, 0] + ends[1, 0] - rate_cd * w)
    if lb_cd < 0.0:
        return lb_cd, -np.inf, -np.inf
    # |CD| stays lb_cd inside its band on the piece: a local bound on the apex sine
    s_min = sin_apex_min(prm, lb_cd)
    _, rate_serial, rate_clear, rate_prox = rates_at(
        dq0, dq1, dq2, prm, s_min, ends[0, 3], ends[1, 3], w
    )
    lb_se = 0.5 * (ends[0, 1] + ends[1, 1] - rate_serial * w)
    # the clearance per link group: the distal links' margin with every link's rate, and the
    # least margin (a lower bound of the proximal links') with the proximal links' rate
    lb_cl = min(
        0.5 * (ends[0, 4] + ends[1, 4] - rate_clear * w),
        0.5 * (ends[0, 2] + ends[1, 2] - rate_prox * w),
    )
    return lb_cd, lb_se, lb_cl


@njit(cache=True, inline="always")
def _push_piece(st_t, st_m, top, ta, tb, m_a, m_b):  # pragma: no cover - compiled
    """Push the piece [ta, tb] with the measures kept (_KEPT,) at its ends on the stack of
    :func:`certify_motion`; returns the new top."""
    st_t[top, 0], st_t[top, 1] = ta, tb
    for j in range(_KEPT):
        st_m[top, 0, j] = m_a[j]
        st_m[top, 1, j] = m_b[j]
    return top + 1


@njit(cache=True)
def _measure_ends(
    qa,
    qb,
    prm,
    spheres,
    capsules,
    boxes,
    sphere_nodes,
    capsule_nodes,
    box_nodes,
    sphere_grid,
    ms,
    done,
):  # pragma: no cover
    """The ends of :func:`certify_motion` when the caller has checked them: measured in full
    into the first and last rows of ``ms``, taken as valid and marked ``done``."""
    n = ms.shape[0] - 1
    evaluate(
        qa[0],
        qa[1],
        qa[2],
        prm,
        spheres,
        capsules,
        boxes,
        sphere_nodes,
        capsule_nodes,
        box_nodes,
        sphere_grid,
        True,
        ms[0],
    )
    evaluate(
        qb[0],
        qb[1],
        qb[2],
        prm,
        spheres,
        capsules,
        boxes,
        sphere_nodes,
        capsule_nodes,
        box_nodes,
        sphere_grid,
        True,
        ms[n],
    )
    ms[0, M_REASON] = 0.0
    ms[n, M_REASON] = 0.0
    done[0] = True
    done[n] = True
