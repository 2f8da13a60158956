"""Every long loop of the library checks its deadline: the issue's reproducers (a Cartesian
path over 1000 m links through 50 far waypoints, a design optimisation over 8192 samples, a
region map) stop with :class:`DeadlineError` soon after the deadline instead of running for
minutes, and the service's jobs hand the request's deadline to the library.

Bounds are the property's (deadline + a generous slack), never a speed; the reference runs
are what the same calls take without a deadline (measured: the Cartesian path over 200 s,
the optimisation over 40 s on the machine of the issue).
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from planner.analysis.optimize import optimize_design
from planner.analysis.regions import cached_region_map, region_map
from planner.cartesian.plan import plan_cartesian
from planner.design import Design
from planner.exceptions import DeadlineError
from planner.planning.problem import JointPosture
from planner.validity import Margins

#: Slack on top of a deadline, s: one chunk of probes, one evaluation, on a loaded machine.
SLACK_S = 5.0
HUGE = Design(0.0, 1000.0, 1000.0)
START = JointPosture((0.3, 2.0, 1.0), "+")
FAR = np.random.default_rng(0).uniform(-1500.0, 1500.0, size=(50, 3))
#: A short straight path of the default robot (tests/service/test_api_cartesian.py's start).
SMALL_START = JointPosture((-0.2187, 2.8609, 0.2807), "+")
SMALL_WAYPOINT = np.array([[0.45, 0.3, 0.1]])


def _huge_cartesian_body() -> dict:
    """The issue's 2 KB ``/v1/cartesian``: 1000 m links, 50 far waypoints, kappa_max 1e6."""
    return {
        "design": {"L0": 0.0, "L1": 1000.0, "L2": 1000.0},
        "start": {"q": list(START.q), "assembly_mode": "+"},
        "waypoints": [[round(float(x), 1) for x in p] for p in FAR],
        "margins": {"kappa_max": 1e6},
    }


def test_a_cartesian_path_over_huge_links_stops_at_its_deadline():
    # the same call, short, first: imports and compiled kernels are not the deadline's
    plan_cartesian(Design.default(), SMALL_START, SMALL_WAYPOINT, timing="none")
    t0 = time.monotonic()
    res = plan_cartesian(HUGE, START, FAR, margins=Margins(kappa_max=1e6), deadline=t0 + 0.5)
    assert time.monotonic() - t0 < 0.5 + SLACK_S
    # the one timeout answer of every kind of motion: a status, not an exception
    assert res.status.value == "timeout" and "deadline passed" in res.message, res.message
    assert res.trajectory is None


def test_a_design_optimisation_stops_at_its_deadline():
    optimize_design("well_conditioned_volume", n_samples=64, maxiter=1)  # imports, kernels
    t0 = time.monotonic()
    with pytest.raises(DeadlineError, match="evaluations done"):
        optimize_design("well_conditioned_volume", n_samples=8192, maxiter=30, deadline=t0 + 0.5)
    assert time.monotonic() - t0 < 0.5 + SLACK_S


def test_a_region_map_past_its_deadline_is_not_built_nor_cached():
    design = Design(0.31, 0.5, 0.6)
    with pytest.raises(DeadlineError):
        region_map(design, n=64, deadline=time.monotonic() - 1.0)
    assert cached_region_map(design, n=64) is None
    assert region_map(design, n=64).n == 64  # without a deadline: built as before


def test_the_service_jobs_pass_their_request_deadline_to_the_library():
    """The endpoints of /v1/cartesian, /v1/design/optimize and /v1/design/regions hand the
    request's deadline (``JobBudget.deadline``) to the library: with one already past, each
    stops at its first check instead of running the issue's requests for minutes (the pool's
    watchdog bounds any other job): a motion answers status ``timeout`` (the one timeout
    answer of the motion pipeline), an analysis raises DeadlineError (a 504 by the error
    table)."""
    from planner.endpoints import JobBudget
    from planner.endpoints.cartesian import cartesian
    from planner.endpoints.design import optimize_design as optimize_job
    from planner.endpoints.design import regions
    from planner.wire import CartesianRequest, DesignOptimizeRequest, RegionsRequest

    past = JobBudget(deadline=time.monotonic() - 1.0)
    t0 = time.monotonic()
    answer = cartesian(CartesianRequest.model_validate(_huge_cartesian_body()), past)
    assert time.monotonic() - t0 < SLACK_S
    assert answer.status == "timeout" and answer.trajectory is None, answer.message
    cases = [
        (optimize_job, DesignOptimizeRequest.model_validate(
            {"objective": "well_conditioned_volume", "n_samples": 8192})),
        (regions, RegionsRequest.model_validate(
            {"design": {"L0": 0.32, "L1": 0.5, "L2": 0.6}, "resolution": 512})),
    ]  # fmt: skip
    for job, request in cases:
        t0 = time.monotonic()
        with pytest.raises(DeadlineError):
            job(request, past)
        assert time.monotonic() - t0 < SLACK_S, job.__name__
