"""How the ``planner`` command line reads: negative numbers are arguments, the help of every
command reads cleanly on an 80-column terminal, and long commands show their progress on
stderr while their results go to stdout."""

from __future__ import annotations

import json
import re
from types import SimpleNamespace

import pytest
import typer
from typer.testing import CliRunner

from planner_cli import app
from planner_cli._support import Progress, numbers_as_arguments

runner = CliRunner()
GROUP = typer.main.get_command(app)
COMMANDS = sorted(GROUP.commands)  # type: ignore[attr-defined]


# ---------------------------------------------------------------------------- negative numbers
def test_ik_takes_negative_coordinates_as_arguments(api):
    r = runner.invoke(app, ["ik", "-0.25", "0.1", "0.3"])
    assert r.exit_code == 0, r.output
    served = api.post("/v1/ik", json={"p": [-0.25, 0.1, 0.3]}).json()
    assert json.loads(r.stdout) == served
    assert len(served["postures"]) >= 1
    # the same as the old spelling with "--", and with options before or after the numbers
    for args in (
        ["ik", "--", "-0.25", "0.1", "0.3"],
        ["ik", "-0.25", "0.1", "0.3", "--working-mode", "any"],
        ["ik", "--design", "default", "-0.25", "0.1", "0.3"],
    ):
        again = runner.invoke(app, args)
        assert again.exit_code == 0, again.output
        assert json.loads(again.stdout) == served


def test_fk_takes_negative_angles_in_any_position_and_notation(api):
    served = api.post("/v1/fk", json={"q": [-0.2, -1.0, 2.0], "assembly_mode": "-"}).json()
    for args in (
        ["fk", "-0.2", "-1", "2", "--assembly-mode", "-"],
        ["fk", "--assembly-mode", "-", "-0.2", "-1.0", "2.0"],
        ["fk", "-2e-1", "-1.0E0", "2", "--assembly-mode", "-"],
        ["fk", "-.2", "-1.", "2", "--assembly-mode=-"],
    ):
        r = runner.invoke(app, args)
        assert r.exit_code == 0, (args, r.output)
        assert json.loads(r.stdout) == served, args


def test_check_design_takes_negative_lengths_to_the_library():
    """A negative L0 reaches the design check, which refuses it by name (not "No such
    option"); an option's negative value stays that option's."""
    r = runner.invoke(app, ["check-design", "-0.1", "0.3", "0.4"])
    assert r.exit_code == 2
    assert "L0 must be >= 0" in r.output and "No such option" not in r.output
    r = runner.invoke(app, ["check-design", "0", "0.4", "0.4", "--kappa-max", "-3"])
    assert r.exit_code == 2 and "kappa" in r.output and "No such option" not in r.output
    r = runner.invoke(app, ["ik", "--L2", "-1", "0.1", "-0.1", "0.1"])
    assert r.exit_code == 2 and "design.L2" in r.output


def test_unknown_options_are_still_refused():
    r = runner.invoke(app, ["fk", "--bogus", "-1", "2", "3"])
    assert r.exit_code == 2 and "No such option: --bogus" in r.output
    r = runner.invoke(app, ["fk", "-x", "-1", "2", "3"])
    assert r.exit_code == 2 and "No such option" in r.output


def test_numbers_as_arguments_keeps_option_values_and_argument_order():
    ik = GROUP.commands["ik"]  # type: ignore[attr-defined]
    params = ik.get_params(typer.Context(ik))
    assert numbers_as_arguments(params, ["0.1", "0.2"]) == ["0.1", "0.2"]  # nothing to do
    assert numbers_as_arguments(params, ["-1", "--L2", "-0.5", "2", "-3", "--help"]) == [
        "--L2",
        "-0.5",
        "--help",
        "--",
        "-1",
        "2",
        "-3",
    ]
    assert numbers_as_arguments(params, ["--L1=-2", "-1", "--", "-x"]) == [
        "--L1=-2",
        "--",
        "-1",
        "-x",
    ]


# ---------------------------------------------------------------------------- help
def _help(*args: str) -> str:
    r = runner.invoke(app, [*args, "--help"], env={"COLUMNS": "80"})
    assert r.exit_code == 0, r.output
    return r.stdout


@pytest.mark.parametrize("name", COMMANDS)
def test_help_of_each_command_reads_cleanly_in_80_columns(name):
    text = _help(name)
    assert "<bool>" not in text
    assert "…" not in text  # nothing cut off by a column too narrow
    assert all(len(line) <= 80 for line in text.splitlines())
    command = GROUP.commands[name]  # type: ignore[attr-defined]
    # the docstring's paragraphs as whole lines (rich wraps them; no break mid-sentence)
    paragraphs = command.help.split("\n\n")
    assert paragraphs[0].endswith(".") and all("\n" not in p for p in paragraphs)
    shown = " ".join(text.replace("│", " ").split())
    for paragraph in paragraphs:
        assert " ".join(paragraph.split()) in shown
    # every option and argument says what it is
    for param in command.params:
        assert (param.help or "").strip(), f"{name}: {param.name} has no help"
        if param.param_type_name == "option":
            assert param.opts[0] in text


def test_top_level_help_lists_each_command_with_its_one_line_summary():
    text = _help()
    assert "<bool>" not in text and "…" not in text
    shown = " ".join(text.replace("│", " ").split())  # the words, across the panel's lines
    for name in COMMANDS:
        summary = GROUP.commands[name].help.split("\n\n")[0]  # type: ignore[attr-defined]
        assert re.search(rf"{re.escape(name)}\s", text)
        assert " ".join(summary.split()) in shown


# ---------------------------------------------------------------------------- progress
def test_figures_prints_the_files_on_stdout_and_its_progress_on_stderr(tmp_path):
    from planner.plotting import FIGURES

    r = runner.invoke(
        app, ["figures", str(tmp_path), "--n", "16", "--formats", "png", "--dpi", "20"]
    )
    assert r.exit_code == 0, r.output
    written = r.stdout.splitlines()
    assert written == [str(tmp_path / f"{stem}.png") for stem, _ in FIGURES.values()]
    assert all((tmp_path / f"{stem}.png").stat().st_size > 0 for stem, _ in FIGURES.values())
    progress = r.stderr.splitlines()
    assert len(progress) == len(FIGURES)
    for i, (number, (stem, _)) in enumerate(FIGURES.items()):
        assert progress[i].startswith(
            f"figures: [{i + 1}/{len(FIGURES)}] figure {number}: {stem} ("
        )


def test_progress_on_a_terminal_keeps_results_off_the_bar(capsys):
    """On a terminal the bar is drawn on stderr; a result printed meanwhile goes to stdout
    whole, and the plain step lines of a non-terminal are not printed."""
    with Progress("test", 2, terminal=True) as progress:
        progress.step("first", 0)
        progress.echo("result 1")
        progress.step("second", 1)
        progress.echo("result 2")
        progress.step("done", 2)
    out, err = capsys.readouterr()
    assert out == "result 1\nresult 2\n"
    assert "result" not in err and "[1/2]" not in err


def test_progress_off_a_terminal_prints_one_plain_line_per_step(capsys):
    with Progress("test", 2, terminal=False) as progress:
        progress.step("first", 0)
        progress.echo("result")
        progress.step("second", 1)
        progress.step("done", 2)
    out, err = capsys.readouterr()
    assert out == "result\n"
    lines = err.splitlines()
    assert [line.split(" (")[0] for line in lines] == ["test: [1/2] first", "test: [2/2] second"]
    with Progress("plan") as progress:  # no known length: the step alone
        progress.step("planning", 0)
    assert capsys.readouterr().err.startswith("plan: planning (")


def test_progress_times_read_as_what_they_are(capsys, monkeypatch):
    """Off a terminal a step's line says when it began ("at" seconds since the command began,
    not how long anything took); ``done`` says how long the last step took, in words."""
    from planner_cli import _support

    clock = iter([10.0, 10.0, 12.5, 13.0])  # created, step 1, step 2, done
    monkeypatch.setattr(_support, "time", SimpleNamespace(perf_counter=lambda: next(clock)))
    with Progress("plan", terminal=False) as progress:
        progress.step("loading the planner", 0)
        progress.step("planning and timing", 0)
        progress.done("planned and timed")
    assert capsys.readouterr().err.splitlines() == [
        "plan: loading the planner (at 0.0 s)",
        "plan: planning and timing (at 2.5 s)",
        "plan: planned and timed in 0.5 s",
    ]


def test_optimize_design_shows_each_generation_and_prints_the_library_optimum():
    from planner.analysis.optimize import optimize_design

    args = ["optimize-design", "--objective", "gci", "--samples", "256", "--maxiter", "3"]
    r = runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    best = optimize_design("gci", n_samples=256, maxiter=3)  # without a progress callback
    d = best.design
    assert r.stdout.splitlines()[0] == (
        f"design: L0 = {d.L0:.6g} m, L1 = {d.L1:.6g} m, L2 = {d.L2:.6g} m"
    )
    assert f"gci: {best.value:.6g}" in r.stdout.splitlines()
    steps = [line.split(" (")[0] for line in r.stderr.splitlines()]
    assert steps == [f"optimize-design: [{k}/3] generation {k} of 3" for k in (1, 2, 3)]
    r = runner.invoke(app, ["optimize-design", "--objective", "nope"])
    assert r.exit_code == 2 and "objective must be one of" in r.stderr
