"""The endpoint of ``/v1/simulate``: a trajectory, or a plan or sequence request planned
first, run on the simulated robot (:func:`planner.simulation.simulate`)."""

from __future__ import annotations

from planner.endpoints import UNBOUNDED, JobBudget
from planner.wire import (
    SimulateRequest,
    SimulateResponse,
    TrajectoryModel,
    TrajectoryPointsModel,
    controller_to_core,
    located,
    reference_to_core,
    simulation_bag,
    simulation_response,
    simulation_robot,
    trajectory_arrays,
)

__all__ = ["simulate", "simulate_bag"]


def simulate(request: SimulateRequest, budget: JobBudget = UNBOUNDED) -> SimulateResponse:
    """``POST /v1/simulate``: convert (the robot, the controller, the trajectory: the given
    one, or the inner request's plan, :func:`_planned`), run
    (:func:`planner.simulation.simulate` with the budget's deadline and sample bound),
    respond (:func:`planner.wire.simulation_response`).

    A library error is a 422 naming its field: a trajectory sample that does not assemble
    or is singular at ``trajectory.q.<i>``, too many samples at ``rate_hz``, a robot field
    given beside ``request`` at that field, an inner request that does not solve at
    ``request`` (with its status and message)."""
    from planner.exceptions import InputError
    from planner.simulation import simulate as run

    robot = simulation_robot(request)
    controller = controller_to_core(request.controller)
    planned: TrajectoryModel | None = None
    if request.request is not None:
        planned = _planned(request, budget)
        reference = reference_to_core(planned, ("body", "request", "trajectory"))
        where: tuple[str | int, ...] = ("body", "request")
    elif request.trajectory is not None:
        reference = reference_to_core(request.trajectory)
        where = ("body", "trajectory")
    else:
        with located("body", "trajectory"):
            raise InputError("give a `trajectory` or a `request` to simulate")
    if request.trajectory is not None and request.request is not None:
        with located("body", "trajectory"):
            raise InputError("give a `trajectory` or a `request`, not both")
    try:
        sim = run(
            robot.design,
            reference,
            inertia=robot.inertia,
            controller=controller,
            rate_hz=request.rate_hz,
            torque_limits=robot.torque_limits,
            gravity=robot.gravity,
            assembly_mode=robot.assembly_mode,
            settle_tolerance_mm=request.settle_tolerance_mm,
            hold_s=request.hold_s,
            deadline=budget.deadline,
            max_samples=_sample_bound(budget, planned is not None),
        )
    except InputError as exc:
        field = exc.field_path[:1]
        prefixes: dict[tuple[str | int, ...], tuple[str | int, ...]] = {
            ("q",): where,
            ("torque",): ("body", "limits"),
        }
        prefix = prefixes.get(field, ("body",))
        with located(*prefix):
            raise
    return simulation_response(sim, planned)


def _sample_bound(budget: JobBudget, with_plan: bool) -> int | None:
    """The most simulated samples the answer may carry: the budget's, halved when the answer
    also carries the planned trajectory (about as many samples, at the control rate)."""
    if budget.max_samples is None or not with_plan:
        return budget.max_samples
    return max(2, budget.max_samples // 2)


def _planned(request: SimulateRequest, budget: JobBudget) -> TrajectoryModel:
    """The inner request's trajectory (arrays form), planned by its endpoint with the same
    budget; its ``timing.sample_rate_hz``, when not given, is ``rate_hz`` (the controller
    then reads the plan's own samples). A plan that does not solve: InputError at
    ``request``."""
    from planner.endpoints.plan import plan
    from planner.endpoints.sequence import sequence
    from planner.exceptions import InputError
    from planner.wire import PlanRequest

    inner = request.request
    assert inner is not None
    if "sample_rate_hz" not in inner.timing.model_fields_set:
        timing = inner.timing.model_copy(update={"sample_rate_hz": request.rate_hz})
        inner = inner.model_copy(update={"timing": timing})
    answer = plan(inner, budget) if isinstance(inner, PlanRequest) else sequence(inner, budget)
    if answer.status != "solved" or answer.trajectory is None:
        with located("body", "request"):
            raise InputError(
                f"the request did not solve ({answer.status}): {answer.message}".rstrip(": ")
            )
    traj = answer.trajectory
    return trajectory_arrays(traj) if isinstance(traj, TrajectoryPointsModel) else traj


def simulate_bag(request: SimulateRequest, budget: JobBudget = UNBOUNDED) -> bytes:
    """``POST /v1/simulate/bag``: :func:`simulate`, answered as a ROS 2 bag (MCAP bytes:
    :func:`planner.wire.simulation_bag`, ``docs/simulation.md``)."""
    return simulation_bag(request, simulate(request, budget))
