"""The client is light: ``import planner.client`` and a whole request through it load none of
the library's heavy parts (numba and the kinematics kernels cost seconds on a slow machine,
the native planning and timing libraries more), so a client machine pays only for httpx,
pydantic and numpy. Checked in a fresh interpreter: this test process has loaded them all.

The package's names stay importable as before (``from planner import Manipulator``): they
are loaded on first use, each from its own module.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import planner

ROOT = Path(__file__).resolve().parents[2]

#: Modules a client must not load: numba (and llvmlite under it), the kinematics and their
#: kernels, and the native or heavy libraries of the core and the pictures.
HEAVY = (
    "numba",
    "llvmlite",
    "planner.kinematics",
    "planner._kernels",
    "planner.validity",
    "planner.planning",
    "ompl",
    "toppra",
    "ruckig",
    "scipy",
    "matplotlib",
)

#: Run in a fresh interpreter: import the client, construct it, send one request (answered
#: by a MockTransport), convert and write a trajectory; print the heavy modules then loaded.
_SCRIPT = """
import io, json, sys
import httpx
import planner.client
from planner.client import PlannerClient, to_points, write_csv
from planner.wire import TrajectoryModel

heavy = json.loads(sys.argv[1])
loaded = {"after import": sorted(m for m in heavy if m in sys.modules)}
answer = {"postures": []}
transport = httpx.MockTransport(lambda request: httpx.Response(200, json=answer))
with PlannerClient("http://planner.test", transport=transport) as client:
    response = client.fk([0.0, 1.0, 2.0], "+", design={"L0": 0.5, "L1": 0.2, "L2": 0.6})
trajectory = TrajectoryModel(
    duration=1.0, t=[0.0, 1.0], q=[[0, 0, 0], [1, 1, 1]], qd=[[0, 0, 0]] * 2,
    qdd=[[0, 0, 0]] * 2,
)
points = to_points(trajectory)
write_csv(trajectory, io.StringIO())
loaded["after a request"] = sorted(m for m in heavy if m in sys.modules)
loaded["answer"] = [type(client).__name__, response.postures, len(points.points)]
print(json.dumps(loaded))
"""


def _loaded_by_a_client() -> dict[str, list]:
    out = subprocess.run(
        [sys.executable, "-c", _SCRIPT, json.dumps(HEAVY)],
        capture_output=True,
        text=True,
        check=True,
        cwd=ROOT,
    )
    return json.loads(out.stdout)


def test_a_client_loads_no_heavy_module() -> None:
    """Importing the client, and using it (a request, a trajectory converted and written as
    CSV), loads none of :data:`HEAVY`; the request did go through (the answer is parsed)."""
    loaded = _loaded_by_a_client()
    assert loaded["answer"] == ["PlannerClient", [], 2]
    assert loaded["after import"] == []
    assert loaded["after a request"] == []


def test_the_check_sees_a_heavy_module() -> None:
    """The same probe reports a heavy module once it is loaded (the check above can fail)."""
    code = (
        "import json, sys, planner.client; from planner import Manipulator; "
        f"print(json.dumps(sorted(m for m in {HEAVY!r} if m in sys.modules)))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    )
    assert {"numba", "planner.kinematics", "planner._kernels"} <= set(json.loads(out.stdout))


@pytest.mark.parametrize("name", [n for n in planner.__all__ if n != "__version__"])
def test_each_package_name_resolves_from_its_module(name: str) -> None:
    """Every name of ``planner.__all__`` is importable from the package and is the object of
    the module that defines it (the lazy map names the right home)."""
    value = getattr(planner, name)
    if callable(value):  # a class or function names its module; a constant: the import below
        assert getattr(sys.modules[value.__module__], name) is value
    namespace: dict[str, object] = {}
    exec(f"from planner import {name}", namespace)
    assert namespace[name] is value


def test_star_import_and_dir_list_the_package_names() -> None:
    namespace: dict[str, object] = {}
    exec("from planner import *", namespace)
    assert set(planner.__all__) <= set(namespace)
    assert set(planner.__all__) <= set(dir(planner))


def test_an_unknown_package_name_is_an_attribute_error() -> None:
    with pytest.raises(AttributeError, match="no_such_name"):
        _ = planner.no_such_name
