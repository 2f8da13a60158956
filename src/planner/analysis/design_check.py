"""Design check: which parallel singularities a design can have and why, which working modes
are operative, the workspace volume, and how much of it is well conditioned.

Rules (``docs/conventions.md``, erratum 4). C lies on the circle of radius L1 about A and D on the
one about B, so ``|CD|`` takes every value in ``[max(0, L0 - 2 L1), L0 + 2 L1]``:

* C = D needs ``|CD| = 0``: possible iff ``L0 <= 2 L1`` (``2 L1 < L0`` removes it);
* P the midpoint of a stretched CD needs ``|CD| = 2 L2``: possible iff
  ``L0 - 2 L1 <= 2 L2 <= L0 + 2 L1``, i.e. ``2 (L2 - L1) <= L0`` (the other bound holds whenever
  the workspace is not empty), so ``2 (L2 - L1) > L0`` removes it.

A joint-space posture with either value of |CD| exists and closes the loop, so these are exact
(joint limits aside: the verdict is about the geometry).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from planner.analysis.workspace import Estimate, closed_form_volume, sample_workspace
from planner.design import Design
from planner.exceptions import InputError
from planner.kinematics import WORKING_MODES

__all__ = ["PARALLEL_KINDS", "DesignCheck", "check_design", "parallel_singularity_kinds"]

#: The two kinds of parallel singularity, as written on the wire.
PARALLEL_KINDS: tuple[str, ...] = ("C=D", "CD_stretched")


@dataclass(frozen=True, slots=True)
class DesignCheck:
    """Verdict on one design.

    Attributes
    ----------
    design : Design
    volume : float
        Closed-form workspace volume without joint limits, m^3.
    parallel_singularities : tuple of str
        Kinds from :data:`PARALLEL_KINDS` that occur somewhere in the workspace.
    reasons : dict kind -> str
        Why each kind can or cannot occur, with the numbers.
    singularity_free : bool
        No parallel singularity anywhere (and a non-empty workspace).
    operative_working_modes : tuple of str
        Working modes with a positive sampled volume of regular postures (kappa(A) finite)
        within the joint limits.
    sampled_volume : Estimate
        Workspace volume within the joint limits, m^3.
    kappa_max : float
        Bound used for the well-conditioned fraction.
    well_conditioned_fraction : Estimate
        Fraction of ``sampled_volume`` where some posture has kappa(A) <= ``kappa_max``.
    gci : Estimate
        Global conditioning index (mean of 1/kappa(A) of the best posture over the volume).
    """

    design: Design
    volume: float
    parallel_singularities: tuple[str, ...]
    reasons: dict[str, str]
    singularity_free: bool
    operative_working_modes: tuple[str, ...]
    sampled_volume: Estimate
    kappa_max: float
    well_conditioned_fraction: Estimate
    gci: Estimate


def parallel_singularity_kinds(design: Design) -> tuple[tuple[str, ...], dict[str, str]]:
    """The parallel-singularity kinds that the geometry allows, with a reason for each kind."""
    L0, L1, L2 = design.L0, design.L1, design.L2
    reasons: dict[str, str] = {}
    kinds: list[str] = []
    if L0 > 2 * (L1 + L2):
        msg = f"L0 = {L0:.6g} m > 2 (L1 + L2) = {2 * (L1 + L2):.6g} m: the workspace is empty"
        return (), dict.fromkeys(PARALLEL_KINDS, msg)
    if L0 <= 2 * L1:
        kinds.append("C=D")
        reasons["C=D"] = f"L0 = {L0:.6g} m <= 2 L1 = {2 * L1:.6g} m: C and D can meet " + (
            "(whenever theta2 = theta3, since L0 = 0)"
            if L0 == 0
            else f"at u = 0, w = +-{math.sqrt(max(L1**2 - L0**2 / 4, 0.0)):.6g} m"
        )
    else:
        reasons["C=D"] = f"2 L1 = {2 * L1:.6g} m < L0 = {L0:.6g} m: C and D cannot meet"
    if 2 * (L2 - L1) <= L0:
        kinds.append("CD_stretched")
        reasons["CD_stretched"] = (
            f"2 (L2 - L1) = {2 * (L2 - L1):.6g} m <= L0 = {L0:.6g} m: |CD| can reach 2 L2 = "
            f"{2 * L2:.6g} m, putting P at the midpoint of a stretched CD"
        )
    else:
        reasons["CD_stretched"] = (
            f"2 (L2 - L1) = {2 * (L2 - L1):.6g} m > L0 = {L0:.6g} m: |CD| <= L0 + 2 L1 = "
            f"{L0 + 2 * L1:.6g} m < 2 L2 = {2 * L2:.6g} m, CD never stretches"
        )
    return tuple(kinds), reasons


def check_design(
    design: Design,
    *,
    kappa_max: float = 10.0,
    rel_se: float = 0.01,
    seed: int = 0,
    deadline: float | None = None,
) -> DesignCheck:
    """Check a design (see the module docstring for the rules).

    Parameters
    ----------
    design : Design
    kappa_max : float
        Bound on kappa(A) for the well-conditioned fraction, ``>= 1``.
    rel_se : float
        Relative standard error asked of the sampled volume.
    seed : int
        Seed of the quasi-random sampling (the answer is deterministic for a seed).
    deadline : float, optional
        :func:`time.monotonic` value by which the sampled volume stops refining (see
        :func:`planner.analysis.workspace.sample_workspace`).
    """
    if not (math.isfinite(kappa_max) and kappa_max >= 1.0):
        raise InputError(f"kappa_max must be a finite number >= 1, got {kappa_max}")
    kinds, reasons = parallel_singularity_kinds(design)
    volume = closed_form_volume(design)
    sample = sample_workspace(
        design, rel_se=rel_se, kappa_max=kappa_max, seed=seed, deadline=deadline
    )
    operative = tuple(m for m in WORKING_MODES if sample.per_mode_regular[m].value > 0.0)
    fraction = sample.well_conditioned_fraction
    if fraction is None:  # pragma: no cover - kappa_max was given, so it is computed
        raise RuntimeError("sample_workspace returned no well-conditioned fraction")
    return DesignCheck(
        design=design,
        volume=volume,
        parallel_singularities=kinds,
        reasons=reasons,
        singularity_free=not kinds and volume > 0.0,
        operative_working_modes=operative,
        sampled_volume=sample.volume,
        kappa_max=float(kappa_max),
        well_conditioned_fraction=fraction,
        gci=sample.gci,
    )
