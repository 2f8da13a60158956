"""POST /v1/simulate: a trajectory (or a plan or sequence request, planned first) run on the
simulated robot, computed in a worker (the job: :func:`planner.endpoints.simulate.simulate`).

The inner ``request`` is held to the limits of its own route (the sequence's targets, the
search budget, the obstacles; located under ``request``), its design completed from the
service's default robot and its named scene resolved, as ``/v1/plan`` and ``/v1/sequence``
do."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request, Response

from planner.endpoints import answer_sample_limit
from planner.endpoints import simulate as jobs
from planner.wire import DesignModel, SequenceRequest, SimulateRequest, SimulateResponse
from planner_api.deps import Deadline, Pool, SettingsDep
from planner_api.exceptions import LimitExceededError
from planner_api.routes._common import run_job, with_design_defaults
from planner_api.routes.plan import check_limits
from planner_api.routes.scenes import resolve_scene
from planner_api.routes.sequence import prepare_sequence
from planner_api.routes.worker_body import (
    BodySpec,
    RouteLimits,
    WorkerBodyRoute,
    parsed_in_worker,
)

__all__ = ["prepare_simulate", "resolve_inner_scene", "router", "simulate"]

router = APIRouter(prefix="/v1", tags=["dynamics"], route_class=WorkerBodyRoute)


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
@parsed_in_worker(
    BodySpec(SimulateRequest, prepare_simulate, lambda _: jobs.simulate, resolve_inner_scene)
)
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
    body = prepare_simulate(body, settings)
    body = await resolve_inner_scene(request, body)
    defaults = settings.design_defaults
    if body.request is not None:
        # the robot is the inner request's: complete its design; the top-level one stays
        # unset (a top-level design given beside `request` is a 422)
        inner = with_design_defaults(body.request, defaults, ("body", "request"))
        body = body.model_copy(update={"request": inner})
        defaults = DesignModel()
    samples = answer_sample_limit(settings.max_trajectory_samples, settings.max_response_bytes)
    return await run_job(
        pool,
        jobs.simulate,
        body,
        deadline,
        design_defaults=defaults,
        max_samples=samples,
    )
