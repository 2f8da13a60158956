"""Workspace volume: closed form without joint limits, quasi-random sampling with them.

Without joint limits, P is reachable when each leg reaches it: ``|L1 - L2| <= |AP| <= L1 + L2``
and the same for B (theta1 turns the linkage plane onto P). The workspace is therefore the
intersection of two hollow spheres centred at A and B (``docs/conventions.md``, erratum 5), whose
volume follows from sphere-sphere lens volumes by inclusion-exclusion
(:func:`closed_form_volume`).

With joint limits, per working mode, or restricted to well-conditioned postures the volume is
estimated by :func:`sample_workspace`: randomised quasi-Monte Carlo (independently scrambled
Sobol' sequences, :mod:`scipy.stats.qmc`) over the cylinder around AB that holds the
workspace, with inverse kinematics of every point in the eight working modes
(:func:`planner.inverse_batch`). The spread of the independent replicates gives the standard
error; the sample grows until the asked relative standard error is met.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import qmc

from planner.analysis._common import KAPPA_SINGULAR, parse_modes, within_limits_mod_2pi
from planner.design import Design
from planner.exceptions import InputError
from planner.kinematics import WORKING_MODES, conditioning, inverse_batch

__all__ = [
    "Estimate",
    "WorkspaceSample",
    "ball_intersection_volume",
    "closed_form_volume",
    "reachable_slots",
    "sample_workspace",
]

logger = logging.getLogger(__name__)

#: Largest number of sample points :func:`sample_workspace` draws in all (a safety bound).
MAX_SAMPLES = 2**22


def ball_intersection_volume(r1: float, r2: float, d: float) -> float:
    """Volume of the intersection of two solid balls, m^3.

    Parameters
    ----------
    r1, r2 : float
        Radii, m, ``>= 0``.
    d : float
        Distance between the centres, m, ``>= 0``.

    Notes
    -----
    Disjoint balls give 0, nested balls the smaller ball, otherwise the lens
    ``pi (r1 + r2 - d)^2 (d^2 + 2 d (r1 + r2) - 3 (r1 - r2)^2) / (12 d)``.
    """
    if r1 <= 0.0 or r2 <= 0.0 or d >= r1 + r2:
        return 0.0
    if d <= abs(r1 - r2):
        return 4.0 / 3.0 * math.pi * min(r1, r2) ** 3
    s = r1 + r2 - d
    # divided through by d: (r1 - r2)^2 / d < |r1 - r2| here, so a tiny d loses no precision
    return math.pi * s * s * (d + 2.0 * (r1 + r2) - 3.0 * (r1 - r2) ** 2 / d) / 12.0


def closed_form_volume(design: Design) -> float:
    """Volume of the workspace without joint limits, m^3 (erratum 5).

    The intersection of the shells ``S_A = B(A, R) \\ B(A, r)`` and ``S_B = B(B, R) \\ B(B, r)``
    with ``R = L1 + L2``, ``r = |L1 - L2|``; since ``B(., r)`` lies inside ``B(., R)``,
    ``|S_A & S_B| = |R R| - |r R| - |R r| + |r r|`` where ``|a b|`` is the volume of the
    intersection of the ball of radius a about A with the ball of radius b about B.
    For ``L0 = 0`` this is ``4/3 pi (R^3 - r^3)``.
    """
    big = design.L1 + design.L2
    small = abs(design.L1 - design.L2)
    d = design.L0
    lens = ball_intersection_volume
    return max(
        0.0,
        lens(big, big, d) - 2.0 * lens(small, big, d) + lens(small, small, d),
    )


@dataclass(frozen=True, slots=True)
class Estimate:
    """A sampled quantity with its standard error.

    Attributes
    ----------
    value : float
        Mean over the replicates (m^3 for a volume, dimensionless for a fraction).
    standard_error : float
        Standard deviation of the replicate estimates divided by sqrt(replicates).
    n_samples : int
        Sample points used in all.
    replicates : int
        Independent randomised QMC replicates.
    """

    value: float
    standard_error: float
    n_samples: int
    replicates: int

    @property
    def relative_error(self) -> float:
        """``standard_error / |value|`` (inf for a zero value with a nonzero error, else 0)."""
        if self.value != 0.0:
            return self.standard_error / abs(self.value)
        return 0.0 if self.standard_error == 0.0 else math.inf

    @classmethod
    def from_replicates(cls, values: np.ndarray, n_samples: int) -> Estimate:
        """Mean and standard error of per-replicate estimates ``values`` (R,)."""
        values = np.asarray(values, dtype=float)
        r = values.size
        se = float(np.std(values, ddof=1) / math.sqrt(r)) if r > 1 else math.inf
        return cls(float(np.mean(values)), se, int(n_samples), int(r))


@dataclass(frozen=True, slots=True)
class WorkspaceSample:
    """Sampled workspace measures of one design.

    Attributes
    ----------
    volume : Estimate
        Volume reached by at least one allowed working mode within the joint limits, m^3.
    per_mode : dict label -> Estimate
        Volume reached by each working mode (allowed or not), m^3; a posture on a parallel
        singularity counts as reached.
    per_mode_regular : dict label -> Estimate
        Same, counting only postures with kappa(A) below ``KAPPA_SINGULAR`` (m^3). A mode whose
        regular volume is 0 is not operative (e.g. s_A = s_B for ``L0 = 0, L1 = L2``).
    well_conditioned : Estimate or None
        Volume where some allowed posture has kappa(A) <= ``kappa_max`` (m^3), if asked.
    well_conditioned_fraction : Estimate or None
        ``well_conditioned / volume`` (per replicate), if asked.
    gci : Estimate
        Global conditioning index: mean over the reached volume of 1 / kappa(A) of the best
        allowed posture at each point, in [0, 1].
    """

    volume: Estimate
    per_mode: dict[str, Estimate]
    per_mode_regular: dict[str, Estimate]
    gci: Estimate
    well_conditioned: Estimate | None = None
    well_conditioned_fraction: Estimate | None = None
    kappa_max: float | None = field(default=None)


def reachable_slots(
    design: Design,
    p: np.ndarray,
    *,
    working_modes: str | Iterable[str] | None = None,
    joint_limits: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Which working modes reach each point, and kappa(A) there.

    Parameters
    ----------
    p : shape (N, 3), m
    working_modes : None, ``"any"`` or iterable of labels
        Modes allowed; the others are marked unreachable.
    joint_limits : bool
        Apply the design's joint limits (any 2-pi shift of a joint may be used).

    Returns
    -------
    reached : shape (N, 8), bool
        Slot k (``WORKING_MODES[k]``) reaches the point. Degenerate points (P on a pivot with
        L1 = L2, erratum 6) are reached by no slot.
    kappa : shape (N, 8)
        kappa(A) of the slot's posture (NaN where not reached by the kinematics).
    """
    batch = inverse_batch(design, p)
    reached = batch.ok & parse_modes(working_modes)[None, :]
    if joint_limits:
        reached &= within_limits_mod_2pi(design, batch.q)
    kappa = conditioning(design, batch.q, batch.passive, batch.w).kappa_A
    return reached, kappa


def _domain(design: Design) -> tuple[float, float, float]:
    """Cylinder about AB holding the workspace: (y half-length, radius, volume), m, m, m^3."""
    big = design.reach
    half_len = max(0.0, big - design.L0 / 2)
    radius = math.sqrt(max(0.0, big * big - design.L0 * design.L0 / 4))
    return half_len, radius, math.pi * radius * radius * 2.0 * half_len


def _points(unit: np.ndarray, half_len: float, radius: float) -> np.ndarray:
    """Map unit-cube points (N, 3) uniformly (by volume) onto the cylinder, shape (N, 3), m."""
    y = half_len * (2.0 * unit[:, 0] - 1.0)
    rho = radius * np.sqrt(unit[:, 1])
    phi = 2.0 * np.pi * unit[:, 2] - np.pi
    return np.stack([rho * np.cos(phi), y, -rho * np.sin(phi)], axis=1)


def sample_workspace(
    design: Design,
    *,
    rel_se: float | None = 0.005,
    n_per_replicate: int = 1024,
    replicates: int = 8,
    working_modes: str | Iterable[str] | None = None,
    joint_limits: bool = True,
    kappa_max: float | None = None,
    seed: int = 0,
    max_samples: int = MAX_SAMPLES,
    deadline: float | None = None,
) -> WorkspaceSample:
    """Estimate workspace volumes by randomised quasi-Monte Carlo.

    Parameters
    ----------
    design : Design
    rel_se : float or None
        Target relative standard error of the total volume. The sample of each replicate is
        doubled (continuing its Sobol' sequence) until it is met or ``max_samples`` is reached.
        ``None``: draw ``n_per_replicate`` points per replicate once (a fixed, deterministic
        sample for a given seed, as an optimiser needs).
    n_per_replicate : int
        Initial points per replicate, rounded up to a power of 2.
    replicates : int
        Independently scrambled Sobol' sequences, ``>= 2``.
    working_modes : None, ``"any"`` or iterable of labels
        Modes counted in ``volume``, ``well_conditioned`` and ``gci``.
    joint_limits : bool
        Apply the design's joint limits.
    kappa_max : float or None
        Bound on kappa(A) defining the well-conditioned volume.
    seed : int
        Seed of the scrambling.
    deadline : float, optional
        A :func:`time.monotonic` value: the sample stops doubling when the next round (about
        twice the last one's time) would end after it, and the estimate is returned with
        the standard error reached (a thin workspace in a large bounding box can need
        millions of points for ``rel_se``; a caller with a time budget gets the best
        estimate within it rather than none).

    Returns
    -------
    WorkspaceSample
    """
    if replicates < 2:
        raise InputError(f"replicates must be >= 2, got {replicates}")
    if rel_se is not None and not (math.isfinite(rel_se) and rel_se > 0):
        raise InputError(f"rel_se must be a positive number, got {rel_se}")
    if kappa_max is not None and not (kappa_max >= 1.0):
        raise InputError(f"kappa_max must be >= 1, got {kappa_max}")
    allowed = parse_modes(working_modes)
    half_len, radius, dom = _domain(design)
    if dom == 0.0:  # L0 >= 2 (L1 + L2): the legs cannot meet off the axis
        return _empty_sample(replicates, kappa_max)
    m = max(1, math.ceil(math.log2(max(2, n_per_replicate))))
    samplers = [
        qmc.Sobol(3, scramble=True, rng=np.random.default_rng(s))
        for s in np.random.SeedSequence(seed).spawn(replicates)
    ]
    counts = _Counts.zeros(replicates)
    n = 0
    draw = 2**m
    while True:
        round_start = time.monotonic()
        for r, sampler in enumerate(samplers):
            unit = sampler.random_base2(m) if n == 0 else sampler.random(draw)
            p = _points(unit, half_len, radius)
            counts.add(r, design, p, allowed, joint_limits=joint_limits, kappa_max=kappa_max)
        n += draw
        total = Estimate.from_replicates(dom * counts.hits / n, n * replicates)
        done = rel_se is None or total.relative_error <= rel_se
        now = time.monotonic()
        late = deadline is not None and now + 2.0 * (now - round_start) > deadline
        if done or late or 2 * n * replicates > max_samples:
            if not done:
                logger.warning(
                    "sample_workspace stopped at %d samples (%s) with relative error %.3g > %.3g",
                    n * replicates,
                    "time budget" if late else "max_samples",
                    total.relative_error,
                    rel_se,
                )
            break
        draw = n
    return counts.estimates(total, dom, n, kappa_max)


def _empty_sample(replicates: int, kappa_max: float | None) -> WorkspaceSample:
    """The answer of :func:`sample_workspace` for a design whose legs cannot meet off the
    axis: every volume is 0, exactly (no sample is drawn)."""
    zero = Estimate(0.0, 0.0, 0, replicates)
    modes = dict.fromkeys(WORKING_MODES, zero)
    return WorkspaceSample(
        volume=zero,
        per_mode=modes,
        per_mode_regular=modes,
        gci=zero,
        well_conditioned=None if kappa_max is None else zero,
        well_conditioned_fraction=None if kappa_max is None else zero,
        kappa_max=kappa_max,
    )


@dataclass(frozen=True, slots=True, eq=False)
class _Counts:
    """What :func:`sample_workspace` counts per replicate, summed over its rounds: points
    reached in an allowed mode (``hits``, (R,)), per slot reached at all and regularly
    (``mode_hits``, ``regular_hits``, (R, 8)), well-conditioned (``wc_hits``), and the sum
    of 1 / kappa(A) of the best allowed posture (``inv_kappa``)."""

    hits: np.ndarray
    mode_hits: np.ndarray
    regular_hits: np.ndarray
    wc_hits: np.ndarray
    inv_kappa: np.ndarray

    @classmethod
    def zeros(cls, replicates: int) -> _Counts:
        return cls(
            hits=np.zeros(replicates),
            mode_hits=np.zeros((replicates, 8)),
            regular_hits=np.zeros((replicates, 8)),
            wc_hits=np.zeros(replicates),
            inv_kappa=np.zeros(replicates),
        )

    def add(
        self,
        r: int,
        design: Design,
        p: np.ndarray,
        allowed: np.ndarray,
        *,
        joint_limits: bool,
        kappa_max: float | None,
    ) -> None:
        """Count the points ``p`` (N, 3), m, of replicate ``r``."""
        reached, kappa = reachable_slots(design, p, joint_limits=joint_limits)
        regular = reached & (kappa < KAPPA_SINGULAR)
        self.mode_hits[r] += reached.sum(axis=0)
        self.regular_hits[r] += regular.sum(axis=0)
        mine = reached & allowed
        any_hit = mine.any(axis=1)
        self.hits[r] += any_hit.sum()
        best = np.where(mine, kappa, np.inf).min(axis=1)
        self.inv_kappa[r] += np.sum(1.0 / best[any_hit])
        if kappa_max is not None:
            self.wc_hits[r] += np.sum(best <= kappa_max)

    def estimates(
        self, total: Estimate, dom: float, n: int, kappa_max: float | None
    ) -> WorkspaceSample:
        """The answer from ``n`` points per replicate in a domain of ``dom`` m^3, ``total``
        the volume's estimate."""
        n_all = n * self.hits.shape[0]

        def ratio(num: np.ndarray) -> Estimate:
            with np.errstate(invalid="ignore", divide="ignore"):
                vals = np.where(self.hits > 0, num / np.where(self.hits > 0, self.hits, 1.0), 0.0)
            return Estimate.from_replicates(vals, n_all)

        per_mode = {
            label: Estimate.from_replicates(dom * self.mode_hits[:, k] / n, n_all)
            for k, label in enumerate(WORKING_MODES)
        }
        per_mode_regular = {
            label: Estimate.from_replicates(dom * self.regular_hits[:, k] / n, n_all)
            for k, label in enumerate(WORKING_MODES)
        }
        wc = wcf = None
        if kappa_max is not None:
            wc = Estimate.from_replicates(dom * self.wc_hits / n, n_all)
            wcf = ratio(self.wc_hits)
        return WorkspaceSample(
            volume=total,
            per_mode=per_mode,
            per_mode_regular=per_mode_regular,
            gci=ratio(self.inv_kappa),
            well_conditioned=wc,
            well_conditioned_fraction=wcf,
            kappa_max=kappa_max,
        )
