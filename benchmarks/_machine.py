"""The machine a benchmark ran on, printed in every benchmark's header: figures are only
comparable on the same machine, so each table names it (``lscpu`` model, cores, Python)."""

from __future__ import annotations

import os
import platform
import subprocess


def cpu_model() -> str:
    """The CPU's model name (``lscpu``; /proc/cpuinfo or the platform as fallbacks)."""
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, timeout=5).stdout
        for line in out.splitlines():
            if line.startswith("Model name:"):
                return line.split(":", 1)[1].strip()
    except (OSError, subprocess.SubprocessError):
        pass
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_line() -> str:
    """One line: CPU model, usable cores, Python version and OS."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return (
        f"machine: {cpu_model()}, {cores} usable cores, Python {platform.python_version()}, "
        f"{platform.system()} {platform.machine()}"
    )


def print_machine() -> None:
    """Print :func:`machine_line` and a rule, as the first lines of a benchmark's output."""
    line = machine_line()
    print(line)
    print("=" * len(line))
