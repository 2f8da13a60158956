"""Working-mode changes: plans made of single-mode segments joined by serial-singularity
transits (:func:`plan_mode_change`).

For a goal in another working mode than the start's (the dispatcher
:func:`planner.planning.plan` calls this when the single-mode plan cannot reach it):

1. *Mode sequences* (:func:`planner.planning.mode_graph.mode_sequences`): walks over the
   mode graph from the start's mode to a mode where the goal is valid, ordered by number of
   transits, then by an estimated cost (the straight joint-space length start -> transit
   postures -> goal through the best sampled transits).
2. *Transit postures*: with the design's region map, first along the map's region walks, then
   the mode walks it can realise, guided by its transit cells
   (:mod:`planner.planning.region_walks`, in one round at the first share); then, and
   without a map, sampled on each singular surface of the right kind
   (:func:`planner.transits.sample_transits`, seeded with ``options.seed``). Either kind is
   kept when valid for every non-serial rule (joint limits, assembly, kappa(A),
   clearance), nearest first to the straight line from the segment's start to the goal,
   and crossed as :mod:`planner.planning.crossings` says (a crossing is kept only when it
   is valid there).
3. *Segments*: each planned with :func:`planner.planning.single_mode.plan_in_region` in its own
   mode's checker (every rule, serial margin included), from the previous q_out to the next
   q_in (the last one to the goal candidates); a segment that fails falls back to the next
   transit candidate, then to the next mode sequence, all within ``options.time_budget_s``,
   in rounds of growing per-segment budgets (:data:`ROUND_SHARES`): a segment between two
   disconnected components of a mode region fails cheaply before detours are tried.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from itertools import pairwise

import numpy as np

from planner.analysis import regions as region_maps
from planner.design import Design
from planner.geometry import Obstacle
from planner.planning.crossings import crossing_signs_hold
from planner.planning.mode_graph import FLIP_NAMES, flipped_sign, mode_sequences
from planner.planning.problem import JointPosture, PlanOptions
from planner.planning.region_walks import (
    cached_map_transits,
    near_regions,
    region_walks,
    theta1_along,
    walk_possible,
)
from planner.planning.result import (
    Diagnostics,
    PlanPath,
    PlanResult,
    PlanStatus,
    Segment,
    Transit,
)
from planner.planning.single_mode import plan_in_region
from planner.transits import (
    Crossing,
    crossing_through,
    kinds_flipping,
    sample_transits,
    transit_kind,
)
from planner.validity import Margins, ValidityChecker

__all__ = ["ROUND_SHARES", "estimated_transit_length", "plan_mode_change"]

#: Surface points drawn per transit kind and mode (before the validity filter).
TRANSIT_SAMPLES = 256
#: Valid crossings kept per transit step (the fallbacks when a segment fails).
CROSSINGS_PER_STEP = 6
#: Transit postures examined per step to find those crossings (nearest first).
CROSSING_TRIES = 40
#: Rounds of the search: in round r each segment search may use this share of
#: ``time_budget_s`` (capped by what remains). Most segments are straight motions or short
#: searches; a segment between two disconnected components of a mode region (split by the
#: literal joint limits or by parallel singularities) can never succeed, so short rounds over
#: every candidate and mode sequence come first, longer searches after.
ROUND_SHARES = (0.01, 0.1, 1.0)


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
        self._map = rmap  # the design's map, kept for :meth:`guided` after :meth:`unguided`
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

    def guided(self) -> None:
        """From now on transit postures come from the region map again (after
        :meth:`unguided`): a region walk needs the map's transits between its regions. The
        sampled pools are dropped (kept: the failed segments, so none is searched twice at
        one budget)."""
        if self.rmap is self._map:
            return
        self.rmap = self._map
        self._pools.clear()
        self._crossings.clear()

    def checker(self, mode: str) -> ValidityChecker:
        if mode not in self._checkers:
            self._checkers[mode] = self.free.with_mode(mode, serial_rules=True)
        return self._checkers[mode]

    def pool(self, before: str, after: str) -> tuple[np.ndarray, list[str]]:
        """Transit postures (M, 3) between two adjacent modes, valid for the non-serial
        rules, and their kinds: from the region map's transit cells when it has some
        (:func:`planner.planning.region_walks.map_transits`), else sampled at random on the
        singular surfaces."""
        key = (before, after)
        if key in self._pools:
            return self._pools[key]
        if self.rmap is not None:
            q = cached_map_transits(self.rmap, self.asm, before, after)
            if len(q):  # theta1 is set along the line and checked in :meth:`crossings`
                q[:, 0] = np.clip(0.0, self.design.joint_min[0], self.design.joint_max[0])
                flipped = FLIP_NAMES[flipped_sign(before, after)]
                kinds = [transit_kind(self.design, x, self.asm, flipped) for x in q[:1]] * len(q)
                self._pools[key] = (q, kinds)
                self.map_pools.add(key)
                return self._pools[key]
        j = flipped_sign(before, after)
        qs, kinds, drawn = [], [], 0
        for kind in kinds_flipping(FLIP_NAMES[j]):
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
            kinds_txt = " or ".join(kinds_flipping(FLIP_NAMES[j]))
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
        j = flipped_sign(before, after)
        if (before, after) in self.map_pools:
            q = theta1_along(q, q_from, q_goal, self.design)
            if regions is not None and self.rmap is not None:
                q = q[near_regions(self.rmap, self.asm, regions, q)]
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
            if time.monotonic() > self.deadline:
                break
            c = crossing_through(
                self.design,
                q[k],
                assembly_mode=self.asm,
                flipped=FLIP_NAMES[j],
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
        remaining = self.deadline - time.monotonic()
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
        and the crossings used, or None. With ``regions`` (a walk of
        :func:`planner.planning.region_walks.region_walks`, one region id per mode of
        ``seq``) each crossing joins its step's two regions and the last segment aims at the
        goal candidates of the last region."""
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
            if time.monotonic() > self.deadline:
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
                if time.monotonic() > self.deadline:
                    return None
            return None

        return step(0, q_start)


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
            qt = c.q_transit
            transits.append(
                Transit(t_index, (float(qt[0]), float(qt[1]), float(qt[2])), c.kind, c.flipped)
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
        diag = replace(diag, planning_time_s=time.monotonic() - t0, searches=search.searches)
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

    def modes_of(walk: tuple[int, ...]) -> tuple[str, ...]:
        assert rmap is not None
        return tuple(rmap.regions[r].working_mode for r in walk)

    search.share = ROUND_SHARES[0]
    for walk in walks_by_region:
        if time.monotonic() > deadline:
            break
        solved = attempt(modes_of(walk), walk)
        if solved is not None:
            return solved
    # walks that come back to a mode (a detour to another region of the start's mode, say):
    # no mode sequence expresses them, so they are tried again at every longer share
    returning = [w for w in walks_by_region if len(set(modes_of(w))) < len(w)]
    seqs = mode_sequences(start_mode, list(targets))
    if rmap is not None:  # walks the region map's transit graph cannot realise go (all
        # kept when none is left: longer walks than these may exist, the search says so)
        seqs = [
            s for s in seqs if walk_possible(rmap, start.assembly_mode, s, start.q, targets[s[-1]])
        ] or seqs
    ranked = []
    for seq in seqs:
        est = search.estimate(seq, start.q, targets[seq[-1]][0])
        if np.isfinite(est):
            ranked.append((len(seq), est, seq))
    ranked.sort(key=lambda x: (x[0], x[1]))
    if not ranked and not returning:
        reasons = sorted(set(search.pool_reasons.values()))
        return PlanResult(
            PlanStatus.UNREACHABLE,
            f"working mode {' or '.join(sorted(targets))} cannot be reached from {start_mode} "
            f"in assembly mode {start.assembly_mode}: no transit exists on any mode sequence ("
            + "; ".join(reasons)
            + ")",
            None,
            Diagnostics(planning_time_s=time.monotonic() - t0),
        )
    # guided by the map without regions (when it placed neither), then today's rounds on
    # sampled surfaces
    rounds = [(share, False) for share in ROUND_SHARES]
    if rmap is not None and not walks_by_region:
        rounds = [(ROUND_SHARES[0], True), *rounds]
    for share, guided in rounds:
        search.share = share
        if share > ROUND_SHARES[0] and returning:
            search.guided()
            for walk in returning:
                if time.monotonic() > deadline:
                    break
                solved = attempt(modes_of(walk), walk)
                if solved is not None:
                    return solved
        if not guided and search.rmap is not None:
            search.unguided()
        for _, _, seq in ranked:
            if time.monotonic() > deadline:
                break
            solved = attempt(seq, None)
            if solved is not None:
                return solved
    n_seqs = len({seq for _, _, seq in ranked} | tried)
    walks = ""
    if walks_by_region:
        shown = "; ".join(_walk_text(rmap, w) for w in walks_by_region[:3])
        more = f" and {len(walks_by_region) - 3} more" if len(walks_by_region) > 3 else ""
        walks = f"; region walks of the design's map tried: {shown}{more}"
    return PlanResult(
        PlanStatus.NO_PATH,
        f"no path found within {options.time_budget_s:g} s through transits "
        f"({len(tried)} of {n_seqs} mode sequences tried{walks})",
        None,
        Diagnostics(planning_time_s=time.monotonic() - t0, searches=search.searches),
    )


def _walk_text(rmap: region_maps.RegionMap | None, walk: tuple[int, ...]) -> str:
    """A region walk for a message: 'region 26 (-+-) -> region 30 (++-) -> ...'."""
    assert rmap is not None
    return " -> ".join(f"region {r} ({rmap.regions[r].working_mode})" for r in walk)


def estimated_transit_length(
    design: Design,
    start: JointPosture,
    start_mode: str,
    targets: dict[str, np.ndarray],
    *,
    obstacles: Sequence[Obstacle],
    margins: Margins,
    options: PlanOptions,
    deadline: float,
) -> float:
    """The least estimated length (rad) of a plan through transits from ``start`` (in
    ``start_mode``) to the first goal candidate of a mode of ``targets``, over the mode
    sequences: the straight joint-space length through the best sampled transit postures
    (inf when no sequence has them). No segment is searched: the dispatcher asks it to know
    whether a mode change may beat a solved single-mode path."""
    search = _ModeChangeSearch(design, start.assembly_mode, margins, obstacles, options, deadline)
    return min(
        search.estimate(seq, start.q, targets[seq[-1]][0])
        for seq in mode_sequences(start_mode, list(targets))
    )
