"""``planner simulate``: the service's simulate job run in this process (a trajectory, or a
plan or sequence request planned first, on the simulated robot), answered by a summary, the
full JSON (``--out``) and a ROS 2 bag (``--bag``, MCAP: ``docs/simulation.md``).

Exit status (:mod:`planner_cli.errors`): 0 simulated and settled, 1 simulated but not
settled at the end (no realised duration), 2 an invalid request.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import typer

from planner_cli._support import Progress
from planner_cli.errors import EXIT_NO_ANSWER, EXIT_OK, fail

__all__ = ["simulate", "simulate_body", "simulate_summary"]


def simulate_body(data: dict[str, Any]) -> dict[str, Any]:
    """The body of ``POST /v1/simulate`` a file stands for: a simulate body as it is; a plan
    or sequence request (``goal`` or ``targets``) as its ``request``; a plan or sequence
    answer (``status`` and ``trajectory``) as its trajectory's ``t``, ``q``, ``qd``,
    ``qdd`` (the arrays form)."""
    if "goal" in data or "targets" in data:
        return {"request": data}
    if "status" in data and isinstance(data.get("trajectory"), dict):
        from pydantic import TypeAdapter

        from planner.wire import AnyTrajectory, trajectory_arrays

        traj = trajectory_arrays(TypeAdapter(AnyTrajectory).validate_python(data["trajectory"]))
        return {"trajectory": traj.model_dump(include={"t", "q", "qd", "qdd"})}
    return data


def simulate(
    request: Annotated[
        Path,
        typer.Argument(
            help="JSON: a body of POST /v1/simulate, a plan or sequence request (planned "
            "first), or a plan or sequence answer (its trajectory)."
        ),
    ],
    controller: Annotated[
        str | None, typer.Option(help="'computed_torque' or 'pd' (default: the file's).")
    ] = None,
    rate_hz: Annotated[
        float | None, typer.Option(help="Control rate, Hz (default: the file's, else 1000).")
    ] = None,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Write the full response JSON here.")
    ] = None,
    bag: Annotated[
        Path | None,
        typer.Option(
            help="Write a ROS 2 bag (MCAP) here: the planned JointTrajectory, the planned and "
            "realised JointStates, the tracking error."
        ),
    ] = None,
) -> None:
    """Run a trajectory on the simulated robot (MuJoCo) in this process, and print a summary.

    Example: planner simulate plan_request.json --controller pd --bag run.mcap"""
    try:
        data = json.loads(request.read_text())
    except (OSError, ValueError) as exc:
        fail([f"cannot read a JSON body from {str(request)!r}: {exc}"])
    if not isinstance(data, dict):
        fail([f"{request}: the JSON must be an object"])
    body = simulate_body(data)
    if controller is not None:
        body["controller"] = {**body.get("controller", {}), "kind": controller}
    if rate_hz is not None:
        body["rate_hz"] = rate_hz
    with Progress("simulate") as progress:
        progress.step("loading the simulator", 0)
        from planner.endpoints.simulate import simulate as job
        from planner.wire import SimulateRequest

        model = SimulateRequest.model_validate(body)
        progress.step("planning" if model.request is not None else "simulating", 0)
        response = job(model)
        progress.done("simulated")
    for line in simulate_summary(response):
        typer.echo(line)
    if out is not None:
        out.write_text(response.model_dump_json(indent=2))
        typer.echo(f"full result: {out}")
    if bag is not None:
        from planner.wire import simulation_bag

        bag.write_bytes(simulation_bag(model, response))
        typer.echo(f"ROS 2 bag: {bag}")
    raise typer.Exit(EXIT_OK if response.realised_duration is not None else EXIT_NO_ANSWER)


def simulate_summary(response: Any) -> list[str]:
    """One screen of text about a :class:`planner.wire.SimulateResponse`."""
    tr = response.tracking
    realised = response.realised_duration
    settles = ", ".join("none" if s is None else f"{s:.4f}" for s in response.settle_times)
    return [
        f"engine: {response.engine}, controller {response.controller} at "
        f"{response.rate_hz:g} Hz (physics step {response.physics_timestep:g} s)",
        f"samples: {len(response.t)}",
        f"tracking: P max {tr.p_max_mm:.4g} mm, rms {tr.p_rms_mm:.4g} mm; q max "
        + ", ".join(f"{x:.3g}" for x in tr.q_max)
        + " rad",
        f"planned duration: {response.planned_duration:.4f} s",
        "realised duration: "
        + ("not settled" if realised is None else f"{realised:.4f} s")
        + f" (stops: {len(response.stops)})",
        f"settle times: {settles} s",
        f"saturated samples: {response.saturated_samples}",
        f"assembly mode kept: {'yes' if response.assembly_kept else 'NO'}",
    ]
