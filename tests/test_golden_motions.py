"""The seeded motions of :mod:`golden_motions` answer as recorded: a refactor of the
pipeline changes no answer (see that module for what is compared and when to re-record)."""

from __future__ import annotations

import json

import golden_motions as motions
import pytest


@pytest.fixture(scope="module")
def record() -> dict:
    return json.loads(motions.RECORD.read_text())


def test_the_record_covers_every_case(record: dict) -> None:
    assert set(record) == set(motions.CASES)
    kinds = {kind for kind, _ in motions.CASES.values()}
    assert kinds == {"plan", "sequence", "cartesian"}
    # the record holds real motions, not empty answers
    solved = [name for name, answer in record.items() if answer["status"] == "solved"]
    assert len(solved) >= len(record) - 1
    assert all(len(record[name]["trajectory"]["t"]) > 10 for name in solved)


@pytest.mark.parametrize("name", sorted(motions.CASES))
def test_answer_unchanged(name: str, record: dict) -> None:
    kind, body = motions.CASES[name]
    assert motions.differences(record[name], motions.run(kind, body)) == []


def test_differences_sees_a_changed_number_and_a_changed_word() -> None:
    base = {"status": "solved", "t": [0.0, 0.5, 1.0], "modes": ["+-+"]}
    assert motions.differences(base, base) == []
    assert motions.differences(base, {**base, "t": [0.0, 0.5, 1.0 + 1e-9]}) == []
    assert motions.differences(base, {**base, "t": [0.0, 0.5, 1.001]}) == [".t[2]: 1.001 != 1.0"]
    assert motions.differences(base, {**base, "modes": ["+++"]}) == [".modes[0]: '+++' != '+-+'"]
    assert motions.differences(base, {**base, "t": [0.0, 0.5]}) == [".t: length 2 != 3"]
