"""POST /v1/calibrate, /v1/calibrate/poses and /v1/identify: the model from measurements
(docs/calibration.md), computed in a worker."""

from __future__ import annotations

from fastapi import APIRouter, Response

from planner.endpoints import calibration as jobs
from planner.wire.calibration import (
    CalibrateRequest,
    CalibrateResponse,
    CalibrationPosesRequest,
    CalibrationPosesResponse,
    IdentifyRequest,
    IdentifyResponse,
)
from planner_api.deps import Deadline, Pool, SettingsDep
from planner_api.routes._common import run_job

__all__ = ["calibrate", "calibration_poses", "identify", "router"]

router = APIRouter(prefix="/v1", tags=["calibration"])


@router.post("/calibrate", response_model=CalibrateResponse)
async def calibrate(
    body: CalibrateRequest, pool: Pool, deadline: Deadline, settings: SettingsDep
) -> Response:
    """Kinematic calibration: the nominal design and measured points P (tracker frame) of
    commanded postures -> the identified L0, L1, L2 (or each leg's), actuator zero offsets
    and tracker frame, with residuals, standard deviations, the condition number and the
    parameters the data cannot identify (held at nominal, named)."""
    return await run_job(
        pool, jobs.calibrate, body, deadline, design_defaults=settings.design_defaults
    )


@router.post("/calibrate/poses", response_model=CalibrationPosesResponse)
async def calibration_poses(
    body: CalibrationPosesRequest, pool: Pool, deadline: Deadline, settings: SettingsDep
) -> Response:
    """``n`` postures worth measuring for a calibration (greedy D-optimal over the valid
    set, spread over the working modes), each with its modes."""
    return await run_job(
        pool, jobs.calibration_poses, body, deadline, design_defaults=settings.design_defaults
    )


@router.post("/identify", response_model=IdentifyResponse)
async def identify(
    body: IdentifyRequest, pool: Pool, deadline: Deadline, settings: SettingsDep
) -> Response:
    """Dynamic identification: measured q, qd, qdd, tau (N x 3) -> the inertial parameters
    the data determine (a design.inertia), the rest held at their priors and named;
    friction per actuator with ``friction: true``."""
    return await run_job(
        pool, jobs.identify, body, deadline, design_defaults=settings.design_defaults
    )
