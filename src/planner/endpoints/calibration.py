"""The jobs of ``/v1/calibrate``, ``/v1/calibrate/poses`` and ``/v1/identify``: kinematic
calibration, the postures to measure, and dynamic identification (``docs/calibration.md``)."""

from __future__ import annotations

import numpy as np

from planner.endpoints import UNBOUNDED, JobBudget
from planner.wire import located
from planner.wire.calibration import (
    CalibrateRequest,
    CalibrateResponse,
    CalibrationPosesRequest,
    CalibrationPosesResponse,
    IdentifyRequest,
    IdentifyResponse,
    calibrate_inputs,
    calibrate_response,
    identify_inputs,
    identify_response,
    poses_response,
)

__all__ = ["calibrate", "calibration_mjcf", "calibration_poses", "identify"]


def calibrate(request: CalibrateRequest, budget: JobBudget = UNBOUNDED) -> CalibrateResponse:
    """``POST /v1/calibrate``: :func:`planner.calibration.calibrate` of the request (a
    measurement whose q does not assemble, or whose measured mode no branch has, is a 422
    naming ``measurements.<i>``; too few measurements a 422 at ``measurements``)."""
    from planner.calibration import calibrate as run

    design, measurements, frame = calibrate_inputs(request)
    with located("body"):
        result = run(design, measurements, identify=request.identify, frame=frame)
    return calibrate_response(result, list(request.identify))


def calibration_poses(
    request: CalibrationPosesRequest, budget: JobBudget = UNBOUNDED
) -> CalibrationPosesResponse:
    """``POST /v1/calibrate/poses``: :func:`planner.calibration.suggest_poses`."""
    from planner.calibration import suggest_poses

    with located("body"):
        poses = suggest_poses(
            request.design.to_design(), request.n, identify=request.identify, seed=request.seed
        )
    return poses_response(poses)


def identify(request: IdentifyRequest, budget: JobBudget = UNBOUNDED) -> IdentifyResponse:
    """``POST /v1/identify``: :func:`planner.dynamics.identify.identify_inertia` (a posture
    that does not assemble or is singular is a 422 naming ``q.<i>``; too few samples a 422 at
    ``tau``)."""
    from planner.dynamics.identify import identify_inertia

    design, prior = identify_inputs(request)
    with located("body"):
        result = identify_inertia(
            design,
            np.asarray(request.q, dtype=float),
            np.asarray(request.qd, dtype=float),
            np.asarray(request.qdd, dtype=float),
            np.asarray(request.tau, dtype=float),
            assembly_mode=request.assembly_mode,
            gravity=request.gravity,
            prior=prior,
            friction=request.friction,
        )
    return identify_response(result)


def calibration_mjcf(answer: CalibrateResponse, *, inertia_design: object = None) -> str:
    """The identified design as MJCF (:func:`planner.dynamics.mjcf.to_mjcf`, the default
    inertia of the identified lengths unless ``inertia_design``, a :class:`DesignModel` with
    ``inertia``, gives one), with its provenance as an XML comment after the root element:
    measurement count, residuals, date, the offsets to add to commanded joints, the tracker's
    frame and, with the legs apart, their four lengths (MJCF gets their means: the product's
    model is symmetric)."""
    from planner.dynamics.mjcf import to_mjcf
    from planner.wire import DesignModel, inertia_to_core

    model = DesignModel.model_validate(answer.design.model_dump())
    inertia = None
    if isinstance(inertia_design, DesignModel) and inertia_design.inertia is not None:
        model = model.model_copy(update={"inertia": inertia_design.inertia})
        inertia = inertia_to_core(model)
    text = to_mjcf(model.to_design(), inertia)
    prov = answer.provenance
    legs = f"; leg lengths (m) {answer.leg_lengths}" if answer.leg_lengths else ""
    comment = (
        f"<!-- identified by planner calibrate on {prov.date} from {prov.measurements} "
        f"measurements ({', '.join(prov.identify)}): residual rms {prov.residual_rms_m:.3e} m, "
        f"max {prov.residual_max_m:.3e} m; joint offsets (add to commanded q, rad) "
        f"{[round(x, 12) for x in answer.offsets]}; tracker frame position "
        f"{[round(x, 12) for x in answer.frame.position]} m, rotation vector "
        f"{[round(x, 12) for x in answer.frame.rotation]} rad; unidentified (held at nominal) "
        f"{answer.unidentified}{legs} -->"
    )
    head, _, rest = text.partition("\n")
    return f"{head}\n{comment}\n{rest}"
