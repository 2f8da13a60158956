"""``planner stop``: the service's stop job run in this process, answered by a summary of the
braking trajectory (and ``--out`` / ``--csv`` files); ``planner stream``: a plan's setpoints
streamed from a running service (``/v1/stream``), printed and recorded.

Exit status (:mod:`planner_cli.errors`): stop: 0 solved, 1 another status (``invalid_start``:
no braking keeps the motion valid), 2 an invalid request; stream: 0 done, 2 an error.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from planner_cli.errors import fail
from planner_cli.plan import CsvOption, OutOption, _answer

__all__ = ["stop", "stop_summary", "stream"]


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


def stream(
    request: Annotated[
        Path, typer.Argument(help="A PlanRequest (or SequenceRequest) as JSON to stream.")
    ],
    url: Annotated[str, typer.Option(help="The service's base URL.")] = "http://127.0.0.1:8000",
    kind: Annotated[str, typer.Option(help="'plan' or 'sequence'.")] = "plan",
    rate: Annotated[float, typer.Option(help="Setpoints per second.")] = 1000.0,
    lookahead: Annotated[float, typer.Option(help="Lookahead of the service, s.")] = 0.05,
    api_key: Annotated[
        str | None, typer.Option(envvar="PLANNER_API_KEY", help="The service's API key.")
    ] = None,
    out: Annotated[
        Path | None, typer.Option(help="Record every message, one JSON object per line.")
    ] = None,
) -> None:
    """Stream a plan's (or sequence's) setpoints from a running service over /v1/stream.

    Prints one line per message (chunks summarised: first time, count, last posture) and
    records them with --out (JSON lines). The stream is acknowledged as it is read. Exit
    status: 0 done, 2 an error message (its field named)."""
    import json

    from planner.client import PlannerClient
    from planner.client_errors import PlannerClientError

    try:
        body = json.loads(request.read_text())
    except (OSError, ValueError) as exc:
        fail([f"cannot read {request}: {exc}"])
    sink = out.open("w") if out is not None else None
    try:
        with (
            PlannerClient(url, api_key=api_key) as client,
            client.stream(body, kind=kind, rate_hz=rate, lookahead_s=lookahead) as session,
        ):
            for message in session:
                typer.echo(_line(message))
                if sink is not None:
                    sink.write(json.dumps(message) + "\n")
    except PlannerClientError as exc:
        fail(
            [
                f"error: {exc}",
                *(
                    f"  at {'.'.join(map(str, d['loc']))}: {d['msg']}"
                    for d in getattr(exc, "detail", [])
                ),
            ]
        )
    except OSError as exc:
        fail([f"cannot stream from {url}: {exc}"])
    finally:
        if sink is not None:
            sink.close()


def _line(message: dict[str, Any]) -> str:
    if message["type"] == "setpoints":
        last = [round(x, 6) for x in message["q"][-1]]
        return f"setpoints t0 {message['t0']:.4f} s, {len(message['q'])} x {message['dt']:g} s, q {last}"
    if message["type"] == "switched":
        return f"switched at {message['at']:.4f} s"
    return f"done at {message['t']:.4f} s"
