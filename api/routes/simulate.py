"""POST /v1/simulate: a trajectory (or a plan or sequence request, planned first) run on the
simulated robot, computed in a worker (the job: :func:`planner.endpoints.simulate.simulate`);
POST /v1/simulate/bag: the same run as a ROS 2 bag.

The inner ``request`` is held to the limits of its own route (the sequence's targets, the
search budget, the obstacles; located under ``request``), its design completed from the
service's default robot and its named scene resolved, as ``/v1/plan`` and ``/v1/sequence``
do.

The body is parsed on the event loop (FastAPI's path), not in a worker as the plan routes'
large bodies are (:mod:`planner_api.routes.worker_body`): that path completes only a body's
own design and resolves only its own scene, where this route must do both for the inner
request. A trajectory is bounded (100,000 samples, ~10 MB of JSON, as ``/v1/dynamics``'s
postures)."""

from __future__ import annotations

from functools import partial
from typing import Any

from fastapi import APIRouter, Request, Response

from planner.endpoints import JobBudget, answer_sample_limit
from planner.endpoints import simulate as jobs
from planner.wire import (
    BAG_MEDIA_TYPE,
    DesignModel,
    SequenceRequest,
    SimulateRequest,
    SimulateResponse,
)
from planner_api.deps import Deadline, Pool, SettingsDep
from planner_api.exceptions import LimitExceededError
from planner_api.routes._common import run_job, with_design_defaults
from planner_api.routes.plan import check_limits
from planner_api.routes.scenes import resolve_scene
from planner_api.routes.sequence import prepare_sequence
from planner_api.routes.worker_body import RouteLimits

__all__ = ["prepare_simulate", "resolve_inner_scene", "router", "simulate", "simulate_bag"]

router = APIRouter(prefix="/v1", tags=["dynamics"])


def prepare_simulate(body: SimulateRequest, limits: RouteLimits) -> SimulateRequest:
    """The simulate route's own checks: an inner request within its route's limits (a
    :class:`LimitExceededError` located under ``request``)."""
    inner = body.request
    if inner is None:
        return body
    if isinstance(inner, SequenceRequest):
        try:
            prepare_sequence(inner, limits)
        except LimitExceededError as exc:
            raise LimitExceededError(exc.message, ("body", "request", *exc.loc[1:])) from None
    else:
        check_limits(inner, limits, ("body", "request"))
    return body


async def resolve_inner_scene(request: Request, body: Any) -> Any:
    """``body`` with its inner request's named scene resolved (unchanged without one)."""
    inner = getattr(body, "request", None)
    if inner is None:
        return body
    return body.model_copy(update={"request": await resolve_scene(request, inner)})


@router.post("/simulate", response_model=SimulateResponse)
async def simulate(
    body: SimulateRequest, pool: Pool, deadline: Deadline, settings: SettingsDep, request: Request
) -> Response:
    """Run a trajectory on the simulated robot: the product's MJCF model in MuJoCo (the
    closed chain, ``design.inertia``, ``gravity``) under ``controller`` (``computed_torque``
    or ``pd``) at ``rate_hz``, the torques clipped at ``limits.torque``. The answer: the
    realised ``t``, ``q``, ``tau``, ``p_error_mm``, the ``tracking`` error, the planned and
    realised durations and the ``settle_times`` of each stop (docs/simulation.md). With
    ``request`` (a plan or sequence request) the motion is planned first and its robot is the
    simulated one. A trajectory sample that does not assemble is a 422 at
    ``trajectory.q.<i>``; an unknown controller at ``controller.kind``."""
    body, defaults = await _prepared(body, settings, request)
    samples = answer_sample_limit(settings.max_trajectory_samples, settings.max_response_bytes)
    return await run_job(
        pool, jobs.simulate, body, deadline, design_defaults=defaults, max_samples=samples
    )


async def _prepared(
    body: SimulateRequest, settings: Any, request: Request
) -> tuple[SimulateRequest, DesignModel]:
    """The body within the limits, its inner request's scene resolved and design completed;
    the design defaults left for the top level (none with ``request``: its robot is the
    inner one's, and a top-level design given beside it is a 422)."""
    body = prepare_simulate(body, settings)
    body = await resolve_inner_scene(request, body)
    defaults = settings.design_defaults
    if body.request is not None:
        inner = with_design_defaults(body.request, defaults, ("body", "request"))
        body = body.model_copy(update={"request": inner})
        defaults = DesignModel()
    return body, defaults


_BAG_RESPONSES: dict[int | str, dict[str, Any]] = {
    200: {"content": {BAG_MEDIA_TYPE: {}}, "description": "The ROS 2 bag (MCAP)."}
}


@router.post("/simulate/bag", response_class=Response, responses=_BAG_RESPONSES)
async def simulate_bag(
    body: SimulateRequest, pool: Pool, deadline: Deadline, settings: SettingsDep, request: Request
) -> Response:
    """The same simulation as ``POST /v1/simulate``, answered as a ROS 2 bag: one MCAP file
    (profile ros2) with the followed trajectory as a ``trajectory_msgs/JointTrajectory`` and
    as ``sensor_msgs/JointState`` samples, the realised ``/joint_states`` and the tracking
    error (``docs/simulation.md``), for ``ros2 bag`` and Foxglove. Bad input: the 422s of
    ``POST /v1/simulate``."""
    body, defaults = await _prepared(body, settings, request)
    body = with_design_defaults(body, defaults)
    samples = answer_sample_limit(settings.max_trajectory_samples, settings.max_response_bytes)
    job = partial(jobs.simulate_bag, budget=JobBudget(deadline, samples))
    content = await pool.run(job, body, deadline=deadline)
    return Response(
        content=content,
        media_type=BAG_MEDIA_TYPE,
        headers={"Content-Disposition": 'attachment; filename="simulation.mcap"'},
    )
