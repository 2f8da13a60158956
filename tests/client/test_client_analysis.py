"""Client methods workspace, figure, timing and optimize_design: what they send (scripted
answers) and what they return from a real service (the ``live_server`` fixture)."""

from __future__ import annotations

import asyncio
import json
import math

import httpx
import numpy as np
import pytest

import planner
from planner.client import AsyncPlannerClient, InvalidRequestError, NotFoundError, PlannerClient
from planner.wire import DesignOptimizeResponse, TimingResponse, WorkspaceResponse

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


class Script:
    """A MockTransport handler answering one fixed response and recording the requests."""

    def __init__(self, answer: httpx.Response) -> None:
        self.answer = answer
        self.requests: list[httpx.Request] = []

    def __call__(self, request: httpx.Request) -> httpx.Response:
        self.requests.append(request)
        return self.answer


def test_figure_sends_the_design_as_query_parameters_and_returns_bytes():
    script = Script(httpx.Response(200, content=b"<svg/>", headers={"content-type": "image/svg"}))
    with PlannerClient("http://x", transport=httpx.MockTransport(script)) as c:
        out = c.figure("joint_section", "svg", design=planner.Design.paper_optimum(), dpi=50)
    assert out == b"<svg/>"
    (req,) = script.requests
    assert req.url.path == "/v1/figures/joint_section.svg"
    assert dict(req.url.params) == {"L0": "0.0", "L1": "0.4", "L2": "0.4", "dpi": "50"}


def test_bad_figure_arguments_are_refused_locally():
    script = Script(httpx.Response(200))
    with PlannerClient("http://x", transport=httpx.MockTransport(script)) as c:
        with pytest.raises(InvalidRequestError):
            c.figure("cartesian_section", "jpg")
        with pytest.raises(InvalidRequestError) as info:
            c.figure("cartesian_section", design={"L1": -1})
        assert info.value.detail[0]["loc"] == ["L1"]
    assert script.requests == []


def test_timing_and_workspace_send_only_what_is_given():
    answer = {"status": "infeasible", "message": "x"}
    script = Script(httpx.Response(200, json=answer))
    with PlannerClient("http://x", transport=httpx.MockTransport(script)) as c:
        out = c.timing(np.array([[0, 1, 2], [0.1, 1, 2]]), limits={"velocity": np.ones(3)})
    assert isinstance(out, TimingResponse) and out.status == "infeasible"
    body = json.loads(script.requests[0].content)
    assert body == {
        "waypoints": [[0, 1, 2], [0.1, 1, 2]],
        "design": {},
        "method": "toppra",
        "limits": {"velocity": [1, 1, 1]},
    }
    with PlannerClient("http://x", transport=httpx.MockTransport(script)) as c:
        with pytest.raises(InvalidRequestError) as info:
            c.timing([[0, 1, 2], [0, 1, 2]], limits={"velocity": [1, 0, 1]})
        assert info.value.detail[0]["loc"] == ["limits", "velocity", 1]
        with pytest.raises(InvalidRequestError) as info:
            c.workspace(resolution=1)
        assert info.value.detail[0]["loc"] == ["sections", "resolution"]
    assert len(script.requests) == 1


def test_live_workspace_timing_optimize_figure(live_server):
    with PlannerClient(live_server, timeout=60) as c:
        ws = c.workspace({"L0": 0.0, "L1": 0.4, "L2": 0.4}, resolution=8, rel_se=0.05)
        assert isinstance(ws, WorkspaceResponse)
        assert ws.volume == pytest.approx(4 / 3 * math.pi * 0.8**3)
        assert len(ws.cartesian_section.reached) == 8 and ws.joint_section.labels == ["+", "-"]
        tr = c.timing([[0.0, 0.5, 1.0], [0.4, 0.9, 1.2]], method="ruckig")
        assert tr.status == "solved" and tr.trajectory.jerk is not None
        opt = c.optimize_design("volume", reach=0.6)
        assert isinstance(opt, DesignOptimizeResponse)
        assert opt.design.L1 == pytest.approx(0.3, abs=1e-3)
        png = c.figure("cartesian_section", design={"L0": 0.3}, resolution=16, dpi=20)
        assert png.startswith(PNG_MAGIC)
        with pytest.raises(NotFoundError) as info:
            c.figure("fig99")
        assert "cartesian_section" in info.value.message
        with pytest.raises(InvalidRequestError) as info:
            c.timing([[0, 1, 2], [0, 1, 3.3]])  # beyond the default joint limit pi
        assert info.value.detail[0]["loc"] == ["body", "waypoints", 1, 2]


def test_live_async_client_same_answers(live_server):
    async def run() -> tuple[bytes, TimingResponse]:
        async with AsyncPlannerClient(live_server, timeout=60) as c:
            return await asyncio.gather(
                c.figure("joint_section", "svg", resolution=16),
                c.timing([[0.0, 0.5, 1.0], [0.4, 0.9, 1.2]]),
            )

    svg, tr = asyncio.run(run())
    assert b"<svg" in svg[:500]
    with PlannerClient(live_server, timeout=60) as c:
        assert c.timing([[0.0, 0.5, 1.0], [0.4, 0.9, 1.2]]).trajectory.duration == pytest.approx(
            tr.trajectory.duration
        )
