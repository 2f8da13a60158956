"""``planner stop``: the service's stop job run in this process, answered by a summary of the
braking trajectory (and ``--out`` / ``--csv`` files).

Exit status (:mod:`planner_cli.errors`): 0 solved, 1 another status (``invalid_start``: no
braking keeps the motion valid), 2 an invalid request.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from planner_cli.errors import fail
from planner_cli.plan import CsvOption, OutOption, _answer

__all__ = ["stop", "stop_summary"]


def stop(
    request: Annotated[
        Path, typer.Argument(help="A StopRequest as JSON (the body of POST /v1/stop).")
    ],
    out: OutOption = None,
    csv: CsvOption = None,
) -> None:
    """Brake a running trajectory to rest from its state at "at", in this process.

    Along the running path where the limits allow, else by the quickest Ruckig brake; the
    answer starts in exactly the running state (times on the running clock). Exit status: 0
    solved, 1 invalid_start, 2 an invalid request."""
    try:
        text = request.read_bytes()
    except OSError as exc:
        fail([f"cannot read {request}: {exc}"])
    from planner.endpoints.stop import stop as job
    from planner.wire import StopRequest

    response = job(StopRequest.model_validate_json(text))
    _answer(response, out, csv, stop_summary)


def stop_summary(response: Any) -> list[str]:
    """One screen of text about a :class:`planner.wire.StopResponse`."""
    lines = [f"status: {response.status}"]
    if response.message:
        lines.append(f"message: {response.message}")
    if response.stop_time is not None:
        where = "along the running path" if response.along_path else "off the running path"
        lines.append(f"stop time: {response.stop_time:.4f} s ({where})")
    lines.append(f"computation time: {response.computation_time_s * 1e3:.3f} ms")
    return lines
