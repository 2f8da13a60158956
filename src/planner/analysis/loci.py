"""Singularity loci and isoconditioning curves, computed as curves (not grid cells).

Every locus is a set of postures traced along a parameter, built from circle intersections in
the linkage plane, and carries its joints, passive angles, the point P and the mode signs of
each posture, so it can be drawn in joint space (theta2, theta3) or in the plane (u, w).

Geometry used (``docs/conventions.md``): the triangle C-P-D is isosceles (|CP| = |DP| = L2), so
``|CD| = 2 L2 |sin(delta / 2)|`` with ``delta = theta4 - theta5``, and kappa(A) depends on |CD|
alone: ``kappa = sqrt((1 + |c|) / (1 - |c|))`` with ``c = cos delta = 1 - |CD|^2 / (2 L2^2)``.
Hence

* the CD-stretched parallel singularity is the curve ``|CD| = 2 L2``, the C = D one ``|CD| = 0``;
* the level set kappa(A) = k is the pair of curves ``|CD| = 2 L2 / sqrt(1 + k^2)`` and
  ``|CD| = 2 L2 k / sqrt(1 + k^2)`` (one curve ``|CD| = sqrt(2) L2`` for the isotropy locus k = 1);
* serial singularities put P on a circle about A or B of radius ``L1 + L2`` (stretched) or
  ``|L1 - L2|`` (folded), or on the axis AB (w = 0).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from planner.constants import CIRCLES_MEET_TOL
from planner.design import Design
from planner.exceptions import InputError
from planner.kinematics import PostureBatch, mode_signs, wrap_angle

__all__ = [
    "LOCUS_KINDS",
    "Locus",
    "cd_distance_for_kappa",
    "isoconditioning_loci",
    "kappa_from_cd_distance",
    "parallel_loci",
    "serial_loci",
]

#: Every kind of locus this module computes.
LOCUS_KINDS: tuple[str, ...] = (
    "C=D",
    "CD_stretched",
    "P_on_axis",
    "leg_A_stretched",
    "leg_A_folded",
    "leg_B_stretched",
    "leg_B_folded",
    "isoconditioning",
)

#: Samples of the curve parameter (an angle over a full turn, or u along the axis).
DEFAULT_SAMPLES = 1441


@dataclass(frozen=True, slots=True)
class Locus:
    """Postures along one kind of singularity or isoconditioning curve.

    Rows are postures along the curve's branches; a row of NaN separates two branches.

    Attributes
    ----------
    kind : str
        One of :data:`LOCUS_KINDS`.
    q : shape (M, 3), rad
        Actuated joints (theta1 is the section's).
    passive : shape (M, 2), rad
        (theta4, theta5).
    uw : shape (M, 2), m
        P in the linkage plane (u along AB, w normal to it).
    working_mode : shape (M, 3), int8
        (s_axis, s_A, s_B) of each posture (0 on a serial singularity).
    assembly_mode : shape (M,), int8
        Sign of sin(theta5 - theta4) (0 on the CD-stretched singularity).
    kappa : float or None
        The level of an isoconditioning locus.
    fills_region : bool
        The Cartesian locus is two-dimensional (C = D with L0 = 0: every posture whose
        s_A = s_B); ``uw`` is then NaN and only the joint-space curve is drawn.
    """

    kind: str
    q: np.ndarray
    passive: np.ndarray
    uw: np.ndarray
    working_mode: np.ndarray
    assembly_mode: np.ndarray
    kappa: float | None = None
    fills_region: bool = False

    def __len__(self) -> int:
        return self.q.shape[0]

    @property
    def valid(self) -> np.ndarray:
        """Shape (M,), bool: rows holding a posture (not separators)."""
        return np.all(np.isfinite(self.q), axis=1)

    def select(self, *, working_mode: str | None = None, assembly_mode: str | None = None) -> Locus:
        """The rows in one working mode and/or assembly mode; other rows become separators."""
        keep = self.valid.copy()
        if working_mode is not None:
            keep &= _signs_match(self.working_mode, working_mode)
        if assembly_mode is not None:
            keep &= _signs_match(self.assembly_mode, assembly_mode)
        nan = ~keep
        q = self.q.copy()
        passive = self.passive.copy()
        uw = self.uw.copy()
        q[nan] = np.nan
        passive[nan] = np.nan
        uw[nan] = np.nan
        return replace(self, q=q, passive=passive, uw=uw)

    def polyline(self, space: str = "cartesian") -> np.ndarray:
        """Shape (M', 2): the curve as a NaN-separated polyline, ready for ``plot``.

        ``space`` is ``'cartesian'`` (u, w in m) or ``'joint'`` (theta2, theta3 in rad, broken
        where an angle wraps around +-pi).
        """
        if space == "cartesian":
            xy = self.uw
            jump = math.inf  # P moves continuously along a branch: no wrap to break at
        elif space == "joint":
            xy = self.q[:, 1:3]
            jump = math.pi
        else:
            raise InputError(f"space must be 'cartesian' or 'joint', got {space!r}")
        if len(xy) < 2:
            return xy.copy()
        step = np.abs(np.diff(xy, axis=0)).max(axis=1)
        breaks = np.flatnonzero(step > jump) + 1
        return np.insert(xy, breaks, np.nan, axis=0)


def _signs_match(signs: np.ndarray, label: str) -> np.ndarray:
    """Rows (M,) of a sign array (M,) or (M, k) whose :func:`planner.kinematics.mode_label` is ``label``.

    Compares the int8 signs with :func:`mode_signs` of the label in one numpy operation
    rather than building a label string per row (which took seconds on the dense loci of a
    figure); a label of the wrong length or with other characters matches no row.
    """
    rows = np.asarray(signs).reshape(len(signs), -1)
    if not isinstance(label, str) or len(label) != rows.shape[1] or set(label) - set("+-0"):
        return np.zeros(len(rows), dtype=bool)
    return np.all(rows == mode_signs(label)[None, :], axis=1)


# ----------------------------------------------------------------------------- geometry
def _angles_to(
    center: np.ndarray, target: np.ndarray, r_center: float, r_target: np.ndarray | float
):
    """Angles (from +u) of the points X with |X - center| = r_center, |X - target| = r_target.

    center, target : shape (N, 2). Returns two arrays (N,): the '+' and '-' solutions, NaN where
    the circles do not meet.
    """
    g = target - center
    dist = np.hypot(g[:, 0], g[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        cos_a = (r_center**2 + dist**2 - np.asarray(r_target) ** 2) / (2.0 * r_center * dist)
    cos_a = np.where(np.abs(cos_a) <= 1.0 + CIRCLES_MEET_TOL, np.clip(cos_a, -1.0, 1.0), np.nan)
    base = np.arctan2(g[:, 1], g[:, 0])
    a = np.arccos(cos_a)
    return base + a, base - a


def _e(t: np.ndarray) -> np.ndarray:
    return np.stack([np.cos(t), np.sin(t)], axis=-1)


def _batch(
    design: Design, theta1: float, t2: np.ndarray, t3: np.ndarray, p_uw: np.ndarray
) -> PostureBatch:
    """Postures from planar joints and P (rows with NaN stay NaN), leading shape (M,)."""
    half = design.L0 / 2
    c = np.array([-half, 0.0]) + design.L1 * _e(t2)
    d = np.array([half, 0.0]) + design.L1 * _e(t3)
    t4 = np.arctan2(p_uw[:, 1] - c[:, 1], p_uw[:, 0] - c[:, 0])
    t5 = np.arctan2(p_uw[:, 1] - d[:, 1], p_uw[:, 0] - d[:, 0])
    q = np.stack([np.full_like(t2, theta1), wrap_angle(t2), wrap_angle(t3)], axis=1)
    passive = np.stack([t4, t5], axis=1)
    w = p_uw[:, 1]
    p = np.stack([w * math.cos(theta1), p_uw[:, 0], -w * math.sin(theta1)], axis=1)
    ok = np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(p_uw), axis=1)
    return PostureBatch(design, q, passive, p, w, ok)


def _locus(kind: str, batch: PostureBatch, **extra: object) -> Locus:
    bad = ~batch.ok
    q = batch.q.copy()
    q[bad] = np.nan
    passive = batch.passive.copy()
    passive[bad] = np.nan
    uw = np.stack([batch.p[:, 1], batch.w], axis=1)
    uw[bad] = np.nan
    with np.errstate(invalid="ignore"):
        wm = np.where(bad[:, None], 0, batch.working_mode_signs).astype(np.int8)
        am = np.where(bad, 0, batch.assembly_mode_signs).astype(np.int8)
    return Locus(kind, q, passive, uw, wm, am, **extra)  # type: ignore[arg-type]


def _cat(parts: Sequence[tuple[np.ndarray, ...]]) -> tuple[np.ndarray, ...]:
    """Concatenate branches (t2, t3, P) with a NaN row between them (one NaN row if none)."""
    if not parts:
        return np.full(1, np.nan), np.full(1, np.nan), np.full((1, 2), np.nan)
    out = []
    for i in range(len(parts[0])):
        pieces = []
        for part in parts:
            a = part[i]
            pieces.append(a)
            pieces.append(np.full((1, *a.shape[1:]), np.nan))
        out.append(np.concatenate(pieces[:-1]))
    return tuple(out)


def _check_samples(samples: int) -> int:
    if not (isinstance(samples, int | np.integer) and 16 <= samples <= 100_000):
        raise InputError(f"samples must be an integer in [16, 100000], got {samples!r}")
    return int(samples)


def _joined(
    plus: np.ndarray, minus: np.ndarray, *, periodic: bool
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Join the two solution branches of a circle intersection into continuous curves.

    Where the solutions exist on an interval of the parameter, the '+' branch runs across it
    and the '-' branch back, meeting at the interval's ends (the turning points), so the curve
    closes. ``periodic``: the parameter samples a full turn with the last sample equal to the
    first. Returns (rows, solution) pairs, rows indexing the parameter samples.
    """
    n = len(plus)
    ok = np.isfinite(plus)
    if ok.all():
        rows = np.arange(n)
        return [(rows, plus), (rows, minus)]
    if periodic:  # start at a gap so that no interval wraps around the array's ends
        m = n - 1
        order = (int(np.flatnonzero(~ok[:m])[0]) + np.arange(m)) % m
    else:
        order = np.arange(n)
    okk = ok[order]
    edges = np.flatnonzero(np.diff(np.concatenate([[0], okk.astype(np.int8), [0]])))
    out = []
    for s, e in zip(edges[::2], edges[1::2], strict=True):
        run = order[s:e]
        rows = np.concatenate([run, run[::-1], run[:1]])
        sol = np.concatenate([plus[run], minus[run][::-1], plus[run[:1]]])
        out.append((rows, sol))
    return out


def _cd_curves(design: Design, dist: float, samples: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Closed curves (t2, t3) of the joint-space curve |CD| = dist, t2 over a full turn."""
    t2 = np.linspace(-math.pi, math.pi, samples)
    c = np.array([-design.L0 / 2, 0.0]) + design.L1 * _e(t2)
    b = np.broadcast_to(np.array([design.L0 / 2, 0.0]), c.shape)
    plus, minus = _angles_to(b, c, design.L1, dist)
    return [(t2[rows], sol) for rows, sol in _joined(plus, minus, periodic=True)]


# ----------------------------------------------------------------------------- public
def kappa_from_cd_distance(design: Design, cd: np.ndarray) -> np.ndarray:
    """kappa(A) of postures whose C-D distance is ``cd`` (m), elementwise (inf at 0 and 2 L2)."""
    c = np.abs(1.0 - np.asarray(cd, dtype=float) ** 2 / (2.0 * design.L2**2))
    with np.errstate(divide="ignore"):
        return np.sqrt((1.0 + c) / np.maximum(1.0 - c, 0.0))


def cd_distance_for_kappa(design: Design, kappa: float) -> tuple[float, float]:
    """The two C-D distances (m) where kappa(A) = ``kappa`` (equal for kappa = 1).

    ``|CD| = 2 L2 / sqrt(1 + kappa^2)`` (C and D close: near C = D) and
    ``|CD| = 2 L2 kappa / sqrt(1 + kappa^2)`` (near the stretched CD).
    """
    if not (math.isfinite(kappa) and kappa >= 1.0):
        raise InputError(f"kappa must be a finite number >= 1, got {kappa}")
    s = math.sqrt(1.0 + kappa * kappa)
    return 2.0 * design.L2 / s, 2.0 * design.L2 * kappa / s


def parallel_loci(
    design: Design, *, theta1: float = 0.0, samples: int = DEFAULT_SAMPLES
) -> dict[str, Locus]:
    """Loci of the parallel singularities that the design has: keys 'C=D', 'CD_stretched'.

    * 'CD_stretched': postures with |CD| = 2 L2 and P the midpoint of CD (t2 over a full turn).
    * 'C=D': with ``L0 < 2 L1`` C meets D at the two points ``(0, +-sqrt(L1^2 - L0^2/4))`` and P
      runs on a circle of radius L2 about them (the joint-space locus is those two points);
      with ``L0 = 0`` C = D whenever theta2 = theta3 (``fills_region``). Absent when
      ``L0 > 2 L1``.
    """
    samples = _check_samples(samples)
    out: dict[str, Locus] = {}
    parts = []
    for t2, t3 in _cd_curves(design, 2.0 * design.L2, samples):
        c = np.array([-design.L0 / 2, 0.0]) + design.L1 * _e(t2)
        d = np.array([design.L0 / 2, 0.0]) + design.L1 * _e(t3)
        parts.append((t2, t3, 0.5 * (c + d)))
    t2, t3, p = _cat(parts)
    stretched = _locus("CD_stretched", _batch(design, theta1, t2, t3, p))
    if stretched.valid.any():
        out["CD_stretched"] = stretched
    if design.L0 == 0.0:
        t = np.linspace(-math.pi, math.pi, samples)
        nan = np.full((samples, 2), np.nan)
        loc = _locus("C=D", _batch(design, theta1, t, t, nan))
        q = np.stack([np.full_like(t, theta1), t, t], axis=1)
        out["C=D"] = replace(loc, q=q, fills_region=True)
    elif design.L0 <= 2.0 * design.L1:
        h = math.sqrt(max(design.L1**2 - design.L0**2 / 4, 0.0))
        phi = np.linspace(-math.pi, math.pi, samples)
        parts = []
        for sign in (1.0, -1.0):
            t2 = np.full(samples, math.atan2(sign * h, design.L0 / 2))
            t3 = np.full(samples, math.atan2(sign * h, -design.L0 / 2))
            p = np.array([0.0, sign * h]) + design.L2 * _e(phi)
            parts.append((t2, t3, p))
        t2, t3, p = _cat(parts)
        out["C=D"] = _locus("C=D", _batch(design, theta1, t2, t3, p))
    return out


def serial_loci(
    design: Design, *, theta1: float = 0.0, samples: int = DEFAULT_SAMPLES
) -> dict[str, Locus]:
    """Loci of the serial singularities: keys 'P_on_axis', 'leg_A_stretched', 'leg_A_folded',
    'leg_B_stretched', 'leg_B_folded' (a kind is absent when no posture has it).

    A leg stretched (folded) puts P on the circle of radius ``L1 + L2`` (``|L1 - L2|``) about
    its pivot, traced by that leg's angle, with the other leg's two solutions; 'P_on_axis'
    traces u along AB with the two solutions of each leg. These curves bound the working modes'
    regions in both spaces.
    """
    samples = _check_samples(samples)
    half = design.L0 / 2
    a = np.array([-half, 0.0])
    b = np.array([half, 0.0])
    t = np.linspace(-math.pi, math.pi, samples)
    out: dict[str, Locus] = {}
    for leg, base, other in (("A", a, b), ("B", b, a)):
        for name, radius in (
            ("stretched", design.L1 + design.L2),
            ("folded", design.L1 - design.L2),
        ):
            p = base + radius * _e(t)
            sol = _angles_to(np.broadcast_to(other, p.shape), p, design.L1, design.L2)
            parts = [
                (t[rows], x, p[rows]) if leg == "A" else (x, t[rows], p[rows])
                for rows, x in _joined(*sol, periodic=True)
            ]
            if not parts:
                continue
            t2, t3, pp = _cat(parts)
            loc = _locus(f"leg_{leg}_{name}", _batch(design, theta1, t2, t3, pp))
            if loc.valid.any():
                out[loc.kind] = loc
    u = np.linspace(half - design.reach, design.reach - half, samples)
    if u.size and u[0] < u[-1]:
        p = np.stack([u, np.zeros_like(u)], axis=1)
        sa = _angles_to(np.broadcast_to(a, p.shape), p, design.L1, design.L2)
        sb = _angles_to(np.broadcast_to(b, p.shape), p, design.L1, design.L2)
        parts = [(x, y, p) for x in sa for y in sb]
        t2, t3, pp = _cat(parts)
        loc = _locus("P_on_axis", _batch(design, theta1, t2, t3, pp))
        if loc.valid.any():
            out["P_on_axis"] = loc
    return out


def isoconditioning_loci(
    design: Design, kappa: float, *, theta1: float = 0.0, samples: int = DEFAULT_SAMPLES
) -> Locus:
    """The postures where kappa(A) equals ``kappa`` (``kappa = 1``: the isotropy locus).

    Traced in joint space as the curves ``|CD| = d`` for the two distances of
    :func:`cd_distance_for_kappa`, in both assembly modes; select a working mode with
    :meth:`Locus.select` for the paper's figure 15.
    """
    samples = _check_samples(samples)
    dists = sorted(set(cd_distance_for_kappa(design, kappa)))
    parts = []
    for dist in dists:
        for t2, t3 in _cd_curves(design, dist, samples):
            c = np.array([-design.L0 / 2, 0.0]) + design.L1 * _e(t2)
            d = np.array([design.L0 / 2, 0.0]) + design.L1 * _e(t3)
            mid = 0.5 * (c + d)
            e = d - c
            n = np.stack([-e[:, 1], e[:, 0]], axis=1)
            with np.errstate(invalid="ignore", divide="ignore"):
                h = np.sqrt(np.maximum(design.L2**2 - dist**2 / 4, 0.0)) / dist
            for branch in (1.0, -1.0):
                parts.append((t2, t3, mid + branch * h * n))
    t2, t3, p = _cat(parts)
    return _locus("isoconditioning", _batch(design, theta1, t2, t3, p), kappa=float(kappa))
