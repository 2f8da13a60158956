"""Jobs and a launcher for the operations tests: module-level (picklable) plan functions that
the worker processes can import, and a server entry point that serves one of them."""

from __future__ import annotations

import logging
import os
import sys
import time

from planner.endpoints import UNBOUNDED, JobBudget
from planner.wire import DiagnosticsModel, PlanRequest, PlanResponse

logger = logging.getLogger("tests.ops_jobs")


def timed_outcome(request: PlanRequest, budget: JobBudget = UNBOUNDED) -> PlanResponse:
    """A plan answer whose status and durations come from the request: ``planner.seed``
    picks the status, ``planner.time_budget_s`` is reported as the planning time, a tenth of
    it as the timing time."""
    statuses = ("solved", "no_path", "unreachable", "invalid_start", "invalid_goal", "timeout")
    seconds = request.planner.time_budget_s
    return PlanResponse(
        status=statuses[(request.planner.seed or 0) % len(statuses)],
        diagnostics=DiagnosticsModel(planning_time_s=seconds, timing_time_s=seconds / 10),
    )


def sleep_pid(request: PlanRequest, budget: JobBudget = UNBOUNDED) -> PlanResponse:
    """Sleep ``planner.time_budget_s`` seconds, log a line, answer with the worker's pid (also
    written to the file named by the environment variable OPS_PID_FILE, when set)."""
    pid_file = os.environ.get("OPS_PID_FILE")
    if pid_file:
        with open(pid_file, "w") as f:
            f.write(str(os.getpid()))
    logger.warning("sleeping %.2f s", request.planner.time_budget_s)
    time.sleep(request.planner.time_budget_s)
    return PlanResponse(status="timeout", message=str(os.getpid()))


def scene_obstacle_count(request: PlanRequest, budget: JobBudget = UNBOUNDED) -> PlanResponse:
    """Sleep ``planner.time_budget_s`` seconds, then answer with the number of obstacles the
    request carries from its named scene and its own (in ``message``): what the job sees of
    a scene that may change while it runs."""
    from planner.wire import scene_obstacles

    time.sleep(request.planner.time_budget_s)
    return PlanResponse(status="no_path", message=str(len(scene_obstacles(request))))


def serve(job_name: str | None, *, warm_up: bool = True) -> None:
    """Serve the app of the environment's settings with the plan job ``job_name`` of this
    module (``python -c 'import ops_jobs; ops_jobs.serve("sleep_pid")'``; None: the real
    plan job), its workers warmed up unless ``warm_up`` is False (as ``planner serve`` does:
    :func:`planner_api.server.run`)."""
    from planner_api.app import create_app
    from planner_api.routes.plan import get_plan_function
    from planner_api.server import run
    from planner_api.settings import Settings

    settings = Settings()
    app = create_app(settings, warm_up=warm_up)
    if job_name is not None:
        job = getattr(sys.modules[__name__], job_name)
        app.dependency_overrides[get_plan_function] = lambda: job
    run(settings, app)
