"""Steps 1-3 of a straight tool path (:mod:`planner.cartesian.plan`): probe the polyline for
the first broken rule, then build the joint waypoints up to there with every chord within
its share of the tolerance and every joint motion certified.

:func:`probe_polyline` is step 1 (probes every :data:`~planner.cartesian.walk.PROBE_STEP` m in
chunks, the first broken rule bisected along the line); :class:`Refinement` is steps 2-3, one
method per way a round can change the path: split the chords over the tolerance
(:meth:`Refinement.split_chords`), pull the end of a final piece back from a rule's boundary
(:meth:`Refinement.pull_back`), split a motion that does not certify
(:meth:`Refinement.split_motion`), or stop before it (:meth:`Refinement.stop_at_motion`).
The deadline is checked between chunks of probes and in every round.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from planner.cartesian.chords import chord_deviation_bound
from planner.cartesian.inspection import BranchSamples
from planner.cartesian.walk import (
    BISECT_TOL,
    PROBE_STEP,
    Polyline,
    Walker,
    branch_ik,
    narrow_bracket,
    unwrap_chain,
)
from planner.design import Design
from planner.kinematics import forward_batch
from planner.motion import Budget
from planner.validity import ValidityChecker
from planner.validity.reports import PathReport

__all__ = [
    "BACKOFF_PIECE",
    "BACKOFF_START",
    "GRADED_SPLIT",
    "INITIAL_STEP",
    "MAX_PARTS",
    "MAX_REFINEMENTS",
    "MAX_ROUNDS",
    "MIN_PIECE",
    "PROBE_CHUNK",
    "Probed",
    "Refinement",
    "probe_polyline",
]

#: Initial spacing of the joint waypoints, m (the chord bound refines where needed).
INITIAL_STEP = 0.05
#: Shortest Cartesian piece the refinement splits down to, m.
MIN_PIECE = 1e-7
#: A final piece ending on the bisected boundary and at most this long (m) has its end pulled
#: back (from :data:`BACKOFF_START` m, by factors of 4) rather than split, to certify it.
BACKOFF_PIECE = 1e-3
BACKOFF_START = 1e-7
#: Most refinement rounds (each splits the pieces that fail).
MAX_ROUNDS = 60
#: Most passes of the refinement loop of the joint waypoints (splits of chords, splits of
#: motions, pull-backs): past them the certified part of the path is the answer.
MAX_REFINEMENTS = 4 * MAX_ROUNDS
#: Most parts one refinement round cuts a piece into.
MAX_PARTS = 16
#: Where a piece whose motion cannot be certified is split (shares of its length).
GRADED_SPLIT = (0.5, 0.75, 0.875)
#: Probes of step 1 computed at once: a long polyline is walked chunk by chunk, its
#: deadline checked between chunks, and the walk ends at the chunk of the first broken rule
#: (memory bounded by the chunk, not by the polyline's length).
PROBE_CHUNK = 8192


@dataclass(frozen=True, slots=True)
class Probed:
    """Step 1's outcome: the path ends at arc length ``end_s`` (m; the polyline's length when
    no rule breaks), with the rule that breaks just after it, the posture that breaks it
    (None when the branch does not exist there) and P there."""

    end_s: float
    stop_rule: str = ""
    q_bad: np.ndarray | None = None
    p_bad: np.ndarray | None = None


def probe_polyline(
    design: Design,
    checker: ValidityChecker,
    walker: Walker,
    poly: Polyline,
    q0: np.ndarray,
    slot: int,
    asm_sign: int,
    budget: Budget,
    known: BranchSamples | None = None,
) -> Probed:
    """Step 1: the first broken rule along the polyline, bisected to
    :data:`~planner.cartesian.walk.BISECT_TOL`. ``known``: the pre-check's inverse kinematics
    of its probes, taken for a chunk whose probes are the same points (a single segment: the
    pre-check probes every :data:`~planner.cartesian.walk.PROBE_STEP` m too) instead of
    solving them again."""
    if known is not None and not (
        known.slot == slot
        and known.asm_sign == asm_sign
        and np.array_equal(known.vertices, poly.vertices)
    ):
        known = None
    if poly.length <= 0:
        return Probed(poly.length)
    n = max(2, math.ceil(poly.length / PROBE_STEP) + 1)
    step = poly.length / (n - 1)
    s_prev, q_prev = 0.0, q0  # the last valid probe
    for c0 in range(1, n, PROBE_CHUNK):
        budget.check("while probing the Cartesian path")
        c1 = min(c0 + PROBE_CHUNK, n)
        s_lin = np.arange(c0, c1) * step
        if c1 == n:
            s_lin[-1] = poly.length
        corners = poly.cum[(poly.cum > s_prev) & (poly.cum < s_lin[-1])]
        s_probe = np.unique(np.concatenate([s_lin, corners]))
        if known is not None and np.array_equal(known.s[c0:c1], s_probe):
            qw, ok, flipped = known.q[c0:c1], known.ok[c0:c1], known.flipped[c0:c1]
        else:
            qw, ok, _, flipped = branch_ik(design, poly.at(s_probe), slot, asm_sign)
        first_missing = int(np.argmax(~ok)) if not np.all(ok) else len(s_probe)
        qp = np.full_like(qw, np.nan)
        if first_missing > 0:
            qp[:first_missing] = unwrap_chain(qw[:first_missing], q_prev)
        valid = np.zeros(len(s_probe), dtype=bool)
        if first_missing > 0:
            valid[:first_missing] = checker.is_valid(qp[:first_missing])
        if np.all(valid):
            s_prev, q_prev = float(s_probe[-1]), qp[-1]
            continue
        j = int(np.argmax(~valid))
        a = float(s_probe[j - 1]) if j > 0 else s_prev
        b = float(s_probe[j])
        good_q = qp[j - 1] if j > 0 else q_prev
        bad_reason = "workspace" if j >= first_missing else ""
        bad_q = None
        if j < first_missing:
            bad_q = qp[j]
            bad_reason = str(checker.check_states(qp[j][None]).reason[0])
        elif flipped[j]:
            bad_reason = "assembly"
        a, b, bad_q, bad_reason = narrow_bracket(
            a,
            b,
            lambda s_, good_q=good_q: walker.probe_valid(s_, good_q),
            BISECT_TOL,
            bad_q,
            bad_reason,
        )
        return Probed(a, bad_reason, bad_q, poly.at(np.array([b]))[0])
    return Probed(poly.length)


def _halve_uncertified(
    walker: Walker, checker: ValidityChecker, s: np.ndarray, q: np.ndarray, first: int, end: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pieces ``first <= i < end`` (from waypoint i to i + 1) whose motion does not
    certify and which are longer than :data:`MIN_PIECE`, with their midpoints that are valid
    postures: (piece indices, midpoints' s, q, working modes). A piece whose midpoint breaks
    a rule is left whole: a later round reaches it as the first uncertified piece, and stops
    there with that rule."""
    motion_ok = checker.motion_test()
    qc = np.ascontiguousarray(q, dtype=float)
    pieces = np.array(
        [
            i
            for i in range(first, end)
            if s[i + 1] - s[i] > MIN_PIECE and not motion_ok(qc[i].copy(), qc[i + 1].copy())
        ],
        dtype=int,
    )
    if len(pieces) == 0:
        return pieces, np.zeros(0), np.zeros((0, 3)), np.zeros(0)
    s_mid = 0.5 * (s[pieces] + s[pieces + 1])
    qm, okm, wm, _ = walker.posture_at(s_mid, q[pieces])
    valid = okm.copy()
    if np.any(okm):
        valid[okm] = checker.is_valid(qm[okm])
    return pieces[valid], s_mid[valid], qm[valid], wm[valid]


class Refinement:
    """Steps 2-3: the joint waypoints at arc lengths ``s`` (postures ``q``, working-mode
    measures ``w``) up to the probed end, refined round by round until every chord bound is
    within ``tol_chord`` and every motion certified (:meth:`run`). After it, ``s``, ``q``,
    ``w`` are the path, ``bound`` each piece's chord bound, ``end_s`` where it ends, and
    ``stop_rule``, ``q_bad``, ``p_bad``, ``cut_reason`` why it ends there ("path_tolerance",
    "midpoint", "motion", "rounds", or "" when nothing cut it after the probes)."""

    def __init__(
        self,
        design: Design,
        checker: ValidityChecker,
        walker: Walker,
        poly: Polyline,
        q0: np.ndarray,
        w0: float,
        probed: Probed,
        tol_chord: float,
    ) -> None:
        self.design, self.checker, self.walker, self.poly = design, checker, walker, poly
        self.tol_chord = tol_chord
        self.asm = checker.assembly_mode
        self.end_s = probed.end_s
        self.stop_rule, self.q_bad, self.p_bad = probed.stop_rule, probed.q_bad, probed.p_bad
        self.cut_reason = ""
        end_s = self.end_s
        n0 = max(1, math.ceil(end_s / INITIAL_STEP))
        s = np.unique(np.concatenate([np.linspace(0.0, end_s, n0 + 1), poly.cum[poly.cum < end_s]]))
        if end_s == 0.0:
            s = np.zeros(1)
        q, ok, w, _ = walker.posture_at(s, q0)
        q[0], ok[0], w[0] = q0, True, w0
        if len(s) > 1:
            q[1:] = unwrap_chain(np.nan_to_num(q[1:]), q0)
        if not np.all(ok):  # a waypoint between probes missed the branch: cut there
            cut = int(np.argmax(~ok))
            s, q, w = s[:cut], q[:cut], w[:cut]
            self.end_s = float(s[-1])
            self.stop_rule = self.stop_rule or "workspace"
        self.s, self.q, self.w = s, q, w
        self.certified = 0  # pieces [0, certified) are certified (chord and motion)
        self.report: PathReport | None = None
        self._report_q: np.ndarray | None = None  # the postures self.report certified
        self.backoff = 0.0
        self.bound = np.zeros(max(len(s) - 1, 0))
        # chord bounds of the pieces from ``certified`` on that the last round of
        # split_chords left whole (NaN: a new piece), for its next round; None: none known
        self._known: np.ndarray | None = None

    def run(self, budget: Budget) -> Refinement:
        """Refine until done or :data:`MAX_REFINEMENTS` passes (then the certified part is the
        path, :meth:`out_of_rounds`)."""
        for _ in range(MAX_REFINEMENTS):
            if self.certified >= len(self.s) - 1:
                break
            budget.check("while refining the Cartesian path")
            if self.split_chords():
                continue
            # every chord is within the tolerance: certify the motions
            rep = self._certify_tail()
            if rep.valid:
                self.certified = len(self.s) - 1
                break
            k = self.certified = self.certified + rep.bad_motion
            if self.pull_back(k) or self.split_motion(k):
                continue
            self.stop_at_motion(k)
        else:
            self.out_of_rounds()
        self.bound = self.bound[: len(self.s) - 1]
        return self

    def _certify_tail(self) -> PathReport:
        """Certify the motions from the first uncertified waypoint on (its report kept, with
        the postures it covers, for :meth:`path_report`)."""
        self._report_q = self.q[self.certified :].copy()
        self.report = self.checker.check_path(self._report_q, certify=True)
        return self.report

    def path_report(self) -> PathReport:
        """The measures of the final path, as ``check_path(q, certify=False)`` gives them
        (extremes over the waypoints and samples every ``DIAGNOSTIC_STEP`` rad), without
        sampling twice: the last certificate measured its own postures (the path's tail when
        it was valid), so only the waypoints before that tail are sampled again. The samples
        of each motion depend on its two ends only, so the extremes of the two parts, joined,
        are those of one pass (NaN-aware: NaN only where no sample of either closes the loop)."""
        q, rep, tail = self.q, self.report, self._report_q
        reuse = (
            rep is not None
            and rep.valid
            and tail is not None
            and 1 < len(tail) <= len(q)
            and np.array_equal(q[len(q) - len(tail) :], tail)
        )
        if not reuse:
            return self.checker.check_path(q, certify=False)
        assert rep is not None and tail is not None
        head_n = len(q) - len(tail) + 1
        if head_n == 1:
            return rep
        head = self.checker.check_path(q[:head_n], certify=False)
        return replace(
            rep,
            min_clearance=float(np.fmin(head.min_clearance, rep.min_clearance)),
            max_kappa_A=float(np.fmax(head.max_kappa_A, rep.max_kappa_A)),
            min_serial_margin=float(np.fmin(head.min_serial_margin, rep.min_serial_margin)),
            length=head.length + rep.length,
        )

    def _cut(self, last: int) -> None:
        """Keep the waypoints up to ``last``."""
        self.s, self.q, self.w = self.s[: last + 1], self.q[: last + 1], self.w[: last + 1]

    def split_chords(self) -> bool:
        """Step 2 for the uncertified pieces: their chord bounds; a piece over the tolerance
        is cut into parts (or, too short to cut, the path stops before it). True when the
        round changed the path."""
        s, q, w, certified, tol_chord = self.s, self.q, self.w, self.certified, self.tol_chord
        known, self._known = self._known, None
        if known is None or known.shape[0] != len(s) - 1 - certified:
            known = np.full(len(s) - 1 - certified, np.nan)
        new = certified + np.flatnonzero(np.isnan(known))  # pieces not bounded yet
        b_tail = known.copy()
        line = self.poly.at(np.concatenate([s[new], s[new + 1]]))  # both ends, one call
        b_tail[new - certified] = chord_deviation_bound(
            self.design,
            q[new],
            q[new + 1],
            w[new],
            w[new + 1],
            line[: len(new)],
            line[len(new) :],
            self.asm,
        )
        self.bound = np.concatenate([self.bound[:certified], b_tail])
        too_far = b_tail > tol_chord
        short = np.diff(s[certified:]) <= MIN_PIECE
        split = too_far & ~short
        if np.any(too_far & short):
            first_stuck = certified + int(np.argmax(too_far & short))
            if not np.any(split[: first_stuck - certified]):
                # cannot follow the line within the tolerance here: stop before the piece
                self._cut(first_stuck)
                self.bound = self.bound[:first_stuck]
                self.end_s, self.cut_reason = float(self.s[-1]), "path_tolerance"
                self.q_bad = None
                self.p_bad = self.poly.at(np.array([self.end_s]))[0]
                return True
        if not np.any(split):
            return False
        # each piece over the tolerance is cut into n equal parts at once, n from the bound's
        # quadratic decay with the piece's length (f and the second-derivative term both
        # scale with its square): one round where halving would take several; a part still
        # over the tolerance is split again in the next round
        pieces = certified + np.flatnonzero(split)
        n_parts = np.clip(np.ceil(np.sqrt(b_tail[split] / tol_chord)), 2, MAX_PARTS).astype(int)
        idx = np.repeat(pieces, n_parts - 1)
        frac = np.concatenate([np.arange(1, n) / n for n in n_parts])
        s_mid = s[idx] + frac * (s[idx + 1] - s[idx])
        qm, okm, wm, _ = self.walker.posture_at(s_mid, q[idx])
        valid_m = okm.copy()
        if np.any(okm):
            valid_m[okm] = self.checker.is_valid(qm[okm])
        if not np.all(valid_m):
            # a midpoint between two valid probes breaks a rule: cut before it
            first = int(np.argmax(~valid_m))
            k = int(idx[first])
            self._cut(k)
            self.end_s = float(self.s[-1])
            self.cut_reason = "midpoint"
            self.q_bad = qm[first] if okm[first] else None
            self.p_bad = self.poly.at(np.array([s_mid[first]]))[0]
            self.stop_rule = (
                str(self.checker.check_states(qm[first][None]).reason[0])
                if okm[first]
                else "workspace"
            )
            keep = idx < k
            idx, s_mid, qm, wm = idx[keep], s_mid[keep], qm[keep], wm[keep]
        if np.all(valid_m):
            # the bounds of the pieces left whole carry over to the next round (a piece's
            # bound depends on its two ends only); the parts of the split ones are new
            parts = np.ones(len(b_tail), dtype=int)
            parts[pieces - certified] = n_parts
            carried = np.repeat(b_tail, parts)
            carried[np.repeat(split, parts)] = np.nan
            self._known = carried
        self.s = np.insert(self.s, idx + 1, s_mid)
        self.q = np.insert(self.q, idx + 1, qm, axis=0)
        self.w = np.insert(self.w, idx + 1, wm)
        self.bound = self.bound[:certified]
        return True

    def pull_back(self, k: int) -> bool:
        """The final piece ends on a margin (the bisected boundary), where no motion can be
        certified (margin 0): pull the end back, by growing steps. The steps are tried in order
        as one at a time would (the first end whose motion certifies is kept; an end that
        breaks a rule, or a step beyond half the piece, ends the pull-back), but their
        postures come from one batched inverse kinematics. True when an end was accepted."""
        s = self.s
        piece = s[k + 1] - s[k]
        if not (k + 1 == len(s) - 1 and self.end_s < self.poly.length and piece <= BACKOFF_PIECE):
            return False
        first_step = BACKOFF_START if self.backoff == 0.0 else 4.0 * self.backoff
        steps = first_step * 4.0 ** np.arange(16)
        pulled = np.cumsum(steps)
        fits = steps < 0.5 * (piece - np.concatenate([[0.0], pulled[:-1]]))
        n_try = int(np.argmin(fits)) if not np.all(fits) else len(fits)
        if n_try == 0:
            self.backoff = first_step
            return False
        s_try = float(s[-1]) - pulled[:n_try]
        qm, okm, wm, _ = self.walker.posture_at(s_try, self.q[k])
        valid_m = okm.copy()
        if np.any(okm):
            valid_m[okm] = self.checker.is_valid(qm[okm])
        for j in range(n_try):
            self.backoff = float(steps[j])
            if not valid_m[j]:
                return False
            self.s[-1], self.q[-1], self.w[-1] = s_try[j], qm[j], wm[j]
            self.end_s = float(s_try[j])
            if self._certify_tail().valid:
                self.bound = self.bound[: self.certified]
                return True
        self.backoff = float(4.0 * steps[n_try - 1])  # the next step is too large
        return False

    def split_motion(self, k: int) -> bool:
        """Split the piece out of waypoint ``k`` whose motion does not certify at its midpoint;
        the final piece of a path that stops on a rule's boundary also at 3/4 and 7/8 (the
        margin shrinks towards that end, so its second half fails in turn: three halving
        rounds in one). Every later piece whose motion does not certify either is halved in
        the same round (one piece per round would need as many rounds as there are such
        pieces: thousands on a long robot, where every initial piece moves a link farther
        than its clearance). True when the path was split."""
        s, q = self.s, self.q
        if not s[k + 1] - s[k] > MIN_PIECE:
            return False
        stops_short = k + 1 == len(s) - 1 and self.end_s < self.poly.length
        frac = GRADED_SPLIT if stops_short else GRADED_SPLIT[:1]
        s_mid = s[k] + np.asarray(frac) * (s[k + 1] - s[k])
        qm, okm, wm, _ = self.walker.posture_at(s_mid, q[k])
        valid_m = okm.copy()
        if np.any(okm):
            valid_m[okm] = self.checker.is_valid(qm[okm])
        n_ok = int(np.argmin(valid_m)) if not np.all(valid_m) else len(frac)
        if n_ok == 0:
            return False
        more, s_more, q_more, w_more = _halve_uncertified(
            self.walker, self.checker, s, q, k + 1, len(s) - 2 if stops_short else len(s) - 1
        )
        at = np.concatenate([np.full(n_ok, k + 1), more + 1])
        self.s = np.insert(s, at, np.concatenate([s_mid[:n_ok], s_more]))
        self.q = np.insert(q, at, np.concatenate([qm[:n_ok], q_more]), axis=0)
        self.w = np.insert(self.w, at, np.concatenate([wm[:n_ok], w_more]))
        self.bound = self.bound[: self.certified]
        return True

    def stop_at_motion(self, k: int) -> None:
        """The motion out of waypoint ``k`` cannot be certified: the path stops at ``k``, with
        the rule its certificate named."""
        rep = self.report
        assert rep is not None
        q = self.q
        self.q_bad = q[k] + rep.t * (q[k + 1] - q[k])
        self.p_bad = forward_batch(self.design, self.q_bad, self.asm).p[0]
        self.stop_rule = rep.reason
        self._cut(k)
        self.bound = self.bound[:k]
        self.end_s = float(self.s[-1])
        self.cut_reason = "motion"

    def out_of_rounds(self) -> None:
        """The rounds ran out before every piece was certified (a path needing more splits
        than :data:`MAX_REFINEMENTS` allows): the certified pieces are the answer, the rest not
        done (the rule of the uncertified motion, not one found farther along the line)."""
        rep = self.report
        uncertified = rep.reason if rep is not None and not rep.valid else ""
        self.stop_rule = uncertified or self.stop_rule or "path_tolerance"
        self._cut(self.certified)
        self.bound = self.bound[: self.certified]
        self.end_s, self.cut_reason = float(self.s[-1]), "rounds"
