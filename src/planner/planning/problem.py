"""Start and goal of a plan request (pure data, no OMPL): a joint posture or a Cartesian
target (``docs/conventions.md``), and the options of the planner."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.constants import PLANNERS, PlannerName
from planner.exceptions import InputError
from planner.kinematics import ASSEMBLY_MODES, WORKING_MODES

__all__ = ["PLANNERS", "CartesianTarget", "JointPosture", "PlanOptions", "PlannerName"]


def _triple(name: str, value: object) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be 3 numbers, got {value!r}") from exc
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be 3 finite numbers, got {value!r}")
    arr = arr.copy()
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, slots=True, eq=False)
class JointPosture:
    """``q`` (3,) rad and ``assembly_mode`` '+' | '-' (wire: ``{"q": [...], "assembly_mode"}``)."""

    q: np.ndarray
    assembly_mode: str = "+"

    def __post_init__(self) -> None:
        object.__setattr__(self, "q", _triple("q", self.q))
        if self.assembly_mode not in ASSEMBLY_MODES:
            raise InputError(f"assembly_mode must be '+' or '-', got {self.assembly_mode!r}")


@dataclass(frozen=True, slots=True, eq=False)
class CartesianTarget:
    """Point ``p`` (3,) m to bring P to, in ``working_mode`` ('+-+'-style or 'any')."""

    p: np.ndarray
    working_mode: str = "any"

    def __post_init__(self) -> None:
        object.__setattr__(self, "p", _triple("p", self.p))
        if self.working_mode != "any" and self.working_mode not in WORKING_MODES:
            raise InputError(
                f"working_mode must be 'any' or one of {', '.join(WORKING_MODES)}, "
                f"got {self.working_mode!r}"
            )


@dataclass(frozen=True, slots=True)
class PlanOptions:
    """Options of :func:`planner.planning.plan` (wire field ``planner``).

    Parameters
    ----------
    name : one of :data:`PLANNERS`, default 'rrtconnect'.
    time_budget_s : search budget, s (> 0), default 1.
    seed : random seed of the search (numba's generator for the compiled RRT-Connect, OMPL's
        for the other planners; reproducible results); default 1. Must be > 0.
    simplify : shorten the path (the compiled search's own shortcuts for 'rrtconnect',
        OMPL's PathSimplifier for the others; every motion certified).
    range : longest motion the tree-growing planners add at once, rad; None: from the scene
        for 'rrtconnect' (:func:`planner.planning.compiled_rrt.scene_range`), 1.0 for OMPL's.
    try_direct : first try the straight joint-space motion start -> goal.
    stop_at_transits : the timed trajectory comes to rest at each working-mode transit
        (the planner ignores it; the service passes the transit indices to
        :func:`planner.timing.time_path` as ``stop_at``). Default False: a transit is
        passed at speed (the crossing is straight, so it is no corner).
    region_map : consult the design's region map (:mod:`planner.analysis.regions`) before
        searching: answer ``no_path`` at once where it proves that no path exists. Default
        True; False runs the search alone (tests and benchmarks compare the two).
    corridor : with obstacles, guide the search through narrow passages by a coarse 3-D
        grid of the valid set (:mod:`planner.planning.corridor`; built after a short plain
        search fails, cached per scene, a heuristic whose path is certified motion by
        motion). Default True; False runs the plain OMPL search alone. Library only: the
        wire has no field for it.
    """

    name: str = "rrtconnect"
    time_budget_s: float = 1.0
    seed: int = 1
    simplify: bool = True
    range: float | None = None
    try_direct: bool = True
    stop_at_transits: bool = False
    region_map: bool = True
    corridor: bool = True

    def __post_init__(self) -> None:
        if self.name not in PLANNERS:
            raise InputError(
                f"planner.name must be one of {', '.join(PLANNERS)}, got {self.name!r}"
            )
        if not (
            isinstance(self.time_budget_s, int | float)
            and math.isfinite(self.time_budget_s)
            and self.time_budget_s > 0
        ):
            raise InputError(f"planner.time_budget_s must be > 0, got {self.time_budget_s!r}")
        if not isinstance(self.seed, int) or isinstance(self.seed, bool) or self.seed <= 0:
            raise InputError(f"planner.seed must be a positive integer, got {self.seed!r}")
        if self.range is not None and not (math.isfinite(self.range) and self.range > 0):
            raise InputError(f"planner.range must be > 0, got {self.range!r}")
