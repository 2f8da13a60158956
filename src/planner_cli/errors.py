"""The one error path of the ``planner`` command line: a bad input, a library error or a
command's "no answer" becomes ``error: ...`` lines on stderr and an exit status.

Exit statuses, the same for every command, as a Unix tool's:

* :data:`EXIT_OK` 0: an answer;
* :data:`EXIT_NO_ANSWER` 1: the input was valid but there is no answer (a plan not solved, no
  posture reaching a point: as ``grep`` finding nothing; a benchmark script failing);
* :data:`EXIT_BAD_INPUT` 2: the input breaks a rule, the message naming the field and the
  rule (click's own usage errors exit 2 too).

Two functions make them:

* :func:`reported` wraps every command (:mod:`planner_cli.app` registers them through it):
  a :class:`pydantic.ValidationError` (a wire model refusing the input) or a
  :class:`planner.exceptions.PlannerError` (the library or a service job refusing it) that
  leaves a command is printed by :func:`error_lines` and exits with :data:`EXIT_BAD_INPUT`.
* :func:`fail` is what a command calls itself to stop with its own message and status.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable
from typing import Any, NoReturn, TypeVar

import typer

__all__ = ["EXIT_BAD_INPUT", "EXIT_NO_ANSWER", "EXIT_OK", "error_lines", "fail", "reported"]

#: A command's exit statuses: an answer; a valid input without an answer; a bad input.
EXIT_OK, EXIT_NO_ANSWER, EXIT_BAD_INPUT = 0, 1, 2

F = TypeVar("F", bound=Callable[..., Any])


def error_lines(exc: Exception) -> list[str]:
    """The lines that say what is wrong with the input, each naming the field when known.

    A validation error gives one line per broken rule, ``field.path: rule``. A library error
    gives ``field.path: message`` when the wire located it in a request
    (:func:`planner.wire.located` sets ``loc``, starting with ``"body"``, which a command's
    input has no name for), else its message alone (the library's messages name their
    argument). Anything else: its message.
    """
    from pydantic import ValidationError

    if isinstance(exc, ValidationError):
        return [_located(e["loc"], e["msg"]) for e in exc.errors()]
    loc = tuple(getattr(exc, "loc", ()))
    return [_located(loc[1:] if loc[:1] == ("body",) else loc, str(exc))]


def _located(loc: Iterable[object], message: str) -> str:
    where = ".".join(map(str, loc))
    return f"{where}: {message}" if where else message


def fail(lines: Iterable[str], code: int = EXIT_BAD_INPUT) -> NoReturn:
    """Print each line as ``error: line`` on stderr and exit with ``code``."""
    for line in lines:
        typer.echo(f"error: {line}", err=True)
    raise typer.Exit(code)


def reported(command: F) -> F:
    """``command`` with its bad inputs reported: a validation or library error leaving it is
    printed (:func:`error_lines`) and exits with :data:`EXIT_BAD_INPUT`, not a traceback."""

    @functools.wraps(command)
    def run(*args: Any, **kwargs: Any) -> Any:
        try:
            return command(*args, **kwargs)
        except Exception as exc:
            if not _bad_input(exc):
                raise
            fail(error_lines(exc))

    return run  # type: ignore[return-value]


def _bad_input(exc: Exception) -> bool:
    """Whether ``exc`` refuses the input (imported only once an error happened, so that a
    command that needs neither pydantic nor the library does not load them)."""
    from pydantic import ValidationError

    from planner.exceptions import PlannerError

    return isinstance(exc, ValidationError | PlannerError)
