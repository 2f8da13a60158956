"""The timing's work is linear in the number of waypoints: a repair round solves again only
the toppra sections and Ruckig moves its repair changed (the caches of ``time_path``), so
the extra work of a repair does not grow with the length of the path; and the caches change
no result (the same path timed without them gives the same trajectory)."""

from __future__ import annotations

import numpy as np
import pytest
from timing_factories import box_checker

from planner import Design
from planner.timing import JointLimits, ruckig_method, time_path, toppra_method

DESIGN = Design.default()
LIMITS = JointLimits.default()


def motif_path(copies: int) -> np.ndarray:
    """``copies`` copies of a 4-waypoint motif, each shifted along theta1: two corners and a
    reversal (a stop) per copy, so the path's rest-to-rest sections stay short."""
    rows = []
    for j in range(copies):
        o = np.array([0.12 * j - 1.0, 1.6, 0.9])
        step = np.array([[0.0, 0.0, 0.0], [0.0, 0.4, 0.0], [0.05, 0.4, 0.4], [0.0, 0.4, 0.0]])
        rows += list(o + step)
    rows.append(np.array([0.12 * copies - 1.0, 1.6, 0.9]))
    return np.array(rows)


def corner_box(w: np.ndarray, k: int, half: float = 0.008):
    """A small forbidden box inside corner k, where its 0.05 rad blend passes (off the
    polyline: the plan's segments stay valid, the blend does not)."""
    y1 = (w[k] - w[k - 1]) / np.linalg.norm(w[k] - w[k - 1])
    y2 = (w[k + 1] - w[k]) / np.linalg.norm(w[k + 1] - w[k])
    centre = w[k] + 0.045 * (y2 - y1) / np.linalg.norm(y2 - y1)
    return box_checker(centre - half, centre + half)


class Counter:
    """Counts the toppra sections solved (``section_grid`` is called only for a section not
    in the cache) and the Ruckig moves solved (``_calculate``: a cache miss)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.sections = 0
        self.moves = 0
        grid, calc = toppra_method.section_grid, ruckig_method._calculate

        def counted_grid(*args, **kwargs):
            self.sections += 1
            return grid(*args, **kwargs)

        def counted_calc(*args, **kwargs):
            self.moves += 1
            return calc(*args, **kwargs)

        monkeypatch.setattr(toppra_method, "section_grid", counted_grid)
        monkeypatch.setattr(ruckig_method, "_calculate", counted_calc)

    def work(self, w: np.ndarray, method: str, check=None) -> tuple[int, int, int]:
        self.sections = self.moves = 0
        traj = time_path(DESIGN, w, LIMITS, method=method, check_states=check)
        return self.sections, self.moves, traj.repairs


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_repair_work_does_not_grow_with_the_path(monkeypatch, method):
    counter = Counter(monkeypatch)
    extra = {}
    for copies in (2, 6):
        w = motif_path(copies)
        base = counter.work(w, method)
        repaired = counter.work(w, method, corner_box(w, 1))
        assert repaired[2] > base[2], "the box must cause a repair"
        extra[copies] = (repaired[0] - base[0], repaired[1] - base[1])
        assert extra[copies][0] >= 1  # the repaired section is solved again
    # before the caches every repair round solved every section and move again: the extra
    # work grew with the copies (three times as many here)
    assert extra[6] == extra[2]


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_first_round_work_is_linear(monkeypatch, method):
    counter = Counter(monkeypatch)
    work = {k: counter.work(motif_path(k), method) for k in (2, 4, 8)}
    assert all(w[2] == 0 for w in work.values())
    # each copy of the motif adds the same sections and moves: the work is affine in the
    # number of waypoints (the path's two ends are the constant)
    for i in (0, 1) if method == "ruckig" else (0,):  # sections, and Ruckig's moves
        per_copy = (work[4][i] - work[2][i]) / 2
        assert per_copy > 0
        assert work[8][i] - work[4][i] == 4 * per_copy


def test_caches_change_no_result(monkeypatch):
    w = motif_path(3)
    check = corner_box(w, 5)
    with_cache = {
        m: time_path(DESIGN, w, LIMITS, method=m, check_states=check) for m in ("toppra", "ruckig")
    }
    # every key unique: nothing is ever found in the caches
    monkeypatch.setattr(toppra_method, "section_key", lambda *a: object())
    monkeypatch.setattr(ruckig_method, "section_key", lambda *a: object())
    for method, traj in with_cache.items():
        fresh = time_path(DESIGN, w, LIMITS, method=method, check_states=check)
        assert traj.repairs == fresh.repairs > 0
        assert traj.duration == pytest.approx(fresh.duration, rel=1e-9)
        t = np.linspace(0.0, traj.duration, 2001)
        for a, b in zip(traj.curve.evaluate(t)[:3], fresh.curve.evaluate(t)[:3], strict=True):
            np.testing.assert_allclose(a, b, atol=1e-7)
