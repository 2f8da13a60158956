"""Both clients against a real service process (``planner serve`` under uvicorn, two
workers, on a free loopback port: the ``live_server`` fixture)."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

import planner
from planner.client import (
    AsyncPlannerClient,
    InvalidRequestError,
    PlannerClient,
)
from planner.wire import AnalyzeResponse, DesignsResponse, FKResponse, IKResponse

START = {"q": [0.0, 1.0, 2.0], "assembly_mode": "+"}


def test_sync_client_every_endpoint(live_server):
    with PlannerClient(live_server, timeout=30) as c:
        assert c.health().status == "ok"
        assert c.version().version == planner.__version__
        designs = c.designs()
        assert isinstance(designs, DesignsResponse) and designs.presets[0].name == "default"
        fk = c.fk([0.2, 1.0, 2.0])
        assert isinstance(fk, FKResponse) and len(fk.postures) == 2
        ik = c.ik(fk.postures[0].p)
        assert isinstance(ik, IKResponse)
        # the posture fk gave is one of ik's answers for its own point
        assert any(np.allclose(p.q, fk.postures[0].q, atol=1e-9) for p in ik.postures)
        analysis = c.analyze([0.2, 1.0, 2.0], "+", qd=[0.1, 0.2, 0.3])
        assert isinstance(analysis, AnalyzeResponse)
        assert analysis.kappa_A == pytest.approx(np.linalg.cond(np.array(analysis.A)), rel=1e-9)
        verdict = c.check_design(planner.Design.paper_optimum(), rel_se=0.05)
        assert verdict.singularity_free is False and "C=D" in verdict.parallel_singularities
        # design objects travel: the paper optimum has L0 = 0, so A = B at the origin
        po = c.fk([0.0, 1.0, 2.0], "+", design=planner.Design.paper_optimum())
        assert po.postures[0].points["A"] == po.postures[0].points["B"] == [0.0, 0.0, 0.0]


def test_sync_client_server_errors(live_server):
    with PlannerClient(live_server, timeout=30) as c:
        with pytest.raises(InvalidRequestError) as info:
            c.analyze([0.0, 0.7, 0.7], "+", design={"L0": 0.0, "L1": 0.4, "L2": 0.4})
        assert info.value.status_code == 422
        assert info.value.detail[0]["loc"] == ["body", "q"]
        result = c.plan(
            start=START, goal={"q": [0.3, 1.1, 2.1], "assembly_mode": "+"}, planner={"seed": 1}
        )
        assert result.status == "solved", result.message
        assert result.path.waypoints[0] == pytest.approx(START["q"])
        assert result.path.waypoints[-1] == pytest.approx([0.3, 1.1, 2.1])


def test_async_client_concurrent_requests(live_server):
    async def scenario():
        async with AsyncPlannerClient(live_server, timeout=30) as c:
            assert (await c.health()).status == "ok"
            qs = [[0.1 * i, 1.0, 2.0] for i in range(8)]
            answers = await asyncio.gather(*(c.fk(q, "+") for q in qs))
            ready = await c.ready()
            return qs, answers, ready

    qs, answers, ready = asyncio.run(scenario())
    assert ready.workers == 2
    for q, answer in zip(qs, answers, strict=True):
        (posture,) = answer.postures
        assert posture.q == pytest.approx(q)
        # theta1 only turns the plane: |P - (0, y, 0)| is the same for every q here
        assert np.hypot(posture.p[0], posture.p[2]) == pytest.approx(
            np.hypot(answers[0].postures[0].p[0], answers[0].postures[0].p[2]), rel=1e-12
        )
