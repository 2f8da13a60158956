"""How the code is laid out: the formatter's layout everywhere except tables.

``# fmt: skip`` keeps a statement as written. It is allowed on a *table* only, a literal laid
out as rows (at least two rows, each a tuple, list, dict or set, or ``pytest.param``), a flat
literal of at least six constants (bucket bounds, colours), or a call whose first or second
argument is such a literal (``np.array([[...]])``, ``pytest.mark.parametrize(names, rows)``).
On any other statement it would pack code onto fewer lines than the formatter gives it,
which hides a module's real size from the line budget (``tests/test_architecture.py``).

A function of ``src/`` or ``api/`` is at most :data:`MAX_FUNCTION_LINES` lines long, from its
``def`` to its last line (decorators excluded, its docstring included): a longer one holds
more than one job, and is split into named steps, each a function of its own.
"""

from __future__ import annotations

import ast
import io
import subprocess
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("src", "api", "tests", "benchmarks", "examples", "deploy", ".ci")


def is_table(node: ast.AST) -> bool:
    """Whether ``node`` is a table in the sense of the module docstring."""
    if isinstance(node, ast.Call):
        literals = (ast.List, ast.Tuple, ast.Dict, ast.Set)
        return any(is_table(a) for a in node.args[:2] if isinstance(a, literals))
    if isinstance(node, ast.List | ast.Tuple | ast.Set):
        elements = list(node.elts)
    elif isinstance(node, ast.Dict):
        elements = list(node.values)
    else:
        return False

    def row(e: ast.AST) -> bool:
        if isinstance(e, ast.Tuple | ast.List | ast.Dict | ast.Set):
            return True
        return (
            isinstance(e, ast.Call) and isinstance(e.func, ast.Attribute) and e.func.attr == "param"
        )

    def constant(e: ast.AST) -> bool:
        return isinstance(e, ast.Constant) or (
            isinstance(e, ast.UnaryOp) and isinstance(e.operand, ast.Constant)
        )

    if len(elements) >= 2 and all(row(e) for e in elements):
        return True
    return len(elements) >= 6 and all(constant(e) for e in elements)


def skipped_statements(source: str) -> list[tuple[int, ast.AST | None]]:
    """(line, the statement or decorator that ends on it) of each ``# fmt: skip``."""
    lines = [
        tok.start[0]
        for tok in tokenize.generate_tokens(io.StringIO(source).readline)
        if tok.type == tokenize.COMMENT and tok.string.replace(" ", "").endswith("fmt:skip")
    ]
    if not lines:
        return []
    ends: dict[int, ast.AST] = {}
    for node in ast.walk(ast.parse(source)):
        for part in [node, *getattr(node, "decorator_list", [])]:
            if isinstance(part, ast.stmt) or part in getattr(node, "decorator_list", []):
                line = getattr(part, "end_lineno", None)
                if line is not None and (line not in ends or part.lineno >= ends[line].lineno):
                    ends[line] = part
    return [(line, ends.get(line)) for line in lines]


def packed(node: ast.AST | None) -> bool:
    """A skipped statement that is not a table."""
    if node is None:
        return True
    value = node if isinstance(node, ast.expr) else getattr(node, "value", None)
    simple = isinstance(node, ast.Assign | ast.AnnAssign | ast.Return | ast.Expr | ast.expr)
    return not (simple and value is not None and is_table(value))


def python_files() -> list[Path]:
    out = subprocess.run(
        ["git", "ls-files", "--", *FOLDERS], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.split()
    return [ROOT / name for name in out if name.endswith(".py") and (ROOT / name).exists()]


def test_fmt_skip_only_on_tables() -> None:
    files = python_files()
    assert len(files) > 200
    found = [
        f"{path.relative_to(ROOT)}:{line}"
        for path in files
        for line, node in skipped_statements(path.read_text())
        if packed(node)
    ]
    assert found == []


def test_the_rule_tells_a_table_from_packed_code() -> None:
    table = "ROWS = [\n    (1, 2),\n    (3, 4),\n]  # fmt: skip\n"
    flat = "BOUNDS = (0.1, 0.2, 0.5, 1.0, 2.0, 5.0)  # fmt: skip\n"
    rows = "x = np.array([[1, 0], [0, 1]])  # fmt: skip\n"
    call = (
        "result = solve(design, start, goal, obstacles=o,\n               margins=m)  # fmt: skip\n"
    )
    short = "PAIR = (1, 2)  # fmt: skip\n"
    signature = "def f(a, b,\n      c):  # fmt: skip\n    return a\n"
    for source, expected in (
        (table, False),
        (flat, False),
        (rows, False),
        (call, True),
        (short, True),
        (signature, True),
    ):
        [(_, node)] = skipped_statements(source)
        assert packed(node) is expected, source


#: The most lines a function or method of src/ or api/ may have (module docstring).
MAX_FUNCTION_LINES = 120
#: Functions allowed over :data:`MAX_FUNCTION_LINES`, as "path:name": none.
LONG_FUNCTIONS_ALLOWED: frozenset[str] = frozenset()


def long_functions(source: str) -> list[tuple[str, int]]:
    """(name, lines) of each function of ``source`` over :data:`MAX_FUNCTION_LINES`."""
    return [
        (node.name, n)
        for node in ast.walk(ast.parse(source))
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
        and (n := (node.end_lineno or node.lineno) - node.lineno + 1) > MAX_FUNCTION_LINES
    ]


def test_no_function_is_over_120_lines() -> None:
    files = [p for p in python_files() if p.relative_to(ROOT).parts[0] in ("src", "api")]
    assert len(files) > 100
    found = {
        f"{path.relative_to(ROOT)}:{name}": n
        for path in files
        for name, n in long_functions(path.read_text())
        if f"{path.relative_to(ROOT)}:{name}" not in LONG_FUNCTIONS_ALLOWED
    }
    assert found == {}


def test_the_function_budget_counts_from_def_to_last_line() -> None:
    body = "".join(f"    x{i} = {i}\n" for i in range(MAX_FUNCTION_LINES - 1))
    at_budget = "@decorator\n@another\ndef f():\n" + body
    over = at_budget + "    return x0\n"
    assert long_functions(at_budget) == []
    assert long_functions(over) == [("f", MAX_FUNCTION_LINES + 1)]
    method = "class C:\n    def m(self):\n" + body.replace("    x", "        x")
    assert long_functions(method + "        pass\n") == [("m", MAX_FUNCTION_LINES + 1)]
