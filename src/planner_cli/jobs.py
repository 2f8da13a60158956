"""``planner job submit|status|wait|list|cancel``: a running service's long jobs
(``POST /v1/jobs``), through the typed client (:class:`planner.client.PlannerClient`). A job
lives in the service's store and runs in one of its replicas, so these commands talk to a
service (``--url``, default ``$PLANNER_URL`` or http://127.0.0.1:8000; ``--api-key`` or
``$PLANNER_API_KEY``: :mod:`planner_cli.service`).

``submit`` prints the job's id (alone on stdout, for scripts: ``id=$(planner job submit
plan req.json)``); ``status`` prints the job's status, with ``--out`` writing its result
(the endpoint's answer) as JSON; ``wait`` polls until the job has finished (for scripts:
``planner job wait $id --out result.json``); ``list`` one line a job; ``cancel`` the status
after.

Exit status: 0 done, 1 no such job (or, for ``status`` and ``wait``, a job that failed or was
cancelled: its error is printed; for ``wait``, one still unfinished at ``--timeout``), 2 a
bad input (the message naming the field) or a service that cannot be reached.
"""

from __future__ import annotations

import json
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Any

import typer

from planner_cli._support import Group
from planner_cli.errors import EXIT_NO_ANSWER, fail, reported
from planner_cli.service import KeyOption, UrlOption, call

__all__ = ["cancel", "job_app", "list_jobs", "status", "submit", "wait"]

#: A job's statuses once it has finished.
FINISHED = frozenset({"done", "failed", "cancelled"})

job_app = typer.Typer(
    cls=Group,
    help="Long jobs of a running service: submit, status, wait, list, cancel.",
    no_args_is_help=True,
    add_completion=False,
)

IdArgument = Annotated[str, typer.Argument(help="The job's id (as submit printed it).")]


def _when(stamp: float | None) -> str:
    if stamp is None:
        return "-"
    return datetime.fromtimestamp(stamp, UTC).strftime("%Y-%m-%d %H:%M:%S")


def _line(job: Any) -> str:
    return (
        f"{job.id}\t{job.kind}\t{job.status}\tsubmitted {_when(job.submitted_at)}\t"
        f"finished {_when(job.finished_at)}"
    )


@reported
def submit(
    kind: Annotated[
        str,
        typer.Argument(
            help="The endpoint the job runs: plan, sequence, cartesian, timing, "
            "design_check, design_optimize or regions."
        ),
    ],
    request: Annotated[Path, typer.Argument(help="A JSON file: that endpoint's request body.")],
    url: UrlOption = None,
    api_key: KeyOption = None,
) -> None:
    """Submit FILE's request as a long job of KIND; print its id.

    The id goes to stdout alone, the status to stderr; poll with 'planner job status ID'."""
    try:
        data = json.loads(request.read_text())
    except (OSError, ValueError) as exc:
        fail([f"cannot read {request} as JSON: {exc}"])
    if not isinstance(data, dict):
        fail([f"{request}: a request is a JSON object (the endpoint's body)"])
    job = call(url, api_key, "submit_job", kind, data)
    typer.echo(job.id)
    typer.echo(f"{job.kind} job {job.status}", err=True)


@reported
def status(
    job_id: IdArgument,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Write the result (done) here, JSON.")
    ] = None,
    url: UrlOption = None,
    api_key: KeyOption = None,
) -> None:
    """Print a job's status and times (a failed job's error: exit 1).

    With --out, a done job's result (the endpoint's answer) is written there as JSON."""
    job = call(url, api_key, "job", job_id)
    typer.echo(_line(job))
    if job.status == "failed" and job.error is not None:
        fail(
            [f"{job.error.status_code} {d.type}: {d.msg}" for d in job.error.detail], EXIT_NO_ANSWER
        )
    if out is not None and job.status == "done":
        out.write_text(json.dumps(job.result, indent=2))
        typer.echo(f"{job.id}: result written to {out}", err=True)


@reported
def wait(
    job_id: IdArgument,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Write the result (done) here, JSON.")
    ] = None,
    timeout: Annotated[
        float, typer.Option(help="Give up after this many seconds (exit 1).", min=0.0)
    ] = 600.0,
    interval: Annotated[float, typer.Option(help="Seconds between polls.", min=0.01)] = 0.5,
    url: UrlOption = None,
    api_key: KeyOption = None,
) -> None:
    """Wait until a job has finished; print its line as status does.

    Each change of its status goes to stderr. With --out, a done job's result is written
    there as JSON. Exit 0 done; 1 failed (its error printed), cancelled or still unfinished
    after --timeout."""
    import time

    deadline = time.monotonic() + timeout
    job = call(url, api_key, "job", job_id)
    seen = None
    while job.status not in FINISHED and time.monotonic() < deadline:
        if job.status != seen:
            typer.echo(f"{job.id}: {job.status}", err=True)
            seen = job.status
        time.sleep(min(interval, max(deadline - time.monotonic(), 0.0)))
        job = call(url, api_key, "job", job_id)
    typer.echo(_line(job))
    if job.status not in FINISHED:
        fail([f"{job.id}: still {job.status} after {timeout:g} s"], EXIT_NO_ANSWER)
    if job.status == "failed" and job.error is not None:
        fail(
            [f"{job.error.status_code} {d.type}: {d.msg}" for d in job.error.detail], EXIT_NO_ANSWER
        )
    if job.status == "cancelled":
        fail([f"{job.id}: cancelled"], EXIT_NO_ANSWER)
    if out is not None:
        out.write_text(json.dumps(job.result, indent=2))
        typer.echo(f"{job.id}: result written to {out}", err=True)


@reported
def list_jobs(url: UrlOption = None, api_key: KeyOption = None) -> None:
    """List the jobs still kept, oldest first.

    One line a job: id, kind, status, submitted and finished (UTC)."""
    for job in call(url, api_key, "jobs").root:
        typer.echo(_line(job))


@reported
def cancel(job_id: IdArgument, url: UrlOption = None, api_key: KeyOption = None) -> None:
    """Cancel a queued or running job (its worker is stopped); print its status."""
    typer.echo(_line(call(url, api_key, "cancel_job", job_id)))


job_app.command("submit")(submit)
job_app.command("status")(status)
job_app.command("wait")(wait)
job_app.command("list")(list_jobs)
job_app.command("cancel")(cancel)
