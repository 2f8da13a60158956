"""``planner version``, ``planner warm-up`` and ``planner bench``: the installation itself,
its first-call costs paid once, and its benchmarks."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from planner_cli._support import Progress
from planner_cli.errors import EXIT_NO_ANSWER, fail

__all__ = ["QUICK_BENCH_ARGS", "bench", "builtin_bench_rows", "version", "warm_up_command"]


def version() -> None:
    """Print the package version."""
    import planner

    typer.echo(planner.__version__)


def warm_up_command() -> None:
    """Compile the numba kernels and pay every first-call cost once.

    Compiles (or loads from numba's cache) every kernel, and runs a tiny plan, its timing
    with TOPPRA and Ruckig, an analysis and a figure, so that later processes start fast.
    The first run in an installation compiles for tens of seconds; later runs take seconds."""
    from planner.warmup import STEPS, warm_up

    with Progress("warm-up", len(STEPS)) as progress:
        seconds = warm_up(progress.step)
    typer.echo(f"warmed up in {seconds:.1f} s")


#: Arguments of each benchmark script for ``planner bench --quick`` (small sizes).
QUICK_BENCH_ARGS: dict[str, list[str]] = {
    "kinematics": ["--n", "100000", "--loop-n", "200", "--repeat", "3"],
    "analysis": ["--n", "64", "--rel-se", "0.02", "--repeat", "3"],
    "timing": ["--paths", "10"],
    "service": ["--workers", "2", "--requests", "60"],
    "warmup": ["--repeat", "1"],
}


def _benchmarks_dir() -> Path | None:
    """The repository's ``benchmarks/`` (next to ``src/``), if this is a source checkout."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        candidate = parent / "benchmarks"
        if candidate.is_dir() and (parent / "src" / "planner").is_dir():
            return candidate
    return None


def _median_ms(fn, repeat: int = 5) -> float:
    import statistics
    import time

    fn()  # warm-up (numba compilation, imports)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def builtin_bench_rows(progress: Progress | None = None) -> list[tuple[str, float]]:
    """The quick built-in subset: (task, median ms) of the core operations, in-process;
    ``progress`` (optional) is told each task as it starts."""
    import numpy as np

    from planner.analysis.workspace import sample_workspace
    from planner.design import Design
    from planner.kinematics import forward_batch, inverse_batch
    from planner.timing import JointLimits, time_path

    design = Design.default()
    rng = np.random.default_rng(0)
    q = rng.uniform(-np.pi, np.pi, (100_000, 3))
    p = forward_batch(design, q, "+").p
    p = p[np.all(np.isfinite(p), axis=1)]
    path = np.cumsum(rng.uniform(-0.15, 0.15, (20, 3)), axis=0) + np.array([0.0, 0.5, 1.5])
    limits = JointLimits.default()
    tasks = [
        ("forward_batch, 100k postures", lambda: forward_batch(design, q, "+")),
        (f"inverse_batch, {len(p) // 1000}k points x 8 modes", lambda: inverse_batch(design, p)),
        (
            "sample_workspace, 1 % relative error",
            lambda: sample_workspace(design, rel_se=0.01, kappa_max=10.0),
        ),
        ("time_path toppra, 20 waypoints", lambda: time_path(design, path, limits)),
    ]
    rows = []
    for index, (task, fn) in enumerate(tasks):
        if progress is not None:
            progress.step(task, index, len(tasks))
        rows.append((task, _median_ms(fn)))
    if progress is not None:
        progress.step("done", len(tasks), len(tasks))
    return rows


def bench(
    names: Annotated[
        list[str] | None,
        typer.Argument(
            help="Benchmarks to run, among the scripts of benchmarks/ (default: all).",
            show_default=False,
        ),
    ] = None,
    quick: Annotated[bool, typer.Option(help="Small sizes (a minute or so in all).")] = False,
    builtin: Annotated[
        bool, typer.Option(help="Only the built-in in-process subset (no scripts).")
    ] = False,
) -> None:
    """Run the benchmarks and print their tables.

    Runs the scripts of benchmarks/ (each prints its table), or a built-in quick subset when
    asked or when there is no benchmarks/ directory (an installed package)."""
    import os
    import subprocess
    import sys

    folder = None if builtin else _benchmarks_dir()
    if folder is None:
        with Progress("bench", 4) as progress:
            rows = builtin_bench_rows(progress)
        typer.echo("built-in benchmark (median of 5 runs after a warm-up, one process):")
        typer.echo(f"{'task':<45} {'median ms':>10}")
        for task, ms in rows:
            typer.echo(f"{task:<45} {ms:>10.3f}")
        return
    available = sorted(f.stem for f in folder.glob("*.py") if not f.stem.startswith("_"))
    chosen = names or available
    unknown = [n for n in chosen if n not in available]
    if unknown:
        raise typer.BadParameter(
            f"unknown benchmark {', '.join(unknown)}; one of {', '.join(available)}",
            param_hint="NAMES",
        )
    root = folder.parent
    env = {**os.environ}
    env["PYTHONPATH"] = os.pathsep.join(
        [str(root / "src"), str(root), *filter(None, [env.get("PYTHONPATH")])]
    )
    failed = []
    with Progress("bench", len(chosen)) as progress:
        for index, name in enumerate(chosen):
            args = QUICK_BENCH_ARGS.get(name, []) if quick else []
            progress.step(name, index)
            progress.echo(f"== {name} ({' '.join(['benchmarks/' + name + '.py', *args])})")
            argv = [sys.executable, str(folder / f"{name}.py"), *args]
            if progress.terminal:  # its table is printed when it ends, not across the bar
                done = subprocess.run(argv, cwd=root, env=env, capture_output=True, text=True)
                progress.echo(done.stdout.rstrip("\n"))
                if done.stderr:
                    progress.echo(done.stderr.rstrip("\n"), err=True)
                code = done.returncode
            else:  # a log or a pipe: the table as it comes
                sys.stdout.flush()
                code = subprocess.call(argv, cwd=root, env=env)
            if code != 0:
                failed.append(name)
        progress.step("done", len(chosen))
    if failed:
        fail([f"benchmarks failed: {', '.join(failed)}"], EXIT_NO_ANSWER)
