"""``planner plan`` and ``planner cartesian``: the service's plan and Cartesian jobs run in
this process, answered by a one-screen summary (and ``--out`` / ``--csv`` files).

Exit status (:mod:`planner_cli.errors`): 0 solved, 1 another status (``no_path``,
``unreachable``, stopped short, ...), 2 an invalid request.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from planner_cli._support import Progress
from planner_cli.common import DesignOption, L0Option, L1Option, L2Option, design_data
from planner_cli.errors import EXIT_NO_ANSWER, EXIT_OK, fail

__all__ = ["cartesian", "plan", "plan_summary"]

OutOption = Annotated[
    Path | None, typer.Option("--out", "-o", help="Write the full response JSON here.")
]
CsvOption = Annotated[
    Path | None,
    typer.Option(
        "--csv",
        help="Write the trajectory as CSV here: columns t, theta1 to theta3 and their rates "
        "(and tau1 to tau3 with design.inertia or limits.torque), under a line naming the "
        "units.",
    ),
]


def plan(
    request: Annotated[
        Path, typer.Argument(help="A PlanRequest as JSON (the body of POST /v1/plan).")
    ],
    out: OutOption = None,
    csv: CsvOption = None,
) -> None:
    """Plan and time a motion in this process, and print a summary.

    The summary gives the status, waypoints, segments, transits, duration and diagnostics;
    the progress on stderr ends with the time the planning and timing took. Exit status: 0
    solved, 1 another status (no_path, unreachable, ...), 2 an invalid request."""
    try:
        text = request.read_bytes()
    except OSError as exc:
        fail([f"cannot read {request}: {exc}"])
    with Progress("plan") as progress:
        progress.step("loading the planner", 0)
        from planner.endpoints.plan import plan as job
        from planner.wire import PlanRequest

        body = PlanRequest.model_validate_json(text)
        progress.step(f"planning (search budget {body.planner.time_budget_s:g} s) and timing", 0)
        response = job(body)
        progress.done("planned and timed")
    _answer(response, out, csv)


def cartesian(
    numbers: Annotated[
        list[float],
        typer.Argument(
            help="The start's joints theta1 theta2 theta3 (rad), then each waypoint's x y z "
            "(m), in order."
        ),
    ],
    assembly_mode: Annotated[str, typer.Option(help="The start's assembly mode, '+' or '-'.")] = (
        "+"
    ),
    path_tolerance: Annotated[
        float, typer.Option(help="Largest distance of P from the polyline, m.")
    ] = 1e-3,
    speed: Annotated[
        float | None, typer.Option(help="Tool speed bound (limits.cartesian_speed), m/s.")
    ] = None,
    method: Annotated[str, typer.Option(help="Timing: toppra, ruckig or none.")] = "toppra",
    velocity_scaling: Annotated[
        float, typer.Option(help="Factor in (0, 1] on the velocity limits.")
    ] = 1.0,
    acceleration_scaling: Annotated[
        float, typer.Option(help="Factor in (0, 1] on the acceleration limits.")
    ] = 1.0,
    trajectory_format: Annotated[
        str, typer.Option("--format", help="Trajectory of --out: arrays or points.")
    ] = "arrays",
    design: DesignOption = "default",
    l0: L0Option = None,
    l1: L1Option = None,
    l2: L2Option = None,
    out: OutOption = None,
    csv: CsvOption = None,
) -> None:
    """Move P on straight lines from the start through the waypoints, in this process.

    P keeps the start's working and assembly mode; where a rule would break, the path stops
    at the last valid point and the summary names the rule, the value and the point.
    Example: planner cartesian -0.2187 2.8609 0.2807 0.45 0.3 0.1 --speed 0.25. Exit
    status: 0 solved (the whole polyline), 1 stopped short, 2 an invalid request."""
    if len(numbers) < 6 or len(numbers) % 3:
        fail(
            [
                "numbers: give the start's 3 joint angles, then 3 coordinates per waypoint "
                f"(at least one waypoint), got {len(numbers)} numbers"
            ]
        )
    with Progress("cartesian") as progress:
        progress.step("loading the planner", 0)
        from planner.endpoints.cartesian import cartesian as job
        from planner.wire import CartesianRequest

        data = {
            "design": design_data(design, l0, l1, l2),
            "start": {"q": numbers[:3], "assembly_mode": assembly_mode},
            "waypoints": [numbers[i : i + 3] for i in range(3, len(numbers), 3)],
            "path_tolerance": path_tolerance,
            "timing": {"method": method, "format": trajectory_format},
            "limits": {
                "velocity_scaling": velocity_scaling,
                "acceleration_scaling": acceleration_scaling,
                **({"cartesian_speed": speed} if speed is not None else {}),
            },
        }
        body = CartesianRequest.model_validate(data)
        progress.step(f"following {len(body.waypoints)} segment(s) and timing", 0)
        response = job(body)
        progress.done("followed and timed")
    _answer(response, out, csv)


def plan_summary(response: Any) -> list[str]:
    """One screen of text about a :class:`planner.wire.PlanResponse` (or a
    :class:`planner.wire.CartesianResponse`: with its fraction and stopping point)."""
    lines = [f"status: {response.status}"]
    if response.message:
        lines.append(f"message: {response.message}")
    fraction = getattr(response, "fraction", None)
    if fraction is not None:
        lines.append(f"fraction: {fraction:.6g}")
    stop = getattr(response, "stop", None)
    if stop is not None:
        p = ", ".join(f"{x:.5f}" for x in stop.p)
        value = "none" if stop.value is None else f"{stop.value:.6g}"
        lines.append(f"stopped by: {stop.rule} (value {value}) at P = [{p}]")
    path = response.path
    if path is not None:
        lines.append(f"waypoints: {len(path.waypoints)}")
        lines.append(f"segments: {len(path.segments)}")
        for seg in path.segments:
            lines.append(
                f"  working mode {seg.working_mode}, assembly mode {seg.assembly_mode}: "
                f"waypoints {seg.start_index}..{seg.end_index}"
            )
        lines.append(f"transits: {len(path.transits)}")
        for tr in path.transits:
            q = ", ".join(f"{x:.4f}" for x in tr.q)
            lines.append(f"  #{tr.index} {tr.kind} (flips {tr.flipped}) at q = [{q}]")
    traj = response.trajectory
    if traj is not None:
        samples = len(traj.points) if hasattr(traj, "points") else len(traj.t)
        lines.append(f"duration: {traj.duration:.4f} s ({traj.method}, {samples} samples)")
    else:
        lines.append("duration: none (no trajectory)")
    diag = response.diagnostics.model_dump(exclude_none=True)
    if diag:
        lines.append("diagnostics:")
        for key, value in diag.items():
            shown = f"{value:.6g}" if isinstance(value, float) else value
            lines.append(f"  {key}: {shown}")
    return lines


def _answer(response: Any, out: Path | None, csv: Path | None, summary: Any = plan_summary) -> None:
    """Print the summary (``summary(response)``, lines), write ``--out`` and ``--csv``, and
    exit with the status's code: the end of every command that answers a trajectory."""
    for line in summary(response):
        typer.echo(line)
    if out is not None:
        out.write_text(response.model_dump_json(indent=2))
        typer.echo(f"full result: {out}")
    if csv is not None:
        if response.trajectory is None:
            typer.echo(f"error: no trajectory to write to {csv}", err=True)
        else:
            from planner.client import write_csv

            write_csv(response.trajectory, csv)
            typer.echo(f"trajectory CSV: {csv}")
    raise typer.Exit(EXIT_OK if response.status == "solved" else EXIT_NO_ANSWER)
