"""Working-mode changes: plans made of single-mode segments joined by serial-singularity
transits, and the library's one entry point :func:`plan` (exported as
``planner.planning.plan``), a dispatcher over the three kinds of goal.

A working mode changes only by crossing a serial singularity, which flips exactly one sign of
(s_axis, s_A, s_B) (``docs/conventions.md``); the assembly mode never changes (that would cross a
parallel singularity). For a goal in another working mode than the start:

1. *Mode sequences*: walks over the 8-mode graph (one sign flipped per edge) from the start's
   mode to a mode where the goal is valid, without revisiting a mode, with at most
   :data:`MAX_DETOUR` flips more than the signs that differ. They are ordered by number of
   transits, then by an estimated cost (the straight joint-space length start -> transit
   postures -> goal through the best sampled transits); every order of the flips is a walk.
2. *Transit postures*: with the design's region map (``options.region_map``, the map of
   the proof below), first along the map's *region walks* (:func:`region_walks`: chains of
   regions joined by the map's transits, from the start's region to a goal's; a mode may
   come back in another of its regions, which a mode walk cannot say), each step's transit
   postures from the map's transit cells next to its two regions (:func:`map_transits`:
   cells of the flip where the two other measures keep their signs with margin, moved onto
   the surface) and its crossings kept only when q_in lies in the step's first region and
   q_out in its second, in one round at the first share; where the map cannot place the
   start or the goals, the mode walks it cannot realise are left out
   (:func:`walk_possible`) and the rest guided the same way without regions; then, and
   without a map, sampled on each singular surface of the right
   kind (:func:`planner.transits.sample_transits`, seeded with ``options.seed``). Either kind
   is kept when valid for every non-serial rule (joint limits, assembly, kappa(A),
   clearance), nearest first to the straight line from the segment's start to the goal. Each is crossed by the straight
   motion q_in -> q_transit -> q_out along the gradient of the serial measure
   (:func:`planner.transits.crossing_through`); a crossing is kept when q_in and q_out are valid
   in their segments' checkers, both motions are certified by a ``serial_rules=False`` checker,
   and a dense walk (every :data:`CROSSING_CHECK_STEP` rad) finds the flipped measure with its
   'before' sign up to the transit and the other sign after it, and the two other measures
   >= ``margins.serial_min`` all along.
3. *Segments*: each planned with :func:`planner.planning.planner.plan_in_region` in its own
   mode's checker (every rule, serial margin included), from the previous q_out to the next
   q_in (the last one to the goal candidates); a segment that fails falls back to the next
   transit candidate, then to the next mode sequence, all within ``options.time_budget_s``,
   in rounds of growing per-segment budgets (:data:`ROUND_SHARES`): a segment between two
   disconnected components of a mode region fails cheaply before detours are tried.

*Proven infeasibility*: before the first OMPL search (and before a mode-change search),
:meth:`_Request.disproof` asks :func:`planner.analysis.regions.prove_disconnected` whether the
start and every goal candidate the request allows lie in different components of the
design's obstacle-free region map (:data:`PROOF_RESOLUTION` cells, cached per process, built
only while :data:`PROOF_MIN_BUDGET_S` of the budget remains); if so the answer is ``no_path``
at once with ``diagnostics.proven_infeasible`` and a message naming the regions. Obstacles only
remove postures, so the proof holds with them. A wall of obstacles needs theta1 too: with
obstacles, a search whose first try found nothing (single mode: the corridor's, or a short
plain search; mode change: :data:`OBSTACLE_PROOF_AFTER_S`) asks
:func:`planner.analysis.obstacle_regions.prove_disconnected_with_obstacles` (the 3-D grid, a
few to tens of milliseconds, so only for a plan that needs it) before it goes on with the rest
of the budget (:meth:`_Request.obstacle_disproof`).

Goals in the start's own mode go to the single-mode planner unchanged. A Cartesian target
with ``working_mode`` "any" is first planned in the start's mode; the mode change is tried when
that fails, or when its estimate is shorter than :data:`BETTER_RATIO` times the single-mode
path (the shorter solved path wins).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from itertools import pairwise

import numpy as np

from planner.analysis import obstacle_regions
from planner.analysis import regions as region_maps
from planner.design import Design
from planner.geometry import Obstacle
from planner.kinematics import WORKING_MODES, forward_batch, mode_signs
from planner.planning.planner import goal_candidates, plan_in_region, plan_single_mode, posture_mode
from planner.planning.problem import CartesianTarget, JointPosture, PlanOptions
from planner.planning.result import (
    Diagnostics,
    PlanPath,
    PlanResult,
    PlanStatus,
    Segment,
    Transit,
)
from planner.transits import (
    Crossing,
    crossing_through,
    kinds_flipping,
    sample_transits,
    transit_kind,
)
from planner.validity import Margins, ValidityChecker, densify

__all__ = [
    "BETTER_RATIO",
    "CROSSING_CHECK_STEP",
    "MAX_DETOUR",
    "PROOF_MIN_BUDGET_S",
    "PROOF_RESOLUTION",
    "ROUND_SHARES",
    "crossing_signs_hold",
    "map_transits",
    "mode_sequences",
    "path_state_checker",
    "plan",
    "plan_mode_change",
    "proof_region_map",
    "region_walks",
    "walk_possible",
]

logger = logging.getLogger(__name__)

#: Extra flips allowed beyond the signs that differ (a sign flipped there and back).
MAX_DETOUR = 2
#: Surface points drawn per transit kind and mode (before the validity filter).
TRANSIT_SAMPLES = 256
#: Valid crossings kept per transit step (the fallbacks when a segment fails).
CROSSINGS_PER_STEP = 6
#: Transit postures examined per step to find those crossings (nearest first).
CROSSING_TRIES = 40
#: Joint-space step (max-norm, rad) of the dense sign walk along a crossing.
CROSSING_CHECK_STEP = 0.002
#: "any" goal: a mode change is tried when its estimated length is below this fraction of
#: the single-mode path's length.
BETTER_RATIO = 0.7
#: Rounds of the search: in round r each segment search may use this share of
#: ``time_budget_s`` (capped by what remains). Most segments are straight motions or short
#: searches; a segment between two disconnected components of a mode region (split by the
#: literal joint limits or by parallel singularities) can never succeed, so short rounds over
#: every candidate and mode sequence come first, longer searches after.
ROUND_SHARES = (0.01, 0.1, 1.0)

#: Region walks (:func:`region_walks`) tried by the guided round: at most this many, with
#: up to :data:`REGION_DETOUR` transits more than the shortest.
REGION_WALKS = 16
REGION_DETOUR = 2

#: Cells per axis of the region map the planner consults (:mod:`planner.analysis.regions`).
#: 128 builds in about 25 ms on a loaded 2-core machine (256: 60-90 ms) and is as sound;
#: a finer map only proves more (fewer undecided cells).
PROOF_RESOLUTION = 128
#: A map not yet in the cache is built only when at least this much of the budget remains,
#: s (a cached map is consulted whatever the budget: a look-up costs microseconds).
PROOF_MIN_BUDGET_S = 0.1
#: With obstacles, the search time (s) after which a mode-change search that found nothing
#: asks the 3-D proof (:meth:`_Request.obstacle_disproof`) before it goes on: most plans
#: among obstacles are found well within it (``benchmarks/planning.py``), and a stuck one can
#: afford the proof's few to tens of milliseconds. A single-mode search asks it after its
#: first try (:func:`planner.planning.planner.plan_in_region`).
OBSTACLE_PROOF_AFTER_S = 0.03

_INDEX = {"axis": 0, "A": 1, "B": 2}
_FLIP_NAMES = ("axis", "A", "B")


def _mode_code(mode: str) -> int:
    """The integer of :func:`path_state_checker`'s sign-triple encoding for a mode label."""
    return sum((2 if ch == "+" else 0) * f for ch, f in zip(mode, (9, 3, 1), strict=True))


def _flip(mode: str, j: int) -> str:
    return mode[:j] + ("-" if mode[j] == "+" else "+") + mode[j + 1 :]


def mode_sequences(start_mode: str, goal_modes: Sequence[str], *, detour: int = MAX_DETOUR):
    """Walks over the mode graph from ``start_mode`` to any of ``goal_modes``.

    Each walk is a tuple of modes (start first) in which consecutive modes differ by one sign
    and no mode repeats; at most ``hamming + detour`` flips. Ordered by number of flips
    (fewest first), then lexicographically (the planner re-orders equal lengths by cost).
    """
    goals = set(goal_modes)
    out: list[tuple[str, ...]] = []

    def walk(path: tuple[str, ...], limit: int) -> None:
        if path[-1] in goals and len(path) > 1:
            out.append(path)
        if len(path) - 1 >= limit:
            return
        for j in range(3):
            nxt = _flip(path[-1], j)
            if nxt not in path:
                walk((*path, nxt), limit)

    for g in goals:
        hamming = sum(a != b for a, b in zip(start_mode, g, strict=True))
        walk((start_mode,), hamming + detour)
    unique = sorted(set(out), key=lambda p: (len(p), p))
    return [p for p in unique if p[-1] in goals]


@dataclass(frozen=True, slots=True)
class _Candidate:
    crossing: Crossing
    before: str
    after: str


class _ModeChangeSearch:
    """One request's search state: checkers, transit pools and crossings (cached)."""

    def __init__(
        self,
        design: Design,
        asm: str,
        margins: Margins,
        obstacles: Sequence[Obstacle],
        options: PlanOptions,
        deadline: float,
        rmap: region_maps.RegionMap | None = None,
    ) -> None:
        self.design, self.asm, self.margins = design, asm, margins
        self.rmap = rmap  # the region map guiding the search (None: sampled transits only)
        self.obstacles = tuple(obstacles)
        self.options, self.deadline = options, deadline
        self.rng = np.random.default_rng(options.seed)
        self._checkers: dict[str, ValidityChecker] = {}
        self.free = ValidityChecker(design, margins, self.obstacles, asm, "+++", serial_rules=False)
        self._pools: dict[tuple[str, str], tuple[np.ndarray, list[str]]] = {}
        self.pool_reasons: dict[tuple[str, str], str] = {}
        self.share = ROUND_SHARES[0]
        self._failed: dict[bytes, float] = {}  # segment key -> largest budget that failed
        self.searches = 0  # OMPL searches run by the segments
        self.map_pools: set[tuple[str, str]] = set()  # pools taken from the region map
        self._crossings: dict[bytes, list[_Candidate]] = {}

    def unguided(self) -> None:
        """From now on transit postures are sampled on the surfaces (the map's are dropped)."""
        self.rmap = None
        for key in self.map_pools:
            del self._pools[key]
        self.map_pools.clear()
        self._crossings.clear()

    @staticmethod
    def _flip(key: tuple[str, str]) -> int:
        """Index of the sign that differs between the two modes of ``key``."""
        return next(i for i in range(3) if key[0][i] != key[1][i])

    def checker(self, mode: str) -> ValidityChecker:
        if mode not in self._checkers:
            self._checkers[mode] = self.free.with_mode(mode, serial_rules=True)
        return self._checkers[mode]

    def pool(self, before: str, after: str) -> tuple[np.ndarray, list[str]]:
        """Transit postures (M, 3) between two adjacent modes, valid for the non-serial
        rules, and their kinds: from the region map's transit cells when it has some
        (:func:`map_transits`), else sampled at random on the singular surfaces."""
        key = (before, after)
        if key in self._pools:
            return self._pools[key]
        if self.rmap is not None:
            q = _map_transits_cached(self.rmap, self.asm, before, after)
            if len(q):  # theta1 is set along the line and checked in :meth:`crossings`
                q[:, 0] = np.clip(0.0, self.design.joint_min[0], self.design.joint_max[0])
                kinds = [transit_kind(self.design, x, self.asm, _FLIP_NAMES[self._flip(key)])
                         for x in q[:1]] * len(q)  # fmt: skip
                self._pools[key] = (q, kinds)
                self.map_pools.add(key)
                return self._pools[key]
        j = next(i for i in range(3) if before[i] != after[i])
        qs, kinds, drawn = [], [], 0
        for kind in kinds_flipping(_FLIP_NAMES[j]):
            q = sample_transits(
                self.design,
                kind,
                working_mode=before,
                assembly_mode=self.asm,
                n=TRANSIT_SAMPLES,
                rng=self.rng,
            )
            drawn += len(q)
            if len(q):
                q = q[self.free.is_valid(q)]
            qs.append(q)
            kinds += [kind] * len(q)
        q = np.vstack(qs) if qs else np.empty((0, 3))
        if len(q) == 0:
            kinds_txt = " or ".join(kinds_flipping(_FLIP_NAMES[j]))
            self.pool_reasons[key] = (
                f"{before} -> {after}: no posture on the {kinds_txt} surface exists in "
                f"assembly mode {self.asm} within the joint limits"
                if drawn == 0
                else f"{before} -> {after}: no {kinds_txt} posture is valid "
                "(joint limits, kappa_max, clearance)"
            )
        self._pools[key] = (q, kinds)
        return q, kinds

    def estimate(self, seq: tuple[str, ...], q_start: np.ndarray, q_goal: np.ndarray) -> float:
        """Straight joint-space length start -> best transits -> goal (greedy), inf when a
        step has no transit posture."""
        prev, total = q_start, 0.0
        for before, after in pairwise(seq):
            q, _ = self.pool(before, after)
            if len(q) == 0:
                return float("inf")
            score = np.linalg.norm(q - prev, axis=1) + np.linalg.norm(q - q_goal, axis=1)
            k = int(np.argmin(score))
            total += float(np.linalg.norm(q[k] - prev))
            prev = q[k]
        return total + float(np.linalg.norm(q_goal - prev))

    def crossings(
        self,
        before: str,
        after: str,
        q_from: np.ndarray,
        q_goal: np.ndarray,
        regions: tuple[int, int] | None = None,
    ) -> list[_Candidate]:
        """Up to :data:`CROSSINGS_PER_STEP` valid crossings before -> after, nearest first to
        the straight line q_from -> q_goal; with ``regions`` (ids of the region map), only
        crossings from the first region (q_in in its cells) into the second (q_out)."""
        q, _ = self.pool(before, after)
        if len(q) == 0:
            return []
        j = next(i for i in range(3) if before[i] != after[i])
        if (before, after) in self.map_pools:
            q = _theta1_along(q, q_from, q_goal, self.design)
            if regions is not None and self.rmap is not None:
                q = q[_near_regions(self.rmap, self.asm, regions, q)]
            q = q[self.free.is_valid(q)]
            if len(q) == 0:
                return []
        d_from = np.linalg.norm(q - q_from, axis=1)
        d_goal = np.linalg.norm(q - q_goal, axis=1)
        # nearest to the straight line first, interleaved with nearest to each end: the mode
        # regions are split (joint limits, parallel singularities), and a transit near the
        # start (or the goal) is more likely in its connected component
        rankings = [
            np.argsort(r, kind="stable")[:CROSSING_TRIES] for r in (d_from + d_goal, d_from, d_goal)
        ]  # the first CROSSING_TRIES of the interleaving come from these
        order = list(dict.fromkeys(int(k) for k in np.stack(rankings, axis=1).ravel()))
        out: list[tuple[bool, float, _Candidate]] = []
        for k in order[:CROSSING_TRIES]:
            if time.perf_counter() > self.deadline:
                break
            c = crossing_through(
                self.design,
                q[k],
                assembly_mode=self.asm,
                flipped=_FLIP_NAMES[j],
                sign_before=1 if before[j] == "+" else -1,
                margin=self.margins.serial_min * 1.05,
            )
            if c is None or not self._crossing_valid(c, before, after, j):
                continue
            if regions is not None and not self._joins(c, regions):
                continue
            cost = float(np.linalg.norm(c.q_in - q_from) + np.linalg.norm(c.q_out - q_goal))
            # a straight first segment is a strong hint of the same connected component
            direct = self.checker(before).motion_valid(q_from, c.q_in)
            out.append((not direct, cost, _Candidate(c, before, after)))
            # from the map's cells (next to the regions' shared boundary) a crossing whose
            # first segment is straight is the usual answer: two fallbacks are enough, and
            # none between two given regions (another region walk is the fallback there)
            guided = (before, after) in self.map_pools
            enough = 1 if regions is not None else 3
            if len(out) >= CROSSINGS_PER_STEP or (guided and len(out) >= enough and not out[0][0]):
                break
        out.sort(key=lambda x: (x[0], x[1]))
        return [c for _, _, c in out]

    def _joins(self, c: Crossing, regions: tuple[int, int]) -> bool:
        """Whether the crossing leaves from the map region ``regions[0]`` (its q_in lies in
        that region's cells) into ``regions[1]`` (q_out)."""
        if self.rmap is None:
            return True
        return all(
            rid in {r.id for r in region_maps.regions_at(self.rmap, q, self.asm)}
            for rid, q in zip(regions, (c.q_in, c.q_out), strict=True)
        )

    def _crossing_valid(self, c: Crossing, before: str, after: str, j: int) -> bool:
        if not (
            self.checker(before).is_valid_one(*c.q_in)
            and self.checker(after).is_valid_one(*c.q_out)
        ):
            return False
        if not (
            self.free.motion_valid(c.q_in, c.q_transit)
            and self.free.motion_valid(c.q_transit, c.q_out)
        ):
            return False
        return crossing_signs_hold(
            self.design, c, before, after, j, self.asm, self.margins.serial_min
        )

    def segment(self, mode: str, q_from: np.ndarray, q_goals: np.ndarray) -> PlanResult:
        remaining = self.deadline - time.perf_counter()
        budget = min(remaining, self.options.time_budget_s * self.share)
        key = mode.encode() + q_from.tobytes() + q_goals.tobytes()
        if budget <= 0 or self._failed.get(key, -1.0) >= budget:
            return PlanResult(PlanStatus.NO_PATH, "skipped", None)
        res = plan_in_region(
            self.checker(mode),
            q_from,
            q_goals,
            options=replace(self.options, time_budget_s=max(budget, 1e-3)),
        )
        self.searches += res.diagnostics.searches
        if not res.solved:
            self._failed[key] = budget
        return res

    def run(
        self,
        seq: tuple[str, ...],
        q_start: np.ndarray,
        q_goals: np.ndarray,
        regions: tuple[int, ...] | None = None,
    ) -> tuple[list[PlanResult], list[_Candidate]] | None:
        """Plan the walk ``seq`` (depth first over transit candidates); the segment results
        and the crossings used, or None. With ``regions`` (a :func:`region_walks` walk, one
        region id per mode of ``seq``) each crossing joins its step's two regions and the
        last segment aims at the goal candidates of the last region."""
        if regions is not None and self.rmap is not None:
            last = regions[-1]
            inside = [
                last in {r.id for r in region_maps.regions_at(self.rmap, g, self.asm)}
                for g in q_goals
            ]
            if any(inside):
                q_goals = q_goals[np.asarray(inside)]
        q_goal = q_goals[0]

        def step(i: int, q_from: np.ndarray) -> tuple[list[PlanResult], list[_Candidate]] | None:
            if time.perf_counter() > self.deadline:
                return None
            if i == len(seq) - 1:
                res = self.segment(seq[i], q_from, q_goals)
                return ([res], []) if res.solved else None
            pair = None if regions is None else (regions[i], regions[i + 1])
            key = (seq[i] + seq[i + 1]).encode() + q_from.tobytes() + q_goal.tobytes()
            key += b"" if pair is None else np.asarray(pair, dtype=np.int64).tobytes()
            if key not in self._crossings:
                self._crossings[key] = self.crossings(seq[i], seq[i + 1], q_from, q_goal, pair)
            for cand in self._crossings[key]:
                res = self.segment(seq[i], q_from, cand.crossing.q_in[None])
                if not res.solved:
                    continue
                rest = step(i + 1, cand.crossing.q_out)
                if rest is not None:
                    return [res, *rest[0]], [cand, *rest[1]]
                if time.perf_counter() > self.deadline:
                    return None
            return None

        return step(0, q_start)


#: Transit postures of the region maps (:func:`map_transits`) per (map, assembly mode,
#: before, after), the most recent :data:`_MAP_TRANSITS_SIZE` kept (the map is kept beside
#: its postures, so an id reused by a new map is never mistaken for the old one).
_MAP_TRANSITS: dict[tuple, tuple[region_maps.RegionMap, np.ndarray]] = {}
_MAP_TRANSITS_SIZE = 512


def _map_transits_cached(
    rmap: region_maps.RegionMap, asm: str, before: str, after: str
) -> np.ndarray:
    """:func:`map_transits`, computed once per map and flip (a copy: callers edit theta1)."""
    key = (id(rmap), asm, before, after)
    hit = _MAP_TRANSITS.get(key)
    if hit is None or hit[0] is not rmap:
        if len(_MAP_TRANSITS) >= _MAP_TRANSITS_SIZE:
            _MAP_TRANSITS.pop(next(iter(_MAP_TRANSITS)))
        hit = _MAP_TRANSITS[key] = (rmap, map_transits(rmap, asm, before, after))
    return hit[1].copy()


def walk_possible(
    rmap: region_maps.RegionMap,
    asm: str,
    seq: tuple[str, ...],
    q_start: np.ndarray,
    q_goals: np.ndarray,
) -> bool:
    """False only when the region map shows that no path follows the mode walk ``seq``:
    no chain of regions r_0 (holding ``q_start``, mode seq[0]), r_1, ... (mode seq[i]), each
    joined to the next by a transit of the map, ends in a region of mode seq[-1] holding a
    goal candidate of ``q_goals`` (K, 3). Each segment of a plan stays in one region of its
    mode and each crossing joins two regions the map joins (the argument of
    :func:`planner.analysis.regions.prove_disconnected`), so such a walk cannot succeed."""
    adj: dict[int, set[int]] = {}
    for t in rmap.transits:
        adj.setdefault(t.a, set()).add(t.b)
        adj.setdefault(t.b, set()).add(t.a)
    here = {r.id for r in region_maps.regions_at(rmap, q_start, asm) if r.working_mode == seq[0]}
    if not here:
        return True  # the map cannot place the start: it decides nothing
    for mode in seq[1:]:
        here = {b for a in here for b in adj.get(a, ()) if rmap.regions[b].working_mode == mode}
    ends = {
        r.id
        for g in np.atleast_2d(q_goals)
        for r in region_maps.regions_at(rmap, g, asm)
        if r.working_mode == seq[-1]
    }
    return bool(here & ends) or not ends


def region_walks(
    rmap: region_maps.RegionMap,
    asm: str,
    start_mode: str,
    q_start: np.ndarray,
    targets: dict[str, np.ndarray],
    *,
    detour: int = REGION_DETOUR,
    limit: int = REGION_WALKS,
) -> list[tuple[int, ...]]:
    """Chains of region ids r_0, ..., r_k of the map's transit graph: r_0 a region of
    ``start_mode`` holding ``q_start``, r_k a region of a mode of ``targets`` (mode -> (K, 3)
    goal candidates) holding one of its candidates, each region joined to the next by a
    transit of the map (so consecutive modes differ by one sign), no region twice; the
    fewest transits first, up to ``detour`` more than the fewest, at most ``limit`` walks.
    Empty when the map cannot place the start or any goal, or joins none of them.

    Why regions, not modes: the regions of one working mode are split (literal joint limits,
    parallel singularities), so the only chain from a start to its goal may be long (on the
    design 0.3/0.3/0.4 a goal one sign away, --+ to ---, is reached only through five
    transits, --+ -> +-+ -> +++ -> ++- -> +-- -> ---, beyond :data:`MAX_DETOUR`) or may come
    back to a mode in another of its regions, which :func:`mode_sequences` (no mode twice)
    cannot express; and a step between two given regions takes its crossings from where
    those two meet, not from anywhere on the surface (a crossing into the wrong region of
    the next mode dooms the rest of the walk)."""
    adj: dict[int, set[int]] = {}
    for t in rmap.transits:
        adj.setdefault(t.a, set()).add(t.b)
        adj.setdefault(t.b, set()).add(t.a)
    starts = sorted(
        r.id for r in region_maps.regions_at(rmap, q_start, asm) if r.working_mode == start_mode
    )
    ends = {
        r.id
        for mode, goals in targets.items()
        for g in np.atleast_2d(goals)
        for r in region_maps.regions_at(rmap, g, asm)
        if r.working_mode == mode
    }
    # transits from every region to the nearest end (breadth first from the ends)
    dist = dict.fromkeys(ends, 0)
    frontier = sorted(ends)
    while frontier:
        nxt = []
        for a in frontier:
            for b in sorted(adj.get(a, ())):
                if b not in dist:
                    dist[b] = dist[a] + 1
                    nxt.append(b)
        frontier = nxt
    reachable = [dist[s] for s in starts if s in dist]
    if not reachable:
        return []
    fewest = max(1, min(reachable))
    out: list[tuple[int, ...]] = []

    def extend(path: list[int], length: int) -> None:
        if len(out) >= limit:
            return
        if len(path) - 1 == length:
            if path[-1] in ends:
                out.append(tuple(path))
            return
        for b in sorted(adj.get(path[-1], ())):
            if b not in path and len(path) + dist.get(b, length + 1) <= length:
                extend([*path, b], length)

    for length in range(fewest, fewest + detour + 1):
        for s in starts:
            extend([s], length)
    return out


def _near_regions(
    rmap: region_maps.RegionMap, asm: str, regions: tuple[int, int], q: np.ndarray
) -> np.ndarray:
    """Which transit postures q (M, 3) lie within reach of a crossing (``max_step`` of
    :func:`planner.transits.crossing_through`, 0.5 rad, in cells) of both regions' cells: the
    candidates of a step between those two regions (the crossing's ends are then checked
    exactly by :meth:`_ModeChangeSearch._joins`)."""
    from scipy import ndimage

    from planner.kinematics import ASSEMBLY_MODES

    ai = ASSEMBLY_MODES.index(asm)
    reach = int(np.ceil(0.5 / min(rmap.h2, rmap.h3))) + 1
    lo = rmap.design.joint_min
    k2 = np.clip(np.floor((q[:, 1] - lo[1]) / rmap.h2).astype(int), 0, rmap.n - 1)
    k3 = np.clip(np.floor((q[:, 2] - lo[2]) / rmap.h3).astype(int), 0, rmap.n - 1)
    keep = np.ones(len(q), dtype=bool)
    for rid in regions:
        r = rmap.regions[rid]
        mask = rmap.labels[ai, WORKING_MODES.index(r.working_mode)] == r.label
        near = ndimage.maximum_filter(mask, size=2 * reach + 1)
        keep &= near[k3, k2]
    return keep


def map_transits(rmap: region_maps.RegionMap, asm: str, before: str, after: str) -> np.ndarray:
    """Transit postures (M, 3) (theta1 0) from the region map: the cells of the flip
    before -> after (``RegionMap.transit_cells``) where the two other signed measures are
    >= ``serial_min`` over the whole cell, each cell centre moved onto the surface where
    the flipped measure vanishes (Newton steps on (theta2, theta3)). Empty when the map has
    no such cell; the caller checks the non-serial rules and builds the crossings."""
    from planner.kinematics import ASSEMBLY_MODES
    from planner.transits import serial_measure

    j = next(i for i in range(3) if before[i] != after[i])
    ai = ASSEMBLY_MODES.index(asm)
    s_min = rmap.margins.serial_min
    mask = rmap.transit_cells[ai, j] > 0
    for k in range(3):
        if k != j:
            if before[k] == "+":
                mask &= rmap.measure_low[ai, k] >= s_min
            else:
                mask &= rmap.measure_high[ai, k] <= -s_min
    k3, k2 = np.nonzero(mask)
    if len(k3) == 0:
        return np.empty((0, 3))
    q = np.stack([np.zeros(len(k3)), rmap.theta2[k2], rmap.theta3[k3]], axis=1)
    flipped, h = _FLIP_NAMES[j], 1e-7
    for _ in range(4):
        stencil = np.concatenate([q, q + np.array([0, h, 0]), q + np.array([0, 0, h])])
        f = serial_measure(rmap.design, stencil, asm, flipped).reshape(3, -1)
        grad = (f[1:] - f[0]) / h
        norm2 = (grad**2).sum(axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            step = (f[0] / norm2)[:, None] * grad.T
        ok = np.all(np.isfinite(step), axis=1)
        q, step = q[ok], step[ok]
        k3, k2 = k3[ok], k2[ok]
        q[:, 1:] -= step
    if len(q) == 0:
        return np.empty((0, 3))
    fb = forward_batch(rmap.design, q, asm)
    f = fb.serial_measures[:, j]
    keep = np.isfinite(f) & fb.ok
    for k in range(3):  # the moved posture keeps the other two signs with the margin
        if k != j:
            sign = 1.0 if before[k] == "+" else -1.0
            with np.errstate(invalid="ignore"):
                keep &= sign * fb.serial_measures[:, k] >= s_min
    reach = 1.5 * max(rmap.h2, rmap.h3)
    near = (np.abs(q[:, 1] - rmap.theta2[k2]) <= reach) & (
        np.abs(q[:, 2] - rmap.theta3[k3]) <= reach
    )
    lo, hi = rmap.design.joint_min, rmap.design.joint_max
    inside = (q[:, 1] >= lo[1]) & (q[:, 1] <= hi[1]) & (q[:, 2] >= lo[2]) & (q[:, 2] <= hi[2])
    return q[keep & (np.abs(f) < 1e-9) & near & inside]


def _theta1_along(
    q: np.ndarray, q_from: np.ndarray, q_goal: np.ndarray, design: Design
) -> np.ndarray:
    """Transit postures ``q`` with theta1 set where the straight line q_from -> q_goal is
    nearest in (theta2, theta3) (no serial measure depends on theta1, so the postures stay
    on their surface), within theta1's limits."""
    d = q_goal[1:] - q_from[1:]
    dd = float(d @ d)
    t = np.clip((q[:, 1:] - q_from[1:]) @ d / dd, 0.0, 1.0) if dd > 0 else np.zeros(len(q))
    out = q.copy()
    out[:, 0] = np.clip(q_from[0] + t * (q_goal[0] - q_from[0]), design.joint_min[0],
                        design.joint_max[0])  # fmt: skip
    return out


def crossing_signs_hold(
    design: Design,
    c: Crossing,
    before: str,
    after: str,
    j: int,
    asm: str,
    serial_min: float,
    *,
    step: float = CROSSING_CHECK_STEP,
) -> bool:
    """Dense walk along a crossing: the flipped measure j has ``before``'s sign strictly
    before the transit and ``after``'s strictly after it; the two others keep their (shared)
    signs with magnitude >= ``serial_min``; every posture assembles."""
    halves = (
        densify(np.stack([c.q_in, c.q_transit]), step)[:-1],
        densify(np.stack([c.q_transit, c.q_out]), step)[1:],
    )
    for line, mode in zip(halves, (before, after), strict=True):
        b = forward_batch(design, line, asm)
        if not b.ok.all():
            return False
        signs = mode_signs(mode).astype(float)
        m = b.serial_measures * signs
        if not np.all(m[:, j] > 0):
            return False
        others = [k for k in range(3) if k != j]
        if not np.all(m[:, others] >= serial_min):
            return False
    return True


def _assemble(
    segments: list[PlanResult], cands: list[_Candidate], free: ValidityChecker, asm: str
) -> tuple[PlanPath, Diagnostics]:
    """Join segment paths and crossings into one path: q_in, q_transit, q_out consecutive."""
    parts: list[np.ndarray] = []
    segs: list[Segment] = []
    transits: list[Transit] = []
    start_index = 0
    min_clear, max_kappa, min_serial, length = np.inf, -np.inf, np.inf, 0.0
    for i, res in enumerate(segments):
        assert res.path is not None
        w = res.path.waypoints
        d = res.diagnostics
        min_clear = min(min_clear, d.min_clearance)
        max_kappa = max(max_kappa, d.max_kappa_A)
        min_serial = min(min_serial, d.min_serial_margin)
        length += d.path_length
        mode = res.path.segments[0].working_mode
        if i == 0:
            parts.append(w)
        else:  # starts at the previous crossing's q_out, already appended
            parts.append(w[1:])
        n_so_far = sum(len(p) for p in parts)
        if i < len(cands):
            c = cands[i].crossing
            parts.append(c.q_transit[None])
            parts.append(c.q_out[None])
            t_index = n_so_far  # index of q_transit
            segs.append(Segment(mode, asm, start_index, t_index))
            transits.append(
                Transit(t_index, tuple(float(x) for x in c.q_transit), c.kind, c.flipped)
            )
            start_index = t_index
            rep = free.check_path(np.stack([c.q_in, c.q_transit, c.q_out]), certify=False)
            min_clear = min(min_clear, rep.min_clearance)
            max_kappa = max(max_kappa, rep.max_kappa_A)
            length += rep.length
        else:
            segs.append(Segment(mode, asm, start_index, n_so_far - 1))
    waypoints = np.vstack(parts)
    path = PlanPath(waypoints, tuple(segs), tuple(transits))
    diag = Diagnostics(
        planning_time_s=0.0,
        path_length=length,
        min_clearance=min_clear,
        max_kappa_A=max_kappa,
        min_serial_margin=min_serial,
        planner="+".join(dict.fromkeys(r.diagnostics.planner for r in segments)),
        attempts=sum(r.diagnostics.attempts for r in segments),
    )
    return path, diag


def plan_mode_change(
    design: Design,
    start: JointPosture,
    start_mode: str,
    targets: dict[str, np.ndarray],
    *,
    obstacles: Sequence[Obstacle],
    margins: Margins,
    options: PlanOptions,
    t0: float,
    deadline: float,
    rmap: region_maps.RegionMap | None = None,
) -> PlanResult:
    """Plan from ``start`` (in ``start_mode``) to the goal candidates ``targets`` (mode ->
    (K, 3) valid joint goals in that mode) through transits; see the module docstring.
    With the design's region map ``rmap`` the transit postures come from its transit cells
    (sampled surfaces where it has none)."""
    search = _ModeChangeSearch(
        design, start.assembly_mode, margins, obstacles, options, deadline, rmap
    )
    tried: set[tuple[str, ...]] = set()

    def attempt(seq: tuple[str, ...], regions: tuple[int, ...] | None) -> PlanResult | None:
        tried.add(seq)
        out = search.run(seq, start.q, targets[seq[-1]], regions)
        if out is None:
            return None
        path, diag = _assemble(out[0], out[1], search.free, start.assembly_mode)
        diag = replace(diag, planning_time_s=time.perf_counter() - t0, searches=search.searches)
        modes = " -> ".join(seq)
        return PlanResult(
            PlanStatus.SOLVED, f"solved through {len(seq) - 1} transit(s): {modes}", path, diag
        )

    # the map's region walks first (fewest transits first), when it can place the start and
    # a goal: one round at the first share
    walks_by_region = (
        region_walks(rmap, start.assembly_mode, start_mode, start.q, targets)
        if rmap is not None
        else []
    )
    search.share = ROUND_SHARES[0]
    for walk in walks_by_region:
        if time.perf_counter() > deadline:
            break
        solved = attempt(tuple(rmap.regions[r].working_mode for r in walk), walk)
        if solved is not None:
            return solved
    seqs = mode_sequences(start_mode, list(targets))
    if rmap is not None:  # walks the region map's transit graph cannot realise go (all
        # kept when none is left: longer walks than these may exist, the search says so)
        seqs = [s for s in seqs if walk_possible(rmap, start.assembly_mode, s, start.q,
                                                 targets[s[-1]])] or seqs  # fmt: skip
    ranked = []
    for seq in seqs:
        est = search.estimate(seq, start.q, targets[seq[-1]][0])
        if np.isfinite(est):
            ranked.append((len(seq), est, seq))
    ranked.sort(key=lambda x: (x[0], x[1]))
    if not ranked:
        reasons = sorted(set(search.pool_reasons.values()))
        return PlanResult(
            PlanStatus.UNREACHABLE,
            f"working mode {' or '.join(sorted(targets))} cannot be reached from {start_mode} "
            f"in assembly mode {start.assembly_mode}: no transit exists on any mode sequence ("
            + "; ".join(reasons)
            + ")",
            None,
            Diagnostics(planning_time_s=time.perf_counter() - t0),
        )
    # guided by the map without regions (when it placed neither), then today's rounds on
    # sampled surfaces
    rounds = [(share, False) for share in ROUND_SHARES]
    if rmap is not None and not walks_by_region:
        rounds = [(ROUND_SHARES[0], True), *rounds]
    for share, guided in rounds:
        search.share = share
        if not guided and search.rmap is not None:
            search.unguided()
        for _, _, seq in ranked:
            if time.perf_counter() > deadline:
                break
            solved = attempt(seq, None)
            if solved is not None:
                return solved
    n_seqs = len({seq for _, _, seq in ranked} | tried)
    return PlanResult(
        PlanStatus.NO_PATH,
        f"no path found within {options.time_budget_s:g} s through transits "
        f"({len(tried)} of {n_seqs} mode sequences tried)",
        None,
        Diagnostics(planning_time_s=time.perf_counter() - t0, searches=search.searches),
    )


def plan(
    design: Design,
    start: JointPosture,
    goal: JointPosture | CartesianTarget,
    *,
    obstacles: Sequence[Obstacle] = (),
    margins: Margins | None = None,
    options: PlanOptions | None = None,
) -> PlanResult:
    """Plan a valid joint path from ``start`` to ``goal``, changing working mode through serial
    singularities where the goal needs it (the assembly mode never changes). The library's
    one entry point, exported as ``planner.planning.plan``; the wire, the service and the
    CLI call it.

    One function per kind of goal: :func:`_plan_to_joint_goal`,
    :func:`_plan_to_point_in_mode` (Cartesian target in a given working mode) and
    :func:`_plan_to_point_in_any_mode` (``working_mode`` 'any'). Each asks the single-mode
    planner (:func:`planner.planning.planner.plan_single_mode`) first, and plans through
    transits (:func:`plan_mode_change`) when that answer calls for it.

    Parameters
    ----------
    design : the manipulator.
    start : joint posture (its working and assembly modes come from it).
    goal : joint posture (in any working mode of the start's assembly mode), or Cartesian
        target (a specific working mode, or 'any').
    obstacles : spheres, boxes, capsules (or wire dictionaries).
    margins : default :class:`Margins`.
    options : default :class:`PlanOptions`; ``options.time_budget_s`` bounds the whole
        search (every segment and fallback).

    Returns
    -------
    PlanResult
        ``solved`` with ``path.segments`` (one per working mode visited) and
        ``path.transits`` (one per sign flip; consecutive segments share the transit
        waypoint); ``invalid_start`` / ``invalid_goal`` naming the broken rule and its value;
        ``unreachable`` when the goal lies in the other assembly mode, out of reach, breaks a
        rule in every joint solution, or no mode sequence has a transit posture (the message
        says why); ``no_path`` when the budget ran out.
    """
    t0 = time.perf_counter()
    options = options if options is not None else PlanOptions()
    request = _Request(
        design,
        start,
        tuple(obstacles),
        margins if margins is not None else Margins(),
        options,
        t0,
        t0 + options.time_budget_s,
    )
    if isinstance(goal, JointPosture):
        return _plan_to_joint_goal(request, goal)
    if goal.working_mode == "any":
        return _plan_to_point_in_any_mode(request, goal)
    return _plan_to_point_in_mode(request, goal)


@dataclass(frozen=True, slots=True)
class _Request:
    """What every step of :func:`plan` shares: the problem, its clock and its deadline."""

    design: Design
    start: JointPosture
    obstacles: tuple[Obstacle, ...]
    margins: Margins
    options: PlanOptions
    t0: float
    deadline: float
    #: goal candidates of a Cartesian target per working mode, once computed (see
    #: :meth:`goal_candidates`), and why each mode has none
    _targets: dict[str, np.ndarray] = field(default_factory=dict)
    _whys: dict[str, str] = field(default_factory=dict)
    #: every goal set :meth:`disproof` was asked about, in order (the 3-D proof reuses them)
    _asked: list[np.ndarray] = field(default_factory=list)

    def single_mode(
        self,
        goal: JointPosture | CartesianTarget,
        *,
        share: float = 1.0,
        before_search: Callable[[np.ndarray], PlanResult | None] | None = None,
    ) -> PlanResult:
        """The single-mode plan to ``goal`` with ``share`` of the time budget; by default
        the region map's proof (:meth:`disproof`) runs just before its first OMPL search.
        Among obstacles, a first try that found nothing asks :meth:`obstacle_disproof`
        about the goals that proof was asked about (every candidate the request allows)
        before the rest of the budget is searched."""
        t0 = time.perf_counter()
        options = self.options
        if share != 1.0:
            options = replace(options, time_budget_s=options.time_budget_s * share)

        def when_stuck(goals: np.ndarray) -> PlanResult | None:
            asked = self._asked[-1] if self._asked else goals
            return self.obstacle_disproof(asked, searched_s=time.perf_counter() - t0)

        return plan_single_mode(
            self.design, self.start, goal,
            obstacles=self.obstacles, margins=self.margins, options=options,
            before_search=self.disproof if before_search is None else before_search,
            when_stuck=when_stuck if options.region_map else None,
        )  # fmt: skip

    def _sliced(self, options: PlanOptions) -> bool:
        """Whether a mode change among obstacles first searches for
        :data:`OBSTACLE_PROOF_AFTER_S` only, then asks :meth:`obstacle_disproof`."""
        return bool(self.obstacles and options.region_map) and (
            options.time_budget_s > 2.0 * OBSTACLE_PROOF_AFTER_S
        )

    def obstacle_disproof(self, goals: np.ndarray, *, searched_s: float) -> PlanResult | None:
        """``no_path`` with ``diagnostics.proven_infeasible`` when the obstacles close every
        path from the start to the goal candidates ``goals`` (K, 3) (every candidate the
        request allows), proven on the 3-D grid of
        :func:`planner.analysis.obstacle_regions.prove_disconnected_with_obstacles`; None
        when it cannot. ``searched_s``: how long the search ran before (for the message)."""
        if len(goals) == 0:
            return None
        asm = self.start.assembly_mode
        proof = obstacle_regions.prove_disconnected_with_obstacles(
            self.design, self.margins, self.obstacles, self.start.q, goals, asm
        )
        if not proof.proven:
            return None
        n1, n3, n2 = proof.shape
        n_goals = len(np.atleast_2d(goals))
        which = "the goal" if n_goals == 1 else f"any of its {n_goals} goal candidates"
        message = (
            f"no valid path exists (proven by the region map with obstacles, {n1} x {n3} x "
            f"{n2} cells over (theta1, theta3, theta2), after {searched_s * 1e3:.0f} ms of "
            f"search): in assembly mode {asm} the obstacles cut the start off from {which}: "
            f"the {proof.visited} cells reachable from the start hold no goal, and every path "
            "out of them crosses cells where a link surely comes closer to an obstacle than "
            "link_radius + clearance, or a posture breaks a rule (joint limits, kappa_max, "
            "serial_min)"
        )
        logger.info("plan no_path (proven with obstacles): %s", message)
        return PlanResult(
            PlanStatus.NO_PATH,
            message,
            None,
            Diagnostics(
                planning_time_s=time.perf_counter() - self.t0,
                planner="region_map",
                proven_infeasible=True,
            ),
        )

    def region_map(self) -> region_maps.RegionMap | None:
        """The design's obstacle-free region map at :data:`PROOF_RESOLUTION`, when it is
        cheap now: cached, or built while at least :data:`PROOF_MIN_BUDGET_S` of the budget
        remains; None otherwise, or when ``options.region_map`` is off."""
        return proof_region_map(self.design, self.margins, self.options, self.deadline)

    def disproof(self, goals: np.ndarray) -> PlanResult | None:
        """``no_path`` with ``diagnostics.proven_infeasible`` when the region map proves that
        no valid path joins the start to any of the goal candidates ``goals`` (K, 3) (every
        candidate the request allows; valid postures); None when it cannot.

        The argument is :func:`planner.analysis.regions.prove_disconnected`'s: the map is
        obstacle-free, and obstacles only remove postures, so its proof holds with them. The
        answer names the regions of the start and of the goals, no search run."""
        self._asked.append(goals)
        rmap = self.region_map()
        if rmap is None or len(goals) == 0:
            return None
        asm = self.start.assembly_mode
        if not region_maps.prove_disconnected(rmap, self.start.q, goals, asm):
            return None
        message = _disproof_message(rmap, self.start, goals)
        logger.info("plan no_path (proven): %s", message)
        return PlanResult(
            PlanStatus.NO_PATH,
            message,
            None,
            Diagnostics(
                planning_time_s=time.perf_counter() - self.t0,
                planner="region_map",
                proven_infeasible=True,
            ),
        )

    def start_mode(self) -> str | None:
        """The start's working mode (None where it is undefined)."""
        return posture_mode(self.design, self.start)

    def mode_change(
        self, start_mode: str, targets: dict[str, np.ndarray], *, prove: bool = True
    ) -> PlanResult:
        """:func:`plan_mode_change` to the goal candidates ``targets`` (mode -> (K, 3)),
        after the region map's proof (:meth:`disproof`) over all of them when ``prove``
        (only when ``targets`` are all the candidates the request allows)."""
        goals = np.vstack(list(targets.values()))
        proof = self.disproof(goals) if prove else None
        if proof is not None:
            return proof
        t0 = time.perf_counter()
        rmap = self.region_map()

        def run(deadline: float) -> PlanResult:
            return plan_mode_change(
                self.design, self.start, start_mode, targets,
                obstacles=self.obstacles, margins=self.margins, options=self.options,
                t0=self.t0, deadline=deadline, rmap=rmap,
            )  # fmt: skip

        if not (prove and self._sliced(self.options)):
            return run(self.deadline)
        first = run(min(self.deadline, t0 + OBSTACLE_PROOF_AFTER_S))
        if first.status is not PlanStatus.NO_PATH:
            return first
        proof = self.obstacle_disproof(goals, searched_s=time.perf_counter() - t0)
        if proof is not None:
            return replace(proof, diagnostics=replace(
                proof.diagnostics, searches=first.diagnostics.searches))  # fmt: skip
        second = run(self.deadline)
        searches = first.diagnostics.searches + second.diagnostics.searches
        return replace(second, diagnostics=replace(second.diagnostics, searches=searches))

    def goal_candidates(
        self, p: np.ndarray, modes: Sequence[str]
    ) -> tuple[dict[str, np.ndarray], dict[str, str]]:
        """Valid joint goals of the point ``p`` (the request's goal point) in each working
        mode of ``modes`` (mode -> (K, 3), modes with none left out), and why each mode left
        out has none; computed once per mode."""
        asm = self.start.assembly_mode
        for m in modes:
            if m in self._targets or m in self._whys:
                continue
            checker = ValidityChecker(self.design, self.margins, self.obstacles, asm, m)
            cands, why = goal_candidates(self.design, CartesianTarget(p, m), checker, self.start.q)
            if len(cands):
                self._targets[m] = cands
            else:
                self._whys[m] = why
        targets = {m: self._targets[m] for m in modes if m in self._targets}
        whys = {m: self._whys[m] for m in modes if m in self._whys}
        return targets, whys

    def finish(self, status: PlanStatus, message: str) -> PlanResult:
        """An answer without a path, timed from the request's start."""
        logger.info("plan %s: %s", status.value, message)
        return PlanResult(status, message, None, Diagnostics(time.perf_counter() - self.t0))


def _plan_to_joint_goal(request: _Request, goal: JointPosture) -> PlanResult:
    """A joint goal: the single-mode plan, or through transits when the goal lies in another
    working mode of the start's assembly mode (the single-mode planner answers every other
    case, checks and messages included, at no extra cost)."""
    first = request.single_mode(goal)
    if first.status is not PlanStatus.UNREACHABLE:
        return first
    start_mode = request.start_mode()
    goal_mode = posture_mode(request.design, goal)
    if (
        start_mode is None  # pragma: no cover - the single-mode planner said invalid_start
        or goal.assembly_mode != request.start.assembly_mode
        or goal_mode in (None, start_mode)
    ):
        return first
    # the single-mode planner checked the goal in its own mode already
    return request.mode_change(start_mode, {goal_mode: goal.q[None].copy()})


def _plan_to_point_in_mode(request: _Request, goal: CartesianTarget) -> PlanResult:
    """A Cartesian target in a given working mode: the single-mode plan, or through
    transits when that mode is not the start's."""
    first = request.single_mode(goal)
    if first.status is not PlanStatus.UNREACHABLE:
        return first
    start_mode = request.start_mode()
    if start_mode is None:  # pragma: no cover - the single-mode planner said invalid_start
        return first
    if goal.working_mode == start_mode:
        return first
    targets, whys = request.goal_candidates(goal.p, [goal.working_mode])
    if not targets:
        return request.finish(PlanStatus.UNREACHABLE, whys[goal.working_mode])
    return request.mode_change(start_mode, targets)


def _plan_to_point_in_any_mode(request: _Request, goal: CartesianTarget) -> PlanResult:
    """A Cartesian target in working mode 'any': the start's mode first with half the
    budget, then through transits to the other modes when that fails, or when their
    estimate is shorter than :data:`BETTER_RATIO` times the single-mode path."""
    start_mode = request.start_mode()

    def every_mode_disproof(cands: np.ndarray) -> PlanResult | None:
        # the proof must cover the goal's candidates in every working mode, not only the
        # start's ``cands``
        targets, _ = request.goal_candidates(goal.p, [m for m in WORKING_MODES if m != start_mode])
        return request.disproof(np.vstack([cands, *targets.values()]))

    first = request.single_mode(goal, share=0.5, before_search=every_mode_disproof)
    if first.status is PlanStatus.INVALID_START or first.diagnostics.proven_infeasible:
        return first
    if start_mode is None:  # pragma: no cover - the single-mode planner said invalid_start
        return first
    others = [m for m in WORKING_MODES if m != start_mode]
    targets, whys = request.goal_candidates(goal.p, others)
    if not targets:
        if first.solved or first.status is not PlanStatus.UNREACHABLE:
            return first
        return request.finish(
            PlanStatus.UNREACHABLE,
            f"the goal point is unreachable in every working mode: in {start_mode} "
            f"{first.message}; " + "; ".join(f"in {m} {w}" for m, w in whys.items()),
        )
    if first.solved:
        return _shorter_through_transits(request, first, start_mode, targets)
    if first.status is PlanStatus.NO_PATH:  # the start's own candidates count too
        own, _ = request.goal_candidates(goal.p, [start_mode])
        proof = request.disproof(np.vstack([*own.values(), *targets.values()]))
        if proof is not None:
            return proof
    # ``targets`` are all the candidates only when the start's mode has none
    other = request.mode_change(start_mode, targets, prove=first.status is PlanStatus.UNREACHABLE)
    if other.solved or first.status is PlanStatus.UNREACHABLE:
        return other
    return other if other.status is PlanStatus.NO_PATH else first


def _shorter_through_transits(
    request: _Request, first: PlanResult, start_mode: str, targets: dict[str, np.ndarray]
) -> PlanResult:
    """The shorter of the solved single-mode plan ``first`` and a plan through transits to
    ``targets``; the transit search runs only when it may beat ``first`` by
    :data:`BETTER_RATIO`."""
    limit = BETTER_RATIO * first.diagnostics.path_length
    # a path is never shorter than the straight distance to its goal: skip the transit
    # sampling when no goal candidate of another mode is close enough
    bound = min(float(np.linalg.norm(c[0] - request.start.q)) for c in targets.values())
    if not bound < limit:
        return first
    search = _ModeChangeSearch(
        request.design, request.start.assembly_mode, request.margins, request.obstacles,
        request.options, request.deadline,
    )  # fmt: skip
    best = min(
        search.estimate(seq, request.start.q, targets[seq[-1]][0])
        for seq in mode_sequences(start_mode, list(targets))
    )
    if not best < limit:
        return first
    other = request.mode_change(start_mode, targets, prove=False)
    if other.solved and other.diagnostics.path_length < first.diagnostics.path_length:
        return other
    planning_time_s = time.perf_counter() - request.t0
    return replace(first, diagnostics=replace(first.diagnostics, planning_time_s=planning_time_s))


def proof_region_map(
    design: Design, margins: Margins, options: PlanOptions, deadline: float
) -> region_maps.RegionMap | None:
    """The design's obstacle-free region map at :data:`PROOF_RESOLUTION` for a proof, when it
    is cheap now: cached, or built while at least :data:`PROOF_MIN_BUDGET_S` remains before
    ``deadline`` (a :func:`time.perf_counter` value); None otherwise, or when
    ``options.region_map`` is off."""
    if not options.region_map:
        return None
    rmap = region_maps.cached_region_map(design, margins, PROOF_RESOLUTION)
    if rmap is None and deadline - time.perf_counter() >= PROOF_MIN_BUDGET_S:
        rmap = region_maps.region_map(design, margins, PROOF_RESOLUTION)
    return rmap


def _disproof_message(rmap: region_maps.RegionMap, start: JointPosture, goals: np.ndarray) -> str:
    """The ``no_path`` message of a proof: the regions (id, working mode, union-graph
    component) holding the start and the goal candidates."""
    asm = start.assembly_mode

    def names(q: np.ndarray) -> list[str]:
        return [
            f"region {r.id} (working mode {r.working_mode}, component {r.component})"
            for r in region_maps.regions_at(rmap, q, asm)
        ]

    at_start = names(start.q)
    at_goals = list(dict.fromkeys(n for g in np.atleast_2d(goals) for n in names(g)))
    shown = ", ".join(at_goals[:4]) + (
        f" and {len(at_goals) - 4} more" if len(at_goals) > 4 else ""
    )
    n_goals = len(np.atleast_2d(goals))
    which = "the goal lies in" if n_goals == 1 else f"its {n_goals} goal candidates lie in"
    return (
        f"no valid path exists (proven by the region map, {rmap.n} x {rmap.n} cells, no "
        f"search run): in assembly mode {asm} the start lies in {', '.join(at_start)}, "
        f"{which} {shown}; no chain of regions and serial transits joins them, so every "
        "path between them crosses a posture that breaks a rule (joint limits, kappa_max, "
        "serial_min)"
    )


def path_state_checker(
    design: Design,
    margins: Margins,
    obstacles: Sequence[Obstacle],
    path: PlanPath,
    *,
    near: float = 0.0,
) -> Callable[[np.ndarray], np.ndarray]:
    """The validity rules of a planned path for a timed trajectory near it: Q (M, 3) ->
    valid (M,) bool.

    A posture is valid when it satisfies every rule of the checker of its own working mode,
    that mode being one of the path's segments'; or when it lies within ``near`` + 1e-9 rad
    (joint space) of a crossing (the motions q_in -> q_transit -> q_out of a transit), keeps
    the two working-mode signs that the transit does not flip, and satisfies every
    non-serial rule (``serial_rules=False``). ``near`` is the timing's corner allowance
    (``max_deviation``).
    """
    segs = path.segments
    asm = segs[0].assembly_mode if segs else "+"
    free = ValidityChecker(design, margins, obstacles, asm, "+++", serial_rules=False)
    checkers = {s.working_mode: free.with_mode(s.working_mode, serial_rules=True) for s in segs}
    w = np.asarray(path.waypoints, dtype=float)
    crossings = []
    for t in path.transits:
        if 0 < t.index < len(w) - 1:
            before = next(s.working_mode for s in segs if s.end_index == t.index)
            crossings.append((w[t.index - 1], w[t.index + 1], _INDEX[t.flipped], before))

    def check(q: np.ndarray) -> np.ndarray:
        q = np.atleast_2d(np.asarray(q, dtype=float))
        fb = forward_batch(design, q, asm)
        signs = fb.working_mode_signs
        valid = np.zeros(len(q), dtype=bool)
        code = (signs.astype(np.int64) + 1) @ np.array([9, 3, 1])  # one integer per sign triple
        for mode, chk in checkers.items():
            sel = code == _mode_code(mode)
            if sel.any():
                valid[sel] = chk.is_valid(q[sel])
        rest = ~valid
        if crossings and rest.any():
            free_ok = np.zeros(len(q), dtype=bool)
            free_ok[rest] = free.is_valid(q[rest])
            for a, b, j, before in crossings:
                ab = b - a
                t = np.clip((q - a) @ ab / float(ab @ ab), 0.0, 1.0)
                dist = np.linalg.norm(a + t[:, None] * ab - q, axis=1)
                others = [k for k in range(3) if k != j]
                want = mode_signs(before)[others]
                keep = np.all(signs[:, others] == want, axis=1)
                valid |= rest & free_ok & keep & (dist <= near + 1e-9)
        return valid

    return check
