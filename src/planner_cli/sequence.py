"""``planner sequence``: the service's sequence job run in this process, answered by a
summary of its legs and cycle time (and ``--out`` / ``--csv`` files).

Exit status (:mod:`planner_cli.errors`): 0 solved, 1 another status (a leg that failed, its
index in the message), 2 an invalid request.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from planner_cli._support import Progress
from planner_cli.errors import fail
from planner_cli.plan import CsvOption, OutOption, _answer

__all__ = ["sequence", "sequence_summary"]


def sequence(
    request: Annotated[
        Path, typer.Argument(help="A SequenceRequest as JSON (the body of POST /v1/sequence).")
    ],
    out: OutOption = None,
    csv: CsvOption = None,
) -> None:
    """Plan and time a task sequence in this process, and print its legs and cycle time.

    One trajectory from the start through every target (at rest at the stops, passing
    through the others within their blend; back to the start with "cycle": true). Exit
    status: 0 solved, 1 another status (the failed leg's index in the message), 2 an invalid
    request."""
    try:
        text = request.read_bytes()
    except OSError as exc:
        fail([f"cannot read {request}: {exc}"])
    with Progress("sequence") as progress:
        progress.step("loading the planner", 0)
        from planner.endpoints.sequence import sequence as job
        from planner.wire import SequenceRequest

        body = SequenceRequest.model_validate_json(text)
        legs = len(body.targets) + body.cycle
        progress.step(f"planning {legs} legs ({body.objective} objective) and timing", 0)
        response = job(body)
        progress.done("planned and timed")
    _answer(response, out, csv, sequence_summary)


def _time(x: float | None) -> str:
    return "-" if x is None else f"{x:.4f}"


def sequence_summary(response: Any) -> list[str]:
    """One screen of text about a :class:`planner.wire.SequenceResponse`."""
    lines = [f"status: {response.status}"]
    if response.message:
        lines.append(f"message: {response.message}")
    lines.append(f"legs: {len(response.legs)}")
    for leg in response.legs:
        n = len(leg.path.waypoints) if leg.path is not None else 0
        lines.append(
            f"  target {leg.target_index}: {leg.status}, mode {leg.working_mode or '-'}, "
            f"{n} waypoints, t {_time(leg.start_time)} .. {_time(leg.end_time)} s"
        )
    cycle = (
        "none (no trajectory)" if response.cycle_time is None else f"{response.cycle_time:.4f} s"
    )
    lines.append(f"cycle time: {cycle}")
    diag = response.diagnostics.model_dump(exclude_none=True)
    if diag:
        lines.append("diagnostics:")
        for key, value in diag.items():
            shown = f"{value:.6g}" if isinstance(value, float) else value
            lines.append(f"  {key}: {shown}")
    return lines
