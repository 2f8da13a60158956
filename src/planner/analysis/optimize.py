"""Design optimisation over (L0, L1, L2) with :mod:`scipy.optimize`.

Objectives (all maximised):

* ``'volume'``: closed-form workspace volume without joint limits (smooth; L-BFGS-B from a few
  starts). The paper's claim: for a fixed ``L1 + L2`` the maximum is at ``L0 = 0, L1 = L2``.
* ``'well_conditioned_volume'``: sampled volume where some posture has kappa(A) <= ``kappa_max``,
  within the joint limits;
* ``'gci'``: global conditioning index, the mean of 1/kappa(A) over the workspace.

The sampled objectives use one fixed quasi-random sample (same seed at every evaluation), so the
objective is a deterministic, piecewise-constant function of the design; they are maximised with
differential evolution, which needs no gradient.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np
from scipy import optimize

from planner.analysis.workspace import closed_form_volume, sample_workspace
from planner.design import MIN_LENGTH, Design
from planner.exceptions import InputError, check_deadline

__all__ = ["OBJECTIVES", "DesignOptimum", "optimize_design"]

logger = logging.getLogger(__name__)

#: Objectives :func:`optimize_design` can maximise.
OBJECTIVES: tuple[str, ...] = ("volume", "well_conditioned_volume", "gci")


@dataclass(frozen=True, slots=True)
class DesignOptimum:
    """Result of :func:`optimize_design`.

    Attributes
    ----------
    design : Design
        The best design found.
    objective : str
    value : float
        Objective at ``design`` (m^3 for volumes, dimensionless for the gci).
    success : bool
        The optimiser reported convergence.
    message : str
    evaluations : int
        Objective evaluations.
    """

    design: Design
    objective: str
    value: float
    success: bool
    message: str
    evaluations: int


def _bounds(
    name: str, b: tuple[float, float] | None, default: tuple[float, float]
) -> tuple[float, float]:
    lo, hi = default if b is None else (float(b[0]), float(b[1]))
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 <= lo <= hi):
        raise InputError(f"{name} must be finite with 0 <= low <= high, got {b}")
    return lo, hi


def optimize_design(
    objective: str = "volume",
    *,
    reach: float | None = 0.8,
    L0_bounds: tuple[float, float] | None = None,
    L1_bounds: tuple[float, float] | None = None,
    L2_bounds: tuple[float, float] | None = None,
    template: Design | None = None,
    kappa_max: float = 10.0,
    n_samples: int = 4096,
    maxiter: int = 30,
    seed: int = 0,
    progress: Callable[[str, int, int], None] | None = None,
    deadline: float | None = None,
) -> DesignOptimum:
    """Maximise an objective of :data:`OBJECTIVES` over the link lengths.

    Parameters
    ----------
    objective : str
    reach : float or None
        Fixed ``L1 + L2``, m (the variables are then L0 and L1). ``None``: L0, L1, L2 vary
        independently inside their bounds.
    L0_bounds, L1_bounds, L2_bounds : (low, high), m, optional
        Defaults: L0 in [0, reach], L1 (and L2) in [0.05 reach, 0.95 reach]; without ``reach``
        the bounds of L1 and L2 are required.
    template : Design, optional
        Link radius and joint limits of the candidates (default: full turns).
    kappa_max : float
        Bound on kappa(A) for ``'well_conditioned_volume'``.
    n_samples : int
        Quasi-random points per evaluation of a sampled objective (over 4 replicates).
    maxiter : int
        Generations of differential evolution (sampled objectives).
    seed : int
        Seed of the sample and of the optimiser.
    progress : callable(step_name, index, total), optional
        Told each local start (``'volume'``) or generation (sampled objectives) as it begins,
        with the number done so far, then ``("done", total, total)``; a long optimisation can
        so show how far it is (the optimiser may stop before ``maxiter`` generations).
    deadline : float, optional
        A :func:`time.monotonic` value, checked before every evaluation of the objective:
        past it, :class:`~planner.exceptions.DeadlineError` (the optimisation is abandoned).
    """
    if objective not in OBJECTIVES:
        raise InputError(f"objective must be one of {OBJECTIVES}, got {objective!r}")
    scale, bounds = _search_space(reach, L0_bounds, L1_bounds, L2_bounds)
    make = partial(_candidate, reach=reach, template=template or Design(0.0, 1.0, 1.0))
    value = partial(
        _objective_value,
        objective=objective,
        n_per_replicate=max(2, n_samples // 4),
        kappa_max=kappa_max,
        seed=seed,
    )
    calls = 0

    def loss(x: np.ndarray) -> float:
        nonlocal calls
        check_deadline(deadline, f"while optimising the design ({calls} evaluations done)")
        calls += 1
        return -value(make(x)) / scale**3 if objective != "gci" else -value(make(x))

    def tell(name: str, index: int, total: int) -> None:
        if progress is not None:
            progress(name, index, total)

    if objective == "volume":
        res = _local_starts(loss, bounds, tell)
    else:
        res = _evolve(
            loss, bounds, seed=seed, maxiter=maxiter, tell=tell, each=progress is not None
        )
    design = make(res.x)
    logger.info("optimize_design(%s): %s after %d evaluations", objective, design, calls)
    return DesignOptimum(
        design, objective, value(design), bool(res.success), str(res.message), calls
    )


def _search_space(
    reach: float | None,
    L0_bounds: tuple[float, float] | None,
    L1_bounds: tuple[float, float] | None,
    L2_bounds: tuple[float, float] | None,
) -> tuple[float, list[tuple[float, float]]]:
    """The first step of :func:`optimize_design`: the length scale (m) and the bounds of the
    variables, (L0, L1) with a fixed ``reach`` and (L0, L1, L2) without, defaults filled in
    and checked."""
    if reach is None and (L1_bounds is None or L2_bounds is None):
        raise InputError("L1_bounds and L2_bounds are required when reach is None")
    if reach is not None and not (math.isfinite(reach) and reach > 0):
        raise InputError(f"reach must be a positive number, got {reach}")
    scale = reach if reach is not None else max(L1_bounds[1], L2_bounds[1])  # type: ignore[index]
    b0 = _bounds("L0_bounds", L0_bounds, (0.0, scale))
    b1 = _bounds("L1_bounds", L1_bounds, (0.05 * scale, 0.95 * scale))
    if reach is not None:
        b1 = (max(b1[0], MIN_LENGTH), min(b1[1], reach - MIN_LENGTH))
        if b1[0] > b1[1]:
            raise InputError(f"L1_bounds leave no room below reach = {reach}")
        return scale, [b0, b1]
    return scale, [b0, b1, _bounds("L2_bounds", L2_bounds, (0.0, scale))]


def _candidate(x: np.ndarray, *, reach: float | None, template: Design) -> Design:
    """The design at the optimiser's point ``x`` (lengths at least ``MIN_LENGTH``; L2 =
    ``reach`` - L1 with a fixed reach), with the link radius and joint limits of
    ``template``."""
    l2 = reach - x[1] if reach is not None else x[2]
    return Design(
        max(float(x[0]), 0.0),
        max(float(x[1]), MIN_LENGTH),
        max(float(l2), MIN_LENGTH),
        link_radius=template.link_radius,
        joint_min=template.joint_min,
        joint_max=template.joint_max,
    )


def _objective_value(
    d: Design, *, objective: str, n_per_replicate: int, kappa_max: float, seed: int
) -> float:
    """The objective at design ``d``: closed form for ``'volume'``, else from the same seeded
    sample at every evaluation (:func:`planner.analysis.workspace.sample_workspace`)."""
    if objective == "volume":
        return closed_form_volume(d)
    s = sample_workspace(
        d,
        rel_se=None,
        n_per_replicate=n_per_replicate,
        replicates=4,
        kappa_max=kappa_max,
        seed=seed,
    )
    if objective == "gci":
        return s.gci.value
    assert s.well_conditioned is not None
    return s.well_conditioned.value


def _local_starts(
    loss: Callable[[np.ndarray], float],
    bounds: list[tuple[float, float]],
    tell: Callable[[str, int, int], None],
) -> optimize.OptimizeResult:
    """The smooth objective's search: L-BFGS-B from three starts (at 1/4, 1/2 and 3/4 of
    every bound), the best of them."""
    best = None
    for k, frac in enumerate((0.25, 0.5, 0.75)):
        tell(f"local start {k + 1} of 3", k, 3)
        x0 = np.array([lo + frac * (hi - lo) for lo, hi in bounds])
        res = optimize.minimize(loss, x0, method="L-BFGS-B", bounds=bounds)
        if best is None or res.fun < best.fun:
            best = res
    tell("done", 3, 3)
    assert best is not None  # three local starts ran
    return best


def _evolve(
    loss: Callable[[np.ndarray], float],
    bounds: list[tuple[float, float]],
    *,
    seed: int,
    maxiter: int,
    tell: Callable[[str, int, int], None],
    each: bool,
) -> optimize.OptimizeResult:
    """The sampled objectives' search: differential evolution (it needs no gradient);
    with ``each``, ``tell`` hears of each generation as it begins (through the optimiser's
    callback, which is left out otherwise)."""
    generation = 0

    def generation_done(intermediate_result: optimize.OptimizeResult) -> None:
        nonlocal generation
        generation += 1
        if generation < maxiter:
            tell(f"generation {generation + 1} of {maxiter}", generation, maxiter)

    tell(f"generation 1 of {maxiter}", 0, maxiter)
    res = optimize.differential_evolution(
        loss,
        # scipy takes (min, max) pairs, one per variable; scipy-stubs types one pair only
        bounds,  # type: ignore[arg-type]
        seed=seed,
        maxiter=maxiter,
        popsize=8,
        tol=1e-3,
        polish=False,
        callback=generation_done if each else None,
    )
    tell("done", maxiter, maxiter)
    return res
