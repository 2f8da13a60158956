"""Support of the ``planner`` command line: progress displays, negative numbers as
arguments, and help texts that read cleanly on an 80-column terminal.

Kept out of the command modules (:mod:`planner_cli.plan`, ...) so that they read as what
they do.

* :class:`Progress`: what a long command is doing and how far it is, on stderr (results go
  to stdout, so ``planner figures out/ > list.txt`` keeps only the results): a rich progress
  bar when stderr is a terminal, one plain line per step otherwise (logs, CI, pipes).
* :class:`Command` / :class:`Group`: typer's classes with two fixes. Click reads any word
  starting with ``-`` as an option, so ``planner ik -0.25 0.1 0.3`` failed with "No such
  option: -0"; here a negative number is an argument unless it is the value of an option.
  And the help: typer's rich help keeps the line breaks of a docstring (lines broken
  mid-sentence) and prints ``<bool>`` beside every flag; here each paragraph of a docstring
  is one line that rich wraps to the terminal, and flags show no type.
"""

from __future__ import annotations

import re
import sys
import time
from collections.abc import Sequence
from typing import Any

import typer
from typer.core import TyperCommand, TyperGroup

__all__ = ["Command", "Group", "Progress", "numbers_as_arguments", "reflow"]

#: A negative number as a word of the command line: -1, -0.25, -.5, -1e-3, -2.5E+2.
NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


class Progress:
    """Progress of one command on stderr: ``with Progress("figures", total=12) as p: ...``.

    ``p.step(name, index, total)`` announces a step (``index`` = steps finished so far, the
    signature of :func:`planner.warmup.warm_up`'s ``progress``); off a terminal its line ends
    with ``(at 2.2 s)``, the time since the command began, when the step starts: not how long
    anything took. ``p.done(what)`` says how long the last step took (``plan: planned and
    timed in 0.4 s``). ``p.echo(text)`` prints a result on stdout without tearing the bar.
    ``total=None``: no known length (a spinner and the elapsed time on a terminal).
    """

    def __init__(self, title: str, total: int | None = None, *, terminal: bool | None = None):
        self.title = title
        self.total = total
        self.terminal = sys.stderr.isatty() if terminal is None else terminal
        self._bar: Any = None
        self._task: Any = None
        self._t0 = self._step_t0 = time.perf_counter()

    def __enter__(self) -> Progress:
        if self.terminal:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                SpinnerColumn,
                TextColumn,
                TimeElapsedColumn,
            )
            from rich.progress import Progress as RichProgress

            self._bar = RichProgress(
                SpinnerColumn(),
                TextColumn("[bold]{task.fields[title]}[/bold] {task.description}"),
                BarColumn(bar_width=24),
                MofNCompleteColumn(),
                TimeElapsedColumn(),
                console=Console(stderr=True),
                transient=True,
                redirect_stdout=False,  # results stay on stdout, never on the bar's stderr
                redirect_stderr=False,
            )
            self._bar.start()
            self._task = self._bar.add_task("", total=self.total, title=self.title)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.stop()
            self._bar = None

    def step(self, name: str, index: int, total: int | None = None) -> None:
        """Step ``name`` begins, ``index`` steps of ``total`` being done (``index == total``:
        all done)."""
        total = self.total if total is None else total
        self._step_t0 = time.perf_counter()
        if self._bar is not None:
            self._bar.update(self._task, description=name, completed=index, total=total)
            return
        if total is not None and index >= total:
            return  # the command prints its own result
        count = f"[{index + 1}/{total}] " if total is not None else ""
        elapsed = self._step_t0 - self._t0
        typer.echo(f"{self.title}: {count}{name} (at {elapsed:.1f} s)", err=True)

    def done(self, what: str) -> None:
        """Say on stderr, on a terminal too, that the last step ended and how long it took:
        ``plan: planned and timed in 0.4 s`` (the seconds of that step alone)."""
        seconds = time.perf_counter() - self._step_t0
        self.echo(f"{self.title}: {what} in {seconds:.1f} s", err=True)

    def echo(self, text: str, *, err: bool = False) -> None:
        """Print ``text`` (stdout, or stderr with ``err``) above the bar, not through it."""
        if self._bar is None:
            typer.echo(text, err=err)
            return
        self._bar.stop()  # transient: the bar is cleared, the text printed, the bar redrawn
        typer.echo(text, err=err)
        self._bar.start()


def reflow(text: str | None) -> str | None:
    """Each paragraph of a docstring as one line (paragraphs apart by a blank line), so that
    the help display wraps it to the terminal's width instead of keeping the source's line
    breaks. A paragraph that starts with ``\\b`` (click's "keep as is") is left alone."""
    if not text:
        return text
    paragraphs = re.split(r"\n\s*\n", text.strip())
    return "\n\n".join(p if p.startswith("\b") else " ".join(p.split()) for p in paragraphs)


def numbers_as_arguments(params: Sequence[Any], args: list[str]) -> list[str]:
    """``args`` with every negative number that is not an option's value moved after a
    ``--`` (where click takes every word as an argument), arguments kept in their order.

    ``params`` are the command's parameters: an option's value (``--L2 -1``) stays where it
    is; unknown options still reach click, which refuses them as before. Without a negative
    number, ``args`` is returned unchanged.
    """
    if not any(NEGATIVE_NUMBER.match(a) for a in args):
        return args
    names: set[str] = set()
    with_value: set[str] = set()
    for p in params:
        if getattr(p, "param_type_name", None) != "option":
            continue
        opts = [*p.opts, *p.secondary_opts]
        names.update(opts)
        if not (p.is_flag or p.count):
            with_value.update(opts)
    options: list[str] = []
    arguments: list[str] = []
    words = iter(args)
    for word in words:
        if word == "--":
            arguments.extend(words)
            break
        if word in with_value:
            options.append(word)
            value = next(words, None)
            if value is not None:
                options.append(value)
        elif word.startswith("-") and len(word) > 1 and not NEGATIVE_NUMBER.match(word):
            options.append(word)  # an option, --name=value, or an unknown option for click
        else:
            arguments.append(word)
    return [*options, "--", *arguments]


def _flags_without_type(params: list[Any]) -> list[Any]:
    """Blank the type column of flags (``--quick/--no-quick``, ``--help``): ``<bool>`` says
    nothing a flag's name does not."""
    for p in params:
        if getattr(p, "is_flag", False) and p.metavar is None:
            p.metavar = ""
    return params


class Command(TyperCommand):
    """A typer command taking negative numbers as arguments, with reflowed help."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs["help"] = reflow(kwargs.get("help"))
        super().__init__(*args, **kwargs)

    def get_params(self, ctx: Any) -> list[Any]:
        return _flags_without_type(super().get_params(ctx))

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        return super().parse_args(ctx, numbers_as_arguments(self.get_params(ctx), args))


class Group(TyperGroup):
    """The top-level ``planner`` group, with reflowed help and no ``<bool>`` beside --help."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs["help"] = reflow(kwargs.get("help"))
        super().__init__(*args, **kwargs)

    def get_params(self, ctx: Any) -> list[Any]:
        return _flags_without_type(super().get_params(ctx))
