"""Pay every first-call cost of the library once, before the first request: ready means warm.

A fresh process pays, on its first plan, much more than the plan itself: compiling (or loading
from numba's on-disk cache) the numba kernels, importing OMPL, toppra, ruckig, scipy and
matplotlib, numba's first dispatch of each kernel, OMPL's first solve, toppra's and ruckig's
first solve, matplotlib's font cache and first render (pydantic's first validation of the
wire models is the service's to warm: :mod:`planner_api.warmup` runs its jobs). Measured
on a 2-core machine that is 3-5 s against 15 ms warm, which spends a request's time budget.

:func:`warm_up` runs :data:`STEPS` in order, each a tiny real job through the library's own
entry points (the paths the service's jobs take: :func:`planner.planning.plan`,
:func:`planner.motion.time_planned` (the pipeline's timing step) with TOPPRA and with Ruckig, the workspace analysis
and the design check, :func:`planner.plotting.render_figure`; a plan among a point cloud, whose
tree only large scenes build), so that afterwards the first job of each kind costs
what the second one does. The service's workers call it when they start (``/v1/ready`` waits
for them); ``make run`` / ``make test`` and the Docker build call ``planner warm-up`` so that
the kernels are in numba's cache before any worker starts (the first compile, about 30 s on
a 2-core machine, then lasts across processes).

OMPL, toppra, ruckig and matplotlib are imported only through :mod:`planner.planning`,
:mod:`planner.timing` and :mod:`planner.plotting`, the only modules that may import them.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

__all__ = ["STEPS", "Progress", "Step", "quiet_library_logs", "warm_up"]

#: ``progress(step_name, index, total)``: called before each step with the number of steps
#: finished so far (``index`` = 0 .. total - 1), and once at the end with ``index == total``.
Progress = Callable[[str, int, int], None]


@dataclass
class _State:
    """What one step hands to the next: the plans found, with their obstacles and margins,
    are the paths the timing steps time."""

    design: Any = None
    plans: list[tuple[Any, Any, Any]] = field(default_factory=list)


def _kinematics(state: _State) -> None:
    """The kinematics kernels (direct, inverse, conditioning) of :mod:`planner._kernels`."""
    from planner.design import Design
    from planner.kinematics import conditioning, forward_batch, inverse_batch

    state.design = Design.default()
    batch = forward_batch(state.design, np.array([[0.0, 2.0, 1.0]]), "+")
    inverse_batch(state.design, batch.p)
    conditioning(state.design, batch.q, batch.passive, batch.w)


def _dynamics(state: _State) -> None:
    """The inverse-dynamics kernel of :mod:`planner.dynamics._kernels` (and its mass matrix)."""
    from planner.dynamics import Inertia, inverse_dynamics

    q = np.array([[0.0, 2.0, 1.0]])
    inverse_dynamics(state.design, Inertia.default(state.design), q, q, q, with_mass_matrix=True)


def _validity(state: _State) -> None:
    """The validity rules and the clearance kernels of every obstacle type (and the
    library's segment distance query, :func:`planner.geometry.segment_obstacle_distance`)."""
    from planner.geometry import Box, Capsule, Obstacle, Sphere, segment_obstacle_distance
    from planner.validity import Margins, ValidityChecker
    from planner.validity import warm_up as warm_validity

    warm_validity()
    obstacles: list[Obstacle] = [
        Sphere(np.array([2.0, 2.0, 2.0]), 0.1),
        Box(np.array([-2.0, 2.0, 2.0]), np.array([0.2, 0.2, 0.2]), np.array([1.0, 0.0, 0.0, 0.0])),
        Capsule(np.array([2.0, -2.0, 2.0]), np.array([2.0, -2.0, 2.5]), 0.05),
    ]
    checker = ValidityChecker(state.design, Margins(), obstacles, "+", "+-+")
    q = np.array([[0.0, 2.0, 1.0], [0.1, 2.1, 1.1]])
    checker.check_states(q)
    checker.check_motion(q[0], q[1])
    checker.check_path(q)
    segment_obstacle_distance(q[:, :3], q[::-1, :3], obstacles)


#: The posture the warm-up plans start from (default design, assembly mode '+', working mode
#: '++-'), and a goal beyond a sphere so that OMPL searches (the direct motion is blocked).
_START = (0.2, 1.0, 2.0)
_GOAL = (1.0, 1.0, 2.0)
_SPHERE = ((0.623, -0.013, -0.426), 0.08)
#: A point of the start's workspace reached in working mode '+--': one transit away.
_MODE_CHANGE_POINT = (0.73924837, -0.01303587, -0.14985306)


def _plan_ompl(state: _State) -> None:
    """OMPL's import and first solve: a plan around a sphere (RRT-Connect, seeded)."""
    from planner.geometry import Sphere
    from planner.planning import JointPosture, PlanOptions, plan
    from planner.validity import Margins

    centre, radius = _SPHERE
    obstacles, margins = [Sphere(np.array(centre), radius)], Margins(clearance=0.01)
    result = plan(
        state.design,
        JointPosture(np.array(_START), "+"),
        JointPosture(np.array(_GOAL), "+"),
        obstacles=obstacles,
        margins=margins,
        options=PlanOptions(seed=1, time_budget_s=2.0),
    )
    state.plans.append((result, obstacles, margins))
    # the compiled RRT-Connect (its search, vertex reduction and shortcuts) and OMPL's own
    # search, each once: the plan above may have ended with the straight motion
    from planner.planning import compiled_rrt, ompl_backend
    from planner.validity import ValidityChecker

    chk = ValidityChecker(state.design, margins, obstacles, "+", "++-")
    start, goal = np.array(_START), np.array(_GOAL)
    out = compiled_rrt.rrt_connect(chk, start, goal, PlanOptions(seed=1), 2.0)
    if out is not None and out.waypoints is not None:
        # the walk's recall of a remembered path (its compiled kernel; nothing remembered)
        from planner.planning import experience

        experience.load_kernels(chk, out.waypoints, compiled_rrt.SIMPLIFY_SLACK)
    ompl_backend.search(chk, start, goal, PlanOptions(seed=1), 0.05)


#: A point cloud of :data:`_CLOUD_SIDE` ^ 2 points 2 cm apart (above
#: :data:`planner.spatial_index.TREE_FROM`: packed with a tree and a grid), on the plane
#: z = -0.8 m below the arm, each a ball of 1.5 cm (a depth camera's floor).
_CLOUD_SIDE = 33


def _plan_cloud(state: _State) -> None:
    """A plan among a point cloud (and a sphere): its tree built (its kernel compiled), its
    tree and grid walked by the validity kernels."""
    from planner.geometry import Points, Sphere
    from planner.planning import JointPosture, PlanOptions, plan

    g = 0.02 * (np.arange(_CLOUD_SIDE) - _CLOUD_SIDE // 2)
    x, y = (a.ravel() for a in np.meshgrid(g, g, indexing="ij"))
    cloud = Points(np.column_stack([x, y, np.full(x.size, -0.8)]), 0.015)
    centre, radius = _SPHERE
    plan(
        state.design,
        JointPosture(np.array(_START), "+"),
        JointPosture(np.array(_GOAL), "+"),
        obstacles=[Sphere(np.array(centre), radius), cloud],
        options=PlanOptions(seed=1, time_budget_s=2.0),
    )


def _plan_mode_change(state: _State) -> None:
    """The mode-change search: a Cartesian goal in another working mode, through a transit."""
    from planner.planning import CartesianTarget, JointPosture, PlanOptions, plan
    from planner.validity import Margins

    result = plan(
        state.design,
        JointPosture(np.array(_START), "+"),
        CartesianTarget(np.array(_MODE_CHANGE_POINT), "+--"),
        options=PlanOptions(seed=1, time_budget_s=2.0),
    )
    state.plans.append((result, (), Margins()))


def _region_map(state: _State) -> None:
    """The region map the planner consults before a search (default design and margins,
    :data:`planner.planning.proofs.PROOF_RESOLUTION`): its kernels compiled and the map kept
    in this process's cache, so that the first plans of the default design pay nothing."""
    from planner.analysis.regions import region_map
    from planner.planning.proofs import PROOF_RESOLUTION
    from planner.validity import Margins

    region_map(state.design, Margins(), PROOF_RESOLUTION)


def _obstacle_proof(state: _State) -> None:
    """The proof with obstacles (:mod:`planner.analysis.obstacle_regions`) on a plate the arm
    cannot pass, both grid levels: its kernels compiled and the default design's coarser
    maps cached, so that the first stuck search among obstacles pays only the proof; and
    :func:`~planner.analysis.obstacle_regions.cell_states` of that grid (its own kernel)."""
    from planner.analysis.obstacle_regions import (
        LEVELS,
        cell_states,
        prove_disconnected_with_obstacles,
    )
    from planner.geometry import Box, Capsule, Obstacle, Sphere
    from planner.validity import Margins

    scene: list[Obstacle] = [
        Box(np.array([0.65, 0.0, 0.0]), np.array([1.2, 3.0, 0.02])),
        Sphere(np.array([0.0, 0.0, 2.0]), 0.1),
        Capsule(np.array([0.0, 2.0, 2.0]), np.array([0.0, 2.2, 2.0]), 0.05),
    ]
    start = np.array([1.0, 2.0, 1.0])
    # every cell's state at the coarser level (figures and tests read the proof's grid so)
    cell_states(state.design, Margins(), scene, start, "+", *LEVELS[0])
    for level in LEVELS:
        prove_disconnected_with_obstacles(
            state.design,
            Margins(),
            scene,
            start,
            np.array([-1.0, 2.0, 1.0]),
            "+",
            levels=(level,),
        )


def _corridor(state: _State) -> None:
    """The corridor of narrow passages (:mod:`planner.planning.corridor`): a small grid built
    (scipy's labelling loaded) and a path searched on it (its A* compiled)."""
    from planner.geometry import Box
    from planner.planning import PlanOptions, corridor
    from planner.validity import Margins, ValidityChecker

    checker = ValidityChecker(
        state.design,
        Margins(),
        [Box(np.array([0.0, 0.0, 0.9]), np.array([0.2, 0.2, 0.2]))],
        "+",
        "+-+",
    )
    grid = corridor.corridor_grid(checker, (8, 16, 16))
    assert grid is not None, "a grid without a time limit is always built"
    marked = np.argwhere(grid.labels == grid.labels.max())
    if len(marked) >= 2:
        a, b = grid.centres(marked[[0, -1]])
        corridor.corridor_path(
            checker, grid, a, b, options=PlanOptions(), deadline=time.monotonic() + 1.0
        )


def _time_plans(state: _State, method: Literal["toppra", "ruckig"]) -> None:
    """Time every path found as :func:`planner.solve` does (the pipeline's timing step,
    :func:`planner.motion.time_planned`: the path's own rules re-checked densely), coming to
    rest at the transits of the mode-change path."""
    from planner.motion import MotionProblem, Planned, path_timing, time_planned
    from planner.planning import JointPosture
    from planner.solver import GoalMotion
    from planner.timing import JointLimits, TimingOptions, time_path

    for result, obstacles, margins in state.plans:
        if result.path is None:  # a budget too short on a very slow machine: time a line
            time_path(state.design, np.array([_START, _GOAL]), JointLimits.default(), method=method)
            continue
        timing = TimingOptions(method=method, stop_at_transits=bool(result.path.transits))
        start = JointPosture(result.path.waypoints[0], result.path.segments[0].assembly_mode)
        problem = MotionProblem.of(
            state.design, start, obstacles=obstacles, margins=margins, timing=timing
        )
        request = path_timing(problem, result.path)
        planned = Planned(result.status, result.message, result, request)
        timed = time_planned(problem, request)
        if timed.error is not None:
            raise timed.error
        GoalMotion(JointPosture(result.path.waypoints[-1])).answer(problem, planned, timed)


def _stop(state: _State) -> None:
    """A stop mid-motion (:func:`planner.timing.braking.stop_trajectory`) of a timed line,
    along its path and by a Ruckig brake: a stream's or ``/v1/stop``'s first brake then takes
    its millisecond, not the imports and first dispatches (a stream's stop margin is twice
    its last brake's time)."""
    from planner.timing import JointLimits, time_path
    from planner.timing.braking import stop_trajectory
    from planner.timing.running import RunningTrajectory
    from planner.validity import ValidityChecker

    timed = time_path(state.design, np.array([_START, _GOAL]), JointLimits.default())
    t = np.linspace(0.0, timed.duration, 50)
    q, qd, qdd, _ = timed.at(t)
    running = RunningTrajectory.of(t, q, qd, qdd)
    rules = ValidityChecker(state.design, assembly_mode="+", serial_rules=False).is_valid
    for jerk_limited in (False, True):
        stop_trajectory(
            running,
            0.5 * timed.duration,
            design=state.design,
            assembly_mode="+",
            limits=JointLimits.default(),
            path_rules=rules,
            brake_rules=rules,
            jerk_limited=jerk_limited,
        )


def _straight(state: _State) -> None:
    """A straight tool path (:func:`planner.cartesian.plan.plan_cartesian`): the pre-check,
    the probes (this line meets a serial margin at 58 %: the bisection too), the certified
    refinement, its timing and the answer's compiled deviation measure
    (:func:`planner.cartesian.walk.max_deviation_along`), which no other step runs."""
    from planner.cartesian.plan import plan_cartesian
    from planner.kinematics import forward_batch
    from planner.planning import JointPosture

    start = JointPosture(np.asarray(_START), "+")
    p0 = forward_batch(state.design, np.asarray(_START), "+").p[0]
    goal = (p0 + np.array([0.0, 0.05, 0.0]))[None]
    plan_cartesian(state.design, start, goal, cartesian_speed=0.25)


def _analysis(state: _State) -> None:
    """The workspace analysis (the design check: closed-form and sampled volumes, the
    conditioning; sections, loci) and scipy's optimiser."""
    from planner.analysis.design_check import check_design
    from planner.analysis.optimize import optimize_design
    from planner.analysis.sections import cartesian_section, joint_section

    check_design(state.design, rel_se=0.1, kappa_max=10.0, seed=0)
    cartesian_section(state.design, 16)
    joint_section(state.design, 16)
    optimize_design("volume", reach=0.8)


def _figures(state: _State) -> None:
    """matplotlib's import, font cache and first render, with the Agg backend: a PNG of the
    loci and an SVG of a section (the two kinds of figure the figure endpoints draw)."""
    os.environ.setdefault("MPLBACKEND", "Agg")  # headless workers: never an interactive GUI
    from planner.plotting import render_figure

    render_figure("working_modes", state.design, n=16, fmt="png", dpi=20)
    render_figure("cartesian_section", state.design, n=16, fmt="svg", dpi=20)


@dataclass(frozen=True)
class Step:
    """One named step of :func:`warm_up` (its name is what progress displays show)."""

    name: str
    run: Callable[[_State], None]


#: The steps of :func:`warm_up`, in order (each may use what the steps before it left).
STEPS: tuple[Step, ...] = (
    Step("numba kernels: kinematics", _kinematics),
    Step("numba kernels: inverse dynamics", _dynamics),
    Step("numba kernels: validity and clearance", _validity),
    Step("region map: the default design's", _region_map),
    Step("region map with obstacles: a wall's proof", _obstacle_proof),
    Step("corridor: a grid and a path on it", _corridor),
    Step("OMPL: a plan around an obstacle", _plan_ompl),
    Step("OMPL: a working-mode change", _plan_mode_change),
    Step("OMPL: a plan among a point cloud", _plan_cloud),
    Step("toppra: timing the plans", lambda state: _time_plans(state, "toppra")),
    Step("ruckig: timing the plans", lambda state: _time_plans(state, "ruckig")),
    Step("a stop mid-motion: along the path and by a brake", _stop),
    Step("a straight line: certified, timed and measured", _straight),
    Step("analysis: workspace, sections, optimiser", _analysis),
    Step("matplotlib: a PNG and an SVG figure", _figures),
)


def warm_up(progress: Progress | None = None) -> float:
    """Run every step of :data:`STEPS` once on a tiny input; returns the seconds it took.

    ``progress(step_name, index, total)``, if given, is called before each step with the
    steps finished so far, and once at the end with ``("ready", total, total)``, so that a
    caller can show what is being warmed up and how far it is. Calling it again in the same
    process is cheap (everything is loaded), so callers need not remember whether they did.
    """
    t0 = time.perf_counter()
    state = _State()
    total = len(STEPS)
    with quiet_library_logs():
        for index, step in enumerate(STEPS):
            if progress is not None:
                progress(step.name, index, total)
            step.run(state)
    if progress is not None:
        progress("ready", total, total)
    return time.perf_counter() - t0


@contextmanager
def quiet_library_logs() -> Iterator[None]:
    """The library's INFO lines off while warming up: its probe plans are nobody's plans
    (an operator would read "plan unreachable" at every worker start); warnings still show."""
    root = logging.getLogger("planner")
    level = root.level
    root.setLevel(max(level, logging.WARNING))
    try:
        yield
    finally:
        root.setLevel(level)
