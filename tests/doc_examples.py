"""The curl examples and the endpoint table of the documents, read as a reader would, for
tests/test_docs.py: every ``curl`` command of README.md and docs/*.md (in fenced blocks and
in inline code), grouped by block, and the rows of docs/service.md's endpoint table.

A block's statements run in one ``bash`` with ``set -e``, so a later command may use a
variable an earlier one set (``id=$(curl ... | jq -r .id)``); only the statements that call
``curl`` run (a block's ``docker run`` or ``planner serve`` lines are the reader's to run).
Each ``curl`` goes through a shell function that points ``localhost:8000`` and
``127.0.0.1:8000`` at the test's service, adds ``--fail-with-body`` (an HTTP error fails the
example), and records the call (for the coverage of the routes).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlsplit

__all__ = [
    "CURL_WRAPPER",
    "CurlBlock",
    "curl_blocks",
    "endpoint_rows",
    "method_and_path",
    "read_calls",
    "shell_statements",
]

#: A statement that runs curl: the word ``curl`` as a command (not inside a word).
_CURL_WORD = re.compile(r"(?:^|[\s;(|&`])curl\s")
_FENCE = re.compile(r"^```[^\n]*\n(.*?)^```", re.S | re.M)
_INLINE = re.compile(r"`(curl [^`]+)`")

#: The bash prelude of every block: the ``curl`` function described in the module docstring.
#: ``$PORT``, ``$CURL_LOG`` and ``$CURL_FAILED`` come from the environment.
CURL_WRAPPER = r"""set -e
curl() {
  local args=("${@//localhost:8000/127.0.0.1:$PORT}")
  args=("${args[@]//127.0.0.1:8000/127.0.0.1:$PORT}")
  { printf '%s\0' "${args[@]}"; printf '\1\0'; } >> "$CURL_LOG"
  local rc=0
  command curl --fail-with-body -sS --max-time 60 "${args[@]}" || rc=$?
  if [ "$rc" -ne 0 ] && [ "$rc" -ne 23 ]; then  # 23: a reader's `| head` closed the pipe
    printf 'curl exit %s: %s\n' "$rc" "${args[*]}" >> "$CURL_FAILED"
  fi
  return "$rc"
}
"""


@dataclass(frozen=True)
class CurlBlock:
    """The curl statements of one fenced block (or one inline example) of a document."""

    doc: str
    line: int
    statements: tuple[str, ...]

    @property
    def where(self) -> str:
        return f"{self.doc}:{self.line}"


def shell_statements(text: str) -> list[str]:
    """The statements of a shell block: lines joined while a quote is open or a line ends
    with a backslash; comment lines dropped."""
    statements, current, quote = [], "", None
    for line in text.splitlines():
        if not current and line.lstrip().startswith("#"):
            continue
        current = f"{current}\n{line}" if current else line
        i = 0
        while i < len(line):
            c = line[i]
            if quote is None and c == "#" and (i == 0 or line[i - 1].isspace()):
                break  # a comment to the end of the line
            if quote is None and c in "'\"":
                quote = c
            elif c == quote and (quote == "'" or line[i - 1] != "\\"):
                quote = None
            i += 1
        if quote is None and not line.endswith("\\"):
            if current.strip():
                statements.append(current)
            current = ""
    if current.strip():
        statements.append(current)
    return statements


def curl_blocks(docs: list[Path], root: Path) -> list[CurlBlock]:
    """Every curl example of ``docs``: each fenced block's curl statements, and each inline
    code span that is a curl command."""
    blocks = []
    for doc in docs:
        text = doc.read_text()
        name = str(doc.relative_to(root))
        for match in _FENCE.finditer(text):
            curls = [s for s in shell_statements(match.group(1)) if _CURL_WORD.search(s)]
            if curls:
                line = text.count("\n", 0, match.start()) + 1
                blocks.append(CurlBlock(name, line, tuple(curls)))
        prose = _FENCE.sub(lambda m: "\n" * m.group(0).count("\n"), text)
        for match in _INLINE.finditer(prose):
            line = prose.count("\n", 0, match.start()) + 1
            blocks.append(CurlBlock(name, line, (" ".join(match.group(1).split()),)))
    return blocks


def read_calls(log: bytes) -> list[list[str]]:
    """The argument lists the curl function recorded."""
    return [
        [a.decode() for a in record.split(b"\0") if a]
        for record in log.split(b"\1\0")
        if record.strip(b"\0")
    ]


def method_and_path(args: list[str], port: int) -> tuple[str, str] | None:
    """The HTTP method and path of one recorded curl call to the service (None: another
    host). ``-X``/``--request`` names the method; else a body makes it POST, else GET."""
    method, path = None, None
    for i, arg in enumerate(args):
        if arg in ("-X", "--request") and i + 1 < len(args):
            method = args[i + 1].upper()
        elif arg.startswith("-X") and len(arg) > 2:
            method = arg[2:].upper()
        elif f"127.0.0.1:{port}" in arg:
            url = arg if "://" in arg else f"http://{arg}"
            path = urlsplit(url).path or "/"
    if path is None:
        return None
    body = any(a in ("-d", "--data", "--data-raw", "--data-binary", "--json") for a in args)
    return method or ("POST" if body else "GET"), path


def endpoint_rows(service_md: str) -> list[tuple[str, str]]:
    """(method, path) of every row of docs/service.md's endpoint table (the table under
    "## Endpoints"); a row may name several routes, each in its own code span."""
    section = service_md.split("\n## Endpoints", 1)[1].split("\n## ", 1)[0]
    rows = []
    for line in section.splitlines():
        if not line.startswith("| `"):
            continue
        first = line.split("|")[1]
        for method, path in re.findall(r"`([A-Za-z]+) (/[^`\s]*)`", first):
            rows.append((method.upper(), path))
    return rows
