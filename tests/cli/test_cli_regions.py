"""``planner regions``: the transits' table gives each end its own cells.

It used to print one ``cells`` column per transit: the crossing cells of the transit set's
component, which is the same number on the row of every pair of regions that component joins
(region 0 to region 3, region 0 to region 4: the same count twice), so it read as one end's
count printed for both. Each end's own count is now printed beside it, the crossing count in
a column of its own.
"""

from __future__ import annotations

import json

from typer.testing import CliRunner

from planner_cli import app

runner = CliRunner()
ARGS = ["regions", "--resolution", "64"]
HEADER = ["from", "cells", "to", "cells", "kind", "flipped", "crossing"]


def _transit_rows(stdout: str) -> list[list[str]]:
    lines = stdout.splitlines()
    start = next(i for i, line in enumerate(lines) if line.split() == HEADER)
    return [line.split() for line in lines[start + 1 :]]


def test_each_end_of_a_transit_shows_its_own_cells():
    table = runner.invoke(app, ARGS)
    assert table.exit_code == 0, table.output
    served = runner.invoke(app, [*ARGS, "--json"])
    assert served.exit_code == 0, served.output
    body = json.loads(served.stdout)
    cells = {r["id"]: r["cells"] for r in body["regions"]}
    rows = _transit_rows(table.stdout)
    assert len(rows) == len(body["transits"]) > 0
    for row, transit in zip(rows, body["transits"], strict=True):
        a, b = transit["from"], transit["to"]
        expected = [a, cells[a], b, cells[b], transit["kind"], transit["flipped"], transit["cells"]]
        assert row == [str(x) for x in expected]
    # the ends differ, and so do their counts: not one region's count printed twice
    assert any(row[1] != row[3] for row in rows)
    # one transit set's component joining a region to two others: the crossing count is the
    # component's, shared by both rows, while each row's far end has its own cells
    shared = {}
    for row in rows:
        shared.setdefault((row[0], row[4], row[6]), set()).add((row[2], row[3]))
    assert any(len({count for _, count in ends}) > 1 for ends in shared.values())
    assert "crossing: the cells where the flipped measure may vanish" in table.stdout
