"""Choosing the working mode of a Cartesian goal for the task (the paper's section 3.3).

For a Cartesian target with ``working_mode`` "any", several working modes may reach the goal.
``prefer = "shortest"`` (today's behaviour) takes the shortest joint path;
``prefer = "best_conditioned"`` takes the one whose path keeps the largest kappa(A) lowest (the
most precise motion: the parallel part's velocity error gain stays smallest all along).

:func:`choose_plan` works on candidate plans the caller made (one per reachable mode);
:func:`plan_candidates` makes them with :func:`planner.planning.plan`. The planner's own
integration (``goal.prefer`` on the wire) is left to it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from planner.design import Design
from planner.exceptions import InputError
from planner.geometry import Obstacle
from planner.kinematics import WORKING_MODES, conditioning, forward_batch
from planner.planning.problem import CartesianTarget, JointPosture, PlanOptions
from planner.planning.result import PlanResult
from planner.validity import Margins, densify

__all__ = [
    "KAPPA_STEP",
    "PREFERENCES",
    "ModeChoice",
    "choose_plan",
    "path_max_kappa",
    "plan_candidates",
]

PREFERENCES: tuple[str, ...] = ("shortest", "best_conditioned")
#: Max-norm joint step (rad) of the samples on which :func:`path_max_kappa` measures kappa(A).
KAPPA_STEP = 0.002


def path_max_kappa(
    design: Design, waypoints: np.ndarray, assembly_mode: str, *, step: float = KAPPA_STEP
) -> float:
    """Largest kappa(A) over a joint path (N, 3) rad, sampled every ``step`` rad (max-norm)
    along its straight pieces (inf where a sample does not assemble)."""
    q = densify(np.atleast_2d(np.asarray(waypoints, dtype=float)), step)
    fb = forward_batch(design, q, assembly_mode)
    if not np.all(fb.ok):
        return math.inf
    c = conditioning(design, fb.q, fb.passive, fb.w)
    return float(np.max(c.kappa_A))


@dataclass(frozen=True, slots=True)
class ModeChoice:
    """The plan chosen among candidates.

    Attributes
    ----------
    working_mode : str -- the mode of the chosen plan's goal (its last segment's).
    result : PlanResult -- the chosen plan.
    prefer : "shortest" | "best_conditioned"
    max_kappa_A : float -- of the chosen path (:func:`path_max_kappa`).
    path_length : float, rad -- of the chosen path.
    message : str -- which mode was chosen and why, with the alternatives' figures.
    table : dict mode -> (max_kappa_A, path_length) of every solved candidate.
    """

    working_mode: str
    result: PlanResult
    prefer: str
    max_kappa_A: float
    path_length: float
    message: str
    table: dict[str, tuple[float, float]]


def _length(path) -> float:
    w = np.asarray(path.waypoints, dtype=float)
    return float(np.sum(np.linalg.norm(np.diff(w, axis=0), axis=1)))


def choose_plan(
    design: Design,
    candidates: Mapping[str, PlanResult],
    prefer: Literal["shortest", "best_conditioned"] = "shortest",
    *,
    kappa_step: float = KAPPA_STEP,
) -> ModeChoice | None:
    """Pick one of the solved candidate plans (keyed by the goal's working mode).

    ``shortest``: least joint-space path length (ties: lower max kappa(A)).
    ``best_conditioned``: least max kappa(A) along the path (:func:`path_max_kappa`, the same
    measure for every candidate; ties: shorter).

    Returns
    -------
    ModeChoice, or None when no candidate is solved.

    Raises
    ------
    InputError
        ``prefer`` is not one of :data:`PREFERENCES`.
    """
    if prefer not in PREFERENCES:
        raise InputError(f"prefer must be one of {', '.join(PREFERENCES)}, got {prefer!r}")
    table: dict[str, tuple[float, float]] = {}
    solved: dict[str, PlanResult] = {}
    for mode, res in candidates.items():
        if res.solved and res.path is not None:
            asm = res.path.segments[0].assembly_mode if res.path.segments else "+"
            k = path_max_kappa(design, res.path.waypoints, asm, step=kappa_step)
            table[mode] = (k, _length(res.path))
            solved[mode] = res
    if not solved:
        return None
    if prefer == "shortest":
        mode = min(table, key=lambda m: (table[m][1], table[m][0], m))
        why = f"the shortest joint path ({table[mode][1]:.4g} rad)"
    else:
        mode = min(table, key=lambda m: (table[m][0], table[m][1], m))
        why = f"the lowest largest kappa(A) along the path ({table[mode][0]:.4g})"
    others = ", ".join(
        f"{m}: kappa {k:.4g}, {length:.4g} rad"
        for m, (k, length) in sorted(table.items())
        if m != mode
    )
    message = f"working mode {mode} chosen ({prefer}): {why}" + (
        f"; other modes: {others}" if others else ""
    )
    return ModeChoice(mode, solved[mode], prefer, table[mode][0], table[mode][1], message, table)


def plan_candidates(
    design: Design,
    start: JointPosture,
    p: np.ndarray,
    *,
    modes: Sequence[str] = WORKING_MODES,
    obstacles: Sequence[Obstacle] = (),
    margins: Margins | None = None,
    options: PlanOptions | None = None,
) -> dict[str, PlanResult]:
    """One plan per working mode in ``modes`` to the Cartesian point ``p`` (3,) m, with
    :func:`planner.planning.plan` (mode changes included); every result, solved or not."""
    from planner.planning import plan

    out = {}
    for mode in modes:
        out[mode] = plan(
            design,
            start,
            CartesianTarget(p, mode),
            obstacles=obstacles,
            margins=margins,
            options=options,
        )
    return out
