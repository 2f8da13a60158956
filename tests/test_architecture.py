"""The layering of the house (docs/architecture.md), as tests.

Floors from the ground up: the core (numpy maths and the native libraries), the pictures
(matplotlib), the wire (pydantic models and the conversions wire <-> core), the client
(httpx), the service, and the CLI on top. A room imports only from floors below it. The
rules are read from the source (the AST of every module, imports inside functions included),
so a lazy import cannot hide a breach; one rule is checked by importing in a fresh process.

Each public module declares ``__all__`` and exports exactly what it defines in public, as
httpx tests its exported members.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import re
import subprocess
import sys
import tomllib
from collections.abc import Iterable, Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LIBRARY = ROOT / "src" / "planner"
SERVICE = ROOT / "api"
CLI = ROOT / "src" / "planner_cli"

#: The import name of the service package (the folder ``api/``).
SERVICE_NAME = "planner_api"

#: The core rooms: numpy maths and the native libraries, nothing of the wire or of HTTP.
CORE = (
    "planner.design",
    "planner.kinematics",
    "planner.geometry",
    "planner.validity",
    "planner.transits",
    "planner.planning",
    "planner.cartesian",
    "planner.timing",
    "planner.analysis",
    "planner.calibration",
    "planner.exceptions",
    "planner.constants",
    "planner.caching",
    "planner._kernels",
    "planner.warmup",
    "planner.solver",
    "planner.sequence",
    "planner.simulation",
)
#: What the core may never import (the wire, the client, the service, the CLI and their
#: third-party libraries).
CORE_FORBIDDEN = (
    "pydantic",
    "pydantic_settings",
    "fastapi",
    "starlette",
    "httpx",
    "typer",
    SERVICE_NAME,
    "planner.wire",
    "planner.endpoints",
    "planner.client",
    "planner_cli",
)
#: Each native library and the one room allowed to import it.
CONFINED = {
    "ompl": ("planner.planning",),
    "toppra": ("planner.timing",),
    "ruckig": ("planner.timing",),
    "matplotlib": ("planner.plotting",),
    "mujoco": ("planner.simulation",),
    "mcap": ("planner.simulation",),
    "mcap_ros2": ("planner.simulation",),
}


def _module_name(path: Path) -> str:
    """The dotted import name of a source file."""
    if path.is_relative_to(SERVICE):
        parts = (SERVICE_NAME, *path.relative_to(SERVICE).with_suffix("").parts)
    else:
        parts = path.relative_to(ROOT / "src").with_suffix("").parts
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _sources() -> dict[str, Path]:
    """Every module of the library, the service and the CLI, by import name."""
    files = [*LIBRARY.rglob("*.py"), *SERVICE.rglob("*.py"), *CLI.rglob("*.py")]
    return {_module_name(p): p for p in sorted(files)}


_TREES: dict[Path, ast.Module] = {}


def _tree(path: Path) -> ast.Module:
    """The parsed module at ``path``, parsed once per session (the rules below read each
    source several times; the trees are never changed)."""
    if path not in _TREES:
        _TREES[path] = ast.parse(path.read_text(), str(path))
    return _TREES[path]


def _walk(tree: ast.AST, *, runtime: bool) -> Iterator[ast.AST]:
    """Every node under ``tree``, as :func:`ast.walk`; with ``runtime``, not those under an
    ``if TYPE_CHECKING:`` body (its ``else`` is walked)."""
    todo: list[ast.AST] = [tree]
    while todo:
        node = todo.pop()
        yield node
        if (
            runtime
            and isinstance(node, ast.If)
            and getattr(node.test, "id", None) == "TYPE_CHECKING"
        ):
            todo.extend([node.test, *node.orelse])
            continue
        todo.extend(ast.iter_child_nodes(node))


def _imports(name: str, path: Path, *, runtime: bool = False) -> set[str]:
    """The absolute names of every module ``name`` imports, anywhere in its body; with
    ``runtime``, without those under ``if TYPE_CHECKING:`` (annotations only: no dependency
    when the module runs)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in _walk(_tree(path), runtime=runtime):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                module = ".".join([*base, node.module] if node.module else base)
            else:
                module = node.module or ""
            found.add(module)
            found.update(f"{module}.{alias.name}" for alias in node.names)
    return found


def _within(module: str, rooms: tuple[str, ...]) -> bool:
    return any(module == room or module.startswith(room + ".") for room in rooms)


SOURCES = _sources()
IMPORTS = {name: _imports(name, path) for name, path in SOURCES.items()}
RUNTIME_IMPORTS = {name: _imports(name, path, runtime=True) for name, path in SOURCES.items()}


def test_the_tree_is_read() -> None:
    """The rules below see the whole tree (a wrong root would make every rule vacuous)."""
    assert "planner.validity" in SOURCES
    assert "planner.planning.ompl_backend" in SOURCES
    assert "planner.endpoints.plan" in SOURCES


#: What the endpoints (each request's work without HTTP) may never import: the service, HTTP
#: and the CLI; the CLI may import the endpoints but never the service package (other than to
#: start it: ``planner serve``).
ENDPOINTS_FORBIDDEN = (
    SERVICE_NAME,
    "fastapi",
    "starlette",
    "uvicorn",
    "httpx",
    "typer",
    "planner_cli",
)


def test_the_endpoints_know_nothing_of_http_and_the_cli_nothing_of_the_service() -> None:
    """The CLI answers a request in its own process through :mod:`planner.endpoints` (the
    library), never through :mod:`planner_api`; the endpoints import no HTTP."""
    endpoints = sorted(
        f"{name} imports {module}"
        for name, imported in IMPORTS.items()
        if _within(name, ("planner.endpoints",))
        for module in imported
        if _within(module, ENDPOINTS_FORBIDDEN)
    )
    cli = sorted(
        f"{name} imports {module}"
        for name, imported in IMPORTS.items()
        if _within(name, ("planner_cli",)) and name != "planner_cli.serve"
        for module in imported
        if _within(module, (SERVICE_NAME,))
    )
    assert endpoints == [] and cli == []


def test_the_packages_installed_are_the_folders() -> None:
    """pyproject's explicit package list (needed for the ``api/`` -> ``planner_api`` mapping)
    names every package folder, and nothing else."""
    listed = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    folders = [name for name, path in SOURCES.items() if path.name == "__init__.py"]
    # folders of data files inside a package are listed too (setuptools ships them as such)
    code_dirs = {path.parent for path in SOURCES.values() if path.name == "__init__.py"}
    data = {
        _module_name(sub / "__init__.py")
        for package in code_dirs
        for sub in package.rglob("*")
        if sub.is_dir() and "__pycache__" not in sub.parts and sub not in code_dirs
    }
    assert sorted(listed) == sorted([*folders, *data])


def test_nothing_imports_the_service_by_its_folder_name() -> None:
    """The service installs as ``planner_api``; an ``import api`` would only work from the
    repository's root, and would load a second copy of the service next to the installed one."""
    # (only the files with an import statement of a module named api* are parsed: none
    # other can import it, and the tests' own files are many and long)
    others = [
        p
        for d in ("tests", "benchmarks", "examples", "deploy")
        for p in (ROOT / d).rglob("*.py")
        if re.search(r"^\s*(?:from|import)\s+api", p.read_text(), re.MULTILINE)
    ]
    modules = {**SOURCES, **{str(p.relative_to(ROOT)): p for p in others}}
    breaches = sorted(
        f"{name} imports {module}"
        for name, path in modules.items()
        for module in _imports(name, path)
        if _within(module, ("api",))
    )
    assert breaches == []


def test_the_service_installs_under_its_distinct_name(tmp_path: Path) -> None:
    """Outside the repository ``planner_api`` is the service (from the ``api/`` folder) and no
    top-level ``api`` is installed that could collide with another project's."""
    code = (
        "import importlib.util as u; s = u.find_spec('planner_api'); "
        "print(s.submodule_search_locations[0]); print(u.find_spec('api'))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=tmp_path
    ).stdout.split()
    assert Path(out[0]).resolve() == SERVICE.resolve()
    assert out[1] == "None"


def test_core_imports_nothing_of_the_wire_or_of_http() -> None:
    breaches = sorted(
        f"{name} imports {module}"
        for name, imported in IMPORTS.items()
        if _within(name, CORE)
        for module in imported
        if _within(module, CORE_FORBIDDEN)
    )
    assert breaches == []


def test_no_library_module_imports_the_service_or_the_cli() -> None:
    breaches = sorted(
        f"{name} imports {module}"
        for name, imported in IMPORTS.items()
        if _within(name, ("planner",))
        for module in imported
        if _within(module, (SERVICE_NAME, "planner_cli"))
    )
    assert breaches == []


@pytest.mark.parametrize("library", sorted(CONFINED))
def test_native_library_is_confined_to_its_room(library: str) -> None:
    users = {
        name for name, imported in IMPORTS.items() if any(_within(m, (library,)) for m in imported)
    }
    assert users, f"nobody imports {library}: the rule is stale"
    assert sorted(u for u in users if not _within(u, CONFINED[library])) == []


#: Private parts used outside their package today (a debt to pay, not a precedent): none.
PRIVATE_USE_KNOWN: set[str] = set()


def _private_part(module: str) -> str | None:
    """A dotted import name up to its first private part (leading underscore), or None."""
    parts = module.split(".")
    first = next((i for i, p in enumerate(parts) if p.startswith("_") and p[:2] != "__"), None)
    return None if first is None else ".".join(parts[: first + 1])


def test_no_room_reaches_into_the_private_parts_of_another() -> None:
    """A private module or name (leading underscore) is used only inside the package that
    holds it: the OMPL backend, for one, certifies motions through the public
    ``ValidityChecker.motion_test``, not through the validity kernels."""

    def owner(private: str) -> str:
        holder = private.rpartition(".")[0]
        is_package = holder in SOURCES and SOURCES[holder].name == "__init__.py"
        return holder if is_package else holder.rpartition(".")[0]

    breaches = {
        f"{name} imports {private}"
        for name, imported in IMPORTS.items()
        for private in map(_private_part, imported)
        if private is not None
        and private.startswith("planner")
        and not _within(name, (owner(private),))
    }
    assert sorted(breaches - PRIVATE_USE_KNOWN) == []
    assert PRIVATE_USE_KNOWN <= breaches, "a known breach is gone: drop it from the list"


#: What the wire may take from the planning room: its data classes, never a search.
WIRE_PLANNING = ("planner.planning.problem", "planner.planning.result", "planner.cartesian.result")


def test_the_wire_converts_and_runs_no_search() -> None:
    """The wire holds conversions only: of the planning room it imports the data classes
    (:data:`WIRE_PLANNING`), nothing that searches, and not :mod:`planner.solver`; of the
    sequences, only their data classes (:mod:`planner.sequence.problem`); of the motion room,
    its problem (:mod:`planner.motion.problem`). Imports for annotations only
    (``if TYPE_CHECKING:``) are not dependencies and are not counted."""
    breaches = sorted(
        f"{name} imports {module}"
        for name, imported in RUNTIME_IMPORTS.items()
        if _within(name, ("planner.wire",))
        for module in imported
        if (
            _within(module, ("planner.planning", "planner.cartesian"))
            and not _within(module, WIRE_PLANNING)
        )
        or _within(module, ("planner.solver", "planner.endpoints"))
        or (
            _within(module, ("planner.motion",))
            and not _within(module, ("planner.motion.problem",))
        )
        or (
            _within(module, ("planner.sequence",))
            and module != "planner.sequence.problem"
            and not module.startswith("planner.sequence.problem.")
        )
    )
    assert breaches == []


def test_the_plan_job_is_convert_solve_respond() -> None:
    """The service's plan job calls the library's plan-and-time step (:func:`planner.solve`),
    not the planner and the timing one by one."""
    imported = IMPORTS["planner.endpoints.plan"]
    assert "planner.solver" in imported
    assert not any(
        _within(m, ("planner.planning.goal_options", "planner.timing.parameterize"))
        or m in ("planner.timing", "planner.planning")
        for m in imported
    ), sorted(imported)


def test_core_has_no_wire_conversions_of_its_own() -> None:
    """``as_wire`` / ``*_from_wire`` / ``*_to_wire`` belong to the wire room."""
    found = sorted(
        f"{name}.{node.name}"
        for name, path in SOURCES.items()
        if _within(name, CORE)
        for node in ast.walk(_tree(path))
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and "wire" in node.name
    )
    assert found == []


def test_the_wire_imports_without_fastapi() -> None:
    """The client and the CLI use the wire models without loading the web framework."""
    code = (
        "import sys, planner.wire; "
        "print(sorted(m for m in sys.modules if m.split('.')[0] in "
        "('fastapi', 'starlette', 'uvicorn', 'httpx', 'api', 'planner_api')))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    )
    assert out.stdout.strip() == "[]"


def test_the_client_converts_trajectories_without_the_timing_libraries() -> None:
    """Writing CSV or converting a trajectory's form (``planner.timing.export``) loads
    neither toppra nor ruckig nor OMPL: a client machine needs none of them at run time."""
    code = (
        "import sys, planner.client, planner.timing.export, planner.timing.limits; "
        "print(sorted(m for m in sys.modules if m.split('.')[0] in "
        "('toppra', 'ruckig', 'ompl', 'matplotlib')))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    )
    assert out.stdout.strip() == "[]"


def _public_modules() -> list[str]:
    return [name for name in SOURCES if not any(part.startswith("_") for part in name.split("."))]


@pytest.mark.parametrize("name", _public_modules())
def test_public_module_exports_what_it_defines(name: str) -> None:
    """``__all__`` lists existing names, sorted once, and every public class and function the
    module defines itself (a new public name is a decision to export it, or to rename it)."""
    module = importlib.import_module(name)
    exported = getattr(module, "__all__", None)
    assert exported is not None, f"{name} has no __all__"
    assert len(set(exported)) == len(exported)
    assert [n for n in exported if not hasattr(module, n)] == []
    defined = {
        n
        for n, obj in vars(module).items()
        if not n.startswith("_")
        and n.isidentifier()  # not pydantic's own entry for a parametrised generic
        and (inspect.isclass(obj) or inspect.isfunction(obj))
        and getattr(obj, "__module__", None) == name
    }
    assert sorted(defined - set(exported)) == []


def test_the_library_is_typed() -> None:
    """PEP 561: type checkers of client code read the library's annotations."""
    assert (LIBRARY / "py.typed").is_file()
    pyproject = (ROOT / "pyproject.toml").read_text()
    assert "py.typed" in pyproject


def test_the_endpoints_mirror_the_routes() -> None:
    """One endpoints module per resource: ``planner/endpoints/<name>.py`` is run by the
    service's ``routes/<name>.py``, and a route module runs no other resource's endpoint."""
    jobs = {n.rsplit(".", 1)[1] for n in SOURCES if n.startswith("planner.endpoints.")}
    routes = {n.rsplit(".", 1)[1] for n in SOURCES if n.startswith(f"{SERVICE_NAME}.routes.")}
    assert jobs and jobs <= routes, sorted(jobs - routes)
    for name in routes:
        used = {
            m.rsplit(".", 1)[1]
            for m in IMPORTS[f"{SERVICE_NAME}.routes.{name}"]
            if m.startswith("planner.endpoints.")
            and m.count(".") == 2
            and m.rsplit(".", 1)[1] in jobs
        }
        assert used <= {name}, (name, sorted(used))


def _public_classes(modules: Iterable[str]) -> dict[str, str]:
    return {
        node.name: name
        for name in modules
        for node in _tree(SOURCES[name]).body
        if isinstance(node, ast.ClassDef) and not node.name.startswith("_")
    }


def test_wire_names_do_not_shadow_library_names() -> None:
    """A wire class never has a library class's name (``MarginsModel`` beside the library's
    ``Margins``): a module that needs both can import both by name."""
    wire = _public_classes(n for n in SOURCES if _within(n, ("planner.wire",)))
    core = _public_classes(n for n in SOURCES if _within(n, CORE))
    assert len(wire) > 20 and "Margins" in core and "MarginsModel" in wire
    assert sorted(f"{c}: {wire[c]} and {core[c]}" for c in wire.keys() & core.keys()) == []


#: The most lines a module of src/ or api/ may have: past it, a module holds more than one job.
MAX_MODULE_LINES = 750


def test_no_module_is_over_the_line_budget() -> None:
    long = {
        name: n
        for name, path in SOURCES.items()
        if (n := len(path.read_text().splitlines())) > MAX_MODULE_LINES
    }
    assert long == {}


#: The rooms whose deadlines and budgets are compared with a clock: one clock for all of
#: them, :func:`time.monotonic`, the one a caller's ``deadline`` is given on (a deadline on
#: another clock would be compared with the wrong time).
ONE_CLOCK = ("planner.planning", "planner.cartesian", "planner.sequence", "planner.motion")


def test_the_motion_rooms_read_one_clock() -> None:
    found = sorted(
        name
        for name, path in SOURCES.items()
        if _within(name, ONE_CLOCK) and "perf_counter" in path.read_text()
    )
    assert any(_within(n, ("planner.planning",)) for n in SOURCES) and found == []


#: The functions that may keep :func:`functools.cache` / ``lru_cache``: functions of no
#: arguments computed once per process, constants rather than caches (see
#: :mod:`planner.caching`'s docstring). Every other cache is made by :mod:`planner.caching`.
ONCE_PER_PROCESS = {
    ("planner_api.settings", "get_settings"),
    ("planner.viewer", "index_html"),
    ("planner.viewer", "content_security_policy"),
    ("planner_api.routes.design", "_presets_json"),
}
_FUNCTOOLS_CACHES = frozenset({"lru_cache", "cache"})


def _cache_uses(tree: ast.Module) -> tuple[list[ast.AST], dict[int, ast.FunctionDef]]:
    """Every reference to functools' caches or a construction of ``BoundedCache`` in a
    module, and the functions decorated by one (by the decorator node's id)."""
    names = {
        alias.asname or alias.name
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and node.module == "functools"
        for alias in node.names
        if alias.name in _FUNCTOOLS_CACHES
    }
    uses: list[ast.AST] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Name) and node.id in names:
            uses.append(node)
        elif (
            isinstance(node, ast.Attribute)
            and node.attr in _FUNCTOOLS_CACHES
            and getattr(node.value, "id", None) == "functools"
        ):
            uses.append(node)
        elif isinstance(node, ast.Call) and "BoundedCache" in (
            getattr(node.func, "id", None),
            getattr(node.func, "attr", None),
        ):
            uses.append(node)
    decorated: dict[int, ast.FunctionDef] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef):
            for deco in node.decorator_list:
                for part in ast.walk(deco):
                    decorated[id(part)] = node
    return uses, decorated


def test_every_cache_is_made_by_the_registry() -> None:
    """No module but :mod:`planner.caching` uses :func:`functools.lru_cache` or
    :func:`functools.cache`, or constructs a ``BoundedCache``: each process-wide cache is
    made by name through the registry, which sizes it from the one budget, clears it and
    reports it. The exceptions (:data:`ONCE_PER_PROCESS`) are functions of no arguments."""
    breaches, allowed = [], set()
    for name, path in SOURCES.items():
        if name == "planner.caching":
            continue
        uses, decorated = _cache_uses(_tree(path))
        for use in uses:
            fn = decorated.get(id(use))
            once = fn is not None and (name, fn.name) in ONCE_PER_PROCESS
            if once and not (fn.args.args or fn.args.kwonlyargs or fn.args.vararg):
                allowed.add((name, fn.name))
            else:
                breaches.append(f"{name}:{use.lineno}")
    assert breaches == []
    assert allowed == ONCE_PER_PROCESS  # each exception still exists (none stale)


def test_the_cache_rule_sees_a_breach() -> None:
    """The rule above finds each kind of breach (a rule that finds nothing proves nothing)."""
    source = (
        "import functools\nfrom functools import lru_cache as lc\n"
        "@functools.cache\ndef a(x): ...\n@lc(maxsize=2)\ndef b(x): ...\n"
        "C = BoundedCache(1, 2, len)\n"
    )
    uses, decorated = _cache_uses(ast.parse(source))
    assert len(uses) == 3
    assert sorted(decorated[id(u)].name for u in uses if id(u) in decorated) == ["a", "b"]
