"""The ``planner`` command line (typer): the app, and every command registered on it.

The commands live in modules of one group each: :mod:`planner_cli.serve`,
:mod:`planner_cli.kinematics` (fk, ik), :mod:`planner_cli.analysis` (check-design,
optimize-design, regions), :mod:`planner_cli.figures`, :mod:`planner_cli.plan` (plan,
cartesian), :mod:`planner_cli.sequence`, :mod:`planner_cli.simulate`, :mod:`planner_cli.tools` (version, warm-up, bench), and the
groups that talk to a running service, :mod:`planner_cli.scenes` and :mod:`planner_cli.jobs`. Each is registered through
:func:`planner_cli.errors.reported`, the one path from a bad input or a library error to an
``error: ...`` message and exit status 2.

Results go to stdout, progress and errors to stderr; every command that can run for more than
a few seconds shows what it is doing (see :class:`planner_cli._support.Progress`). Negative
numbers are arguments (``planner ik -0.25 0.1 0.3``) unless they are an option's value.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import typer

from planner_cli import (
    analysis,
    calibration,
    dynamics,
    execution,
    figures,
    jobs,
    kinematics,
    plan,
    scenes,
    sequence,
    serve,
    simulate,
    tools,
)
from planner_cli._support import Command, Group
from planner_cli.errors import reported

__all__ = ["app", "register"]

app = typer.Typer(
    cls=Group,
    help="Plan, time and analyse motions of the 3-DOF hybrid manipulator.",
    no_args_is_help=True,
    add_completion=False,
)


def register(function: Callable[..., Any], name: str | None = None) -> None:
    """Add ``function`` to :data:`app` as the command ``name`` (default: the function's name
    with '-' for '_'), with :class:`planner_cli._support.Command` (negative numbers as
    arguments, reflowed help) and :func:`planner_cli.errors.reported` (the one error path)."""
    app.command(name, cls=Command)(reported(function))


# in the order of ``planner --help``
register(serve.serve)
register(kinematics.fk)
register(kinematics.ik)
register(tools.warm_up_command, "warm-up")
register(tools.version)
register(figures.figures)
register(analysis.check_design_command, "check-design")
register(analysis.optimize_design_command, "optimize-design")
register(analysis.regions)
register(plan.plan)
register(plan.cartesian)
register(sequence.sequence)
register(execution.stop)
register(execution.stream)
register(tools.bench)
register(dynamics.dynamics)
register(dynamics.mjcf)
register(dynamics.inertia_report, "inertia-report")
register(calibration.calibrate)
register(calibration.identify)
register(simulate.simulate)
app.add_typer(scenes.scene_app, name="scene")
app.add_typer(jobs.job_app, name="job")
