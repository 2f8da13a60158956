"""``planner calibrate`` and ``planner identify``: kinematic calibration and dynamic
identification run in this process (their JSON printed as ``POST /v1/calibrate`` and
``POST /v1/identify`` answer it), the postures worth measuring (``--suggest N``), and the
identified model written as JSON and MJCF with its provenance (``docs/calibration.md``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import typer

from planner_cli.common import DesignOption, L0Option, L1Option, L2Option, design_data
from planner_cli.errors import fail

__all__ = ["calibrate", "identify"]


def _read(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        fail([f"cannot read a JSON body from {str(path)!r}: {exc}"])


def calibrate(
    file: Annotated[
        Path | None,
        typer.Argument(
            help="A JSON body of POST /v1/calibrate, or a JSON list of measurements "
            '({"q": [3], "p": [3], ...}) calibrated against --design.'
        ),
    ] = None,
    suggest: Annotated[
        int | None,
        typer.Option(help="Print N postures worth measuring instead (no FILE).", min=1),
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of --suggest's sample.", min=0)] = 0,
    output: Annotated[
        Path | None, typer.Option(help="Also write the identified model's JSON here.")
    ] = None,
    mjcf: Annotated[
        Path | None, typer.Option(help="Also write the identified design as MJCF here.")
    ] = None,
    design: DesignOption = "default",
    l0: L0Option = None,
    l1: L1Option = None,
    l2: L2Option = None,
) -> None:
    """Calibrate the kinematics from measurements, or suggest postures to measure.

    Prints the JSON of POST /v1/calibrate (identified design, offsets, tracker frame,
    residuals, std, condition number, unidentified parameters, provenance). Examples:
    planner calibrate --suggest 40 > poses.json;  planner calibrate body.json --mjcf robot.xml"""
    from planner.endpoints import calibration as jobs
    from planner.wire.calibration import CalibrateRequest, CalibrationPosesRequest

    nominal = design_data(design, l0, l1, l2)
    if suggest is not None:
        if file is not None:
            fail(["give FILE or --suggest N, not both"])
        req = CalibrationPosesRequest.model_validate(
            {"design": nominal, "n": suggest, "seed": seed}
        )
        typer.echo(jobs.calibration_poses(req).model_dump_json(indent=2))
        return
    if file is None:
        fail(["give FILE (a body of POST /v1/calibrate or a list of measurements) or --suggest"])
    data = _read(file)
    body = {"design": nominal, "measurements": data} if isinstance(data, list) else data
    request = CalibrateRequest.model_validate(body)
    answer = jobs.calibrate(request)
    text = answer.model_dump_json(indent=2)
    typer.echo(text)
    if output is not None:
        output.write_text(text + "\n")
    if mjcf is not None:
        mjcf.write_text(jobs.calibration_mjcf(answer, inertia_design=request.design))


def identify(
    file: Annotated[Path, typer.Argument(help="A JSON body of POST /v1/identify.")],
    output: Annotated[Path | None, typer.Option(help="Also write the answer's JSON here.")] = None,
) -> None:
    """Identify the inertial parameters (and friction) from measured q, qd, qdd, tau.

    Prints the JSON of POST /v1/identify: the identified design.inertia, friction when the
    body asks ("friction": true), the residual and the parameters held at their priors."""
    from planner.endpoints.calibration import identify as job
    from planner.wire.calibration import IdentifyRequest

    text = job(IdentifyRequest.model_validate(_read(file))).model_dump_json(indent=2)
    typer.echo(text)
    if output is not None:
        output.write_text(text + "\n")
