"""The documents a newcomer reads stay true to the code: the client's method list in
docs/service.md is the client's, no document cites an issue number (a reader has no tracker),
and the README's library example of a timed plan runs as written."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from planner.client import AsyncPlannerClient, PlannerClient

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _public_methods(cls: type) -> set[str]:
    own = {"close", "aclose"}  # the connection's life, not an endpoint
    return {n for n in vars(cls) if not n.startswith("_") and n not in own}


def test_service_doc_lists_every_client_method():
    text = (ROOT / "docs" / "service.md").read_text()
    block = re.search(r"Methods: (.*?); the async client", text, re.S)
    assert block, "docs/service.md lost its 'Methods: ...' sentence"
    listed = set(re.findall(r"`([a-z_]+)`", block.group(1)))
    assert listed == _public_methods(PlannerClient)
    assert _public_methods(AsyncPlannerClient) == _public_methods(PlannerClient)


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_no_document_cites_an_issue(doc: Path):
    text = doc.read_text()
    assert not re.findall(r"(?i)\bissues? #?\d+|\bthe (service|timing|planning) issue\b", text)


def test_the_readme_timed_plan_runs():
    """The README's ``solve`` example, run as written: a solved, timed plan."""
    text = (ROOT / "README.md").read_text()
    blocks = [b for b in re.findall(r"```python\n(.*?)```", text, re.S) if "solve(" in b]
    assert len(blocks) == 1
    scope: dict = {}
    exec(compile(blocks[0].replace("print(", "(lambda *a: None)("), "README", "exec"), scope)
    s = scope["s"]
    assert s.solved and s.trajectory.duration > 0
