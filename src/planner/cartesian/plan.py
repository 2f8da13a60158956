"""Straight tool paths: P follows a Cartesian polyline inside one working and assembly mode.

Entry points: :func:`plan_cartesian` (the joint path, optionally timed) and
:func:`inspect_cartesian` (a pre-check that says where the polyline leaves the workspace of
the start's working mode or meets a serial or parallel singular surface, before any planning).

How a straight path is built (``docs/cartesian.md`` has the full argument):

1. The polyline starts at P of the start posture and runs through ``waypoints`` in order. It is
   probed every :data:`PROBE_STEP` m by the inverse kinematics of the start's working mode
   (one branch: the mode's sign triple fixes it), joint values unwrapped continuously from
   the start's literal values, and every probe is checked against every rule of a plan
   (:class:`planner.validity.ValidityChecker`). The first probe that breaks a rule, or where
   the branch does not exist (P out of reach) or changes assembly mode, ends the path; the
   last valid point before it is found by bisection along the polyline.
2. Up to there, the joint path is a polyline through inverse-kinematics postures. Between two
   consecutive ones the robot moves on the straight joint segment, whose P leaves the
   Cartesian line; :func:`chord_deviation_bound` bounds that deviation from above (a second
   derivative bound, proved in its docstring), and a piece is split into equal Cartesian
   parts (as many as the bound's quadratic decay asks, :data:`MAX_PARTS` at most) until the
   bound is at most ``chord_share * path_tolerance``.
3. Every joint piece is certified by :meth:`ValidityChecker.check_path` (all rules hold on the
   whole straight joint motion, not only at samples); a piece that cannot be certified is
   split too, and where splitting reaches :data:`MIN_PIECE` m the path stops at the piece's
   start, with the rule the certificate named.
4. Timing (optional) is :func:`planner.timing.time_path` with the blend allowance of every
   joint vertex chosen so that a blended posture keeps P within the rest of the tolerance
   (:func:`blend_allowance`).

One module a part, this one the plan (steps 1-4) and the family's public face (it exports the
names users import from ``planner.cartesian.plan``): :mod:`planner.cartesian.walk`
(the polyline, the inverse kinematics of the mode's branch along it, the bisection of step 1),
:mod:`planner.cartesian.chords` (the bounds of steps 2 and 4),
:mod:`planner.cartesian.inspection` (the pre-check) and
:mod:`planner.cartesian.result` (the answer).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Literal

import numpy as np

from planner.cartesian.chords import (
    blend_allowance,
    chord_deviation_bound,
    second_derivative_bound,
)
from planner.cartesian.inspection import inspect_cartesian
from planner.cartesian.result import (
    CartesianDiagnostics,
    CartesianResult,
    PathEvent,
    StopPoint,
)
from planner.cartesian.walk import (
    BISECT_TOL,
    PROBE_STEP,
    Polyline,
    Walker,
    as_points,
    branch_ik,
    distance_to_polyline_3d,
    narrow_bracket,
    unwrap_chain,
)
from planner.design import Design
from planner.exceptions import (
    DeadlineError,
    InputError,
    TimingDeadlineError,
    TimingError,
    check_deadline,
)
from planner.geometry import Obstacle
from planner.kinematics import WORKING_MODES, conditioning, forward_batch
from planner.planning.problem import JointPosture
from planner.planning.result import PlanPath, PlanStatus, Segment
from planner.planning.single_mode import posture_mode
from planner.validity import Margins, ValidityChecker

__all__ = [
    "CHORD_SHARE",
    "MIN_PIECE",
    "PROBE_STEP",
    "CartesianDiagnostics",
    "CartesianResult",
    "PathEvent",
    "StopPoint",
    "blend_allowance",
    "chord_deviation_bound",
    "distance_to_polyline_3d",
    "inspect_cartesian",
    "plan_cartesian",
    "second_derivative_bound",
]

#: Initial spacing of the joint waypoints, m (the chord bound refines where needed).
INITIAL_STEP = 0.05
#: Shortest Cartesian piece the refinement splits down to, m.
MIN_PIECE = 1e-7
#: A final piece ending on the bisected boundary and at most this long (m) has its end pulled
#: back (from :data:`BACKOFF_START` m, by factors of 4) rather than split, to certify it.
BACKOFF_PIECE = 1e-3
BACKOFF_START = 1e-7
#: Share of ``path_tolerance`` given to the chords between joint waypoints; the rest is the
#: timing's corner blends.
CHORD_SHARE = 0.5
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


def _fmt_value(value: float, bound: float) -> str:
    """``value`` with just enough digits to differ from ``bound`` (at least 4)."""
    for digits in range(4, 17):
        a, b = f"{value:.{digits}g}", f"{bound:.{digits}g}"
        if a != b:
            return a
    return repr(value)


def _fmt_point(p: np.ndarray) -> str:
    return "(" + ", ".join(f"{x:.4g}" for x in p) + ")"


def _describe(
    design: Design,
    checker: ValidityChecker,
    rule: str,
    q_bad: np.ndarray | None,
    p_bad: np.ndarray,
) -> tuple[float, str]:
    """(measured value, sentence) of the rule broken at posture q_bad (P = p_bad)."""
    m = checker.margins
    if rule == "workspace":
        a = np.array([0.0, -design.L0 / 2, 0.0])
        b = -a
        ra, rb = float(np.linalg.norm(p_bad - a)), float(np.linalg.norm(p_bad - b))
        hi, lo = design.L1 + design.L2, abs(design.L2 - design.L1)
        for name, r in (("AP", ra), ("BP", rb)):
            if r > hi:
                return r, (
                    f"workspace: |{name}| = {_fmt_value(r, hi)} m > L1 + L2 = {hi:.6g} m, "
                    "P is out of reach"
                )
            if r < lo:
                return r, (
                    f"workspace: |{name}| = {_fmt_value(r, lo)} m < |L2 - L1| = "
                    f"{lo:.6g} m, P is out of reach"
                )
        return float("nan"), (
            f"workspace: working mode {checker.working_mode} does not reach P there"
        )
    if q_bad is None or not np.all(np.isfinite(q_bad)):
        return float("nan"), f"{rule}: the path cannot continue"
    if rule == "assembly":
        return float("nan"), (
            f"assembly: the inverse kinematics of working mode {checker.working_mode} changes "
            f"assembly mode (from {checker.assembly_mode}): the line crosses a parallel "
            "singularity (C, D, P aligned)"
        )
    rep = checker.check_states(q_bad[None])
    if rule == "joint_limits":
        lo, hi = np.asarray(design.joint_min), np.asarray(design.joint_max)
        i = int(np.argmax(np.maximum(lo - q_bad, q_bad - hi)))
        bound = lo[i] if q_bad[i] < lo[i] else hi[i]
        rel = "<" if q_bad[i] < lo[i] else ">"
        return float(q_bad[i]), (
            f"joint_limits: theta{i + 1} = {_fmt_value(q_bad[i], bound)} rad {rel} "
            f"joint_{'min' if rel == '<' else 'max'}[{i}] = {bound:.6g} rad"
        )
    if rule == "kappa_max":
        k = float(rep.kappa_A[0])
        return k, f"kappa(A) = {_fmt_value(k, m.kappa_max)} > margins.kappa_max = {m.kappa_max:g}"
    if rule in ("serial_min", "working_mode"):
        fb = forward_batch(design, q_bad, checker.assembly_mode)
        c = conditioning(design, fb.q, fb.passive, fb.w)
        names = {
            "P_on_axis": "|w| / (L1 + L2) (P near the axis AB)",
            "leg_A": "|sin(theta4 - theta2)| (leg A near stretched or folded)",
            "leg_B": "|sin(theta5 - theta3)| (leg B near stretched or folded)",
        }
        kind = str(c.nearest_serial_kind[0])
        val = float(c.min_serial[0])
        return val, (
            f"serial_min: {names[kind]} = {_fmt_value(val, m.serial_min)} < "
            f"margins.serial_min = {m.serial_min:g}"
        )
    if rule == "clearance":
        c = float(rep.clearance[0])
        return c, (
            f"clearance: link clearance {_fmt_value(c, m.clearance)} m < "
            f"margins.clearance = {m.clearance:g} m"
        )
    return float("nan"), checker.explain(q_bad)


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


def plan_cartesian(
    design: Design,
    start: JointPosture,
    waypoints: np.ndarray,
    *,
    obstacles: Sequence[Obstacle] = (),
    margins: Margins | None = None,
    path_tolerance: float = 1e-3,
    timing: Literal["toppra", "ruckig", "none"] = "toppra",
    limits: object | None = None,
    cartesian_speed: float | None = None,
    sample_rate_hz: float = 100.0,
    check_resolution: float | None = None,
    chord_share: float = CHORD_SHARE,
    time_partial: bool = True,
    inspect: bool = True,
    inertia: object | None = None,
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81),
    deadline: float | None = None,
) -> CartesianResult:
    """Move P on the straight segments start-P -> waypoints[0] -> ... in the start's working
    and assembly mode, stopping at the last valid point where a rule would break.

    Parameters
    ----------
    design : Design
    start : JointPosture
        Its working mode (the sign triple of its posture) and assembly mode are kept.
    waypoints : array, shape (K, 3) or (3,), m
    obstacles : spheres, boxes, capsules (:mod:`planner.geometry`).
    margins : Margins, optional (defaults).
    path_tolerance : float, m, > 0
        Largest distance of P from the polyline, along the joint path (certified by
        :func:`chord_deviation_bound`) and along the timed trajectory (certified by the blend
        allowance of :func:`blend_allowance`, re-measured densely).
    timing : "toppra" | "ruckig" | "none"
    limits : planner.timing.JointLimits, optional (defaults).
    cartesian_speed : float, m/s, optional
        Bound on the speed of P (``max_cartesian_speed`` of :func:`planner.timing.time_path`):
        the tool moves at this constant speed wherever the joint limits allow.
    sample_rate_hz : float, Hz -- output rate of the trajectory.
    check_resolution : float, rad, optional -- the timing's dense re-check step (default
        the timing's default).
    chord_share : float in (0, 1) -- share of the tolerance for the chords.
    time_partial : bool -- also time a path that stops short (default True).
    inspect : bool -- run :func:`inspect_cartesian` and attach its events.
    inertia, gravity : the robot's :class:`planner.dynamics.Inertia` and gravity (m/s^2) for
        the timing's torques (:func:`planner.timing.time_path`).
    deadline : float, optional
        A :func:`time.monotonic` value: checked between chunks of probes, in every round of
        the refinement and by the timing; past it, :class:`~planner.exceptions.DeadlineError`
        (the work is abandoned, nothing is answered).

    Returns
    -------
    CartesianResult
        ``fraction`` = share of the polyline's length achieved; status ``solved`` exactly
        when it is 1.

    Raises
    ------
    InputError
        A malformed argument (the message names it).
    DeadlineError
        ``deadline`` passed before the path was built (and timed).
    """
    from planner.timing import DEFAULT_CHECK_RESOLUTION, JointLimits, time_path

    t0 = time.perf_counter()
    margins = margins if margins is not None else Margins()
    if not isinstance(start, JointPosture):
        raise InputError(f"start must be a JointPosture, got {type(start).__name__}")
    try:
        tol = float(path_tolerance)
    except (TypeError, ValueError) as exc:
        raise InputError(f"path_tolerance must be a number, got {path_tolerance!r}") from exc
    if not (math.isfinite(tol) and tol > 0):
        raise InputError(f"path_tolerance must be a positive finite number (m), got {tol!r}")
    if not 0.0 < chord_share < 1.0:
        raise InputError(f"chord_share must lie in (0, 1), got {chord_share!r}")
    if timing not in ("toppra", "ruckig", "none"):
        raise InputError(f"timing must be 'toppra', 'ruckig' or 'none', got {timing!r}")
    limits = limits if limits is not None else JointLimits.default()
    pts = as_points(waypoints)
    asm = start.assembly_mode
    q0 = np.array(start.q, dtype=float)
    fb = forward_batch(design, q0, asm)

    def early(status: PlanStatus, message: str, mode: str = "") -> CartesianResult:
        poly = np.vstack([fb.p[0][None] if fb.ok[0] else np.full((1, 3), np.nan), pts])
        return CartesianResult(
            status,
            message,
            0.0,
            None,
            poly,
            np.zeros(0),
            np.zeros((0, 3)),
            None,
            None,
            "",
            (),
            mode,
            asm,
            CartesianDiagnostics(time.perf_counter() - t0),
        )

    mode = posture_mode(design, start)
    if mode is None:
        checker0 = ValidityChecker(design, margins, obstacles, asm, "+++")
        why = checker0.explain(q0)
        if why in ("valid",) or why.startswith(("working_mode", "serial_min", "kappa")):
            why = "working_mode: the start lies on a serial singularity (its mode is undefined)"
        return early(PlanStatus.INVALID_START, f"invalid start: {why}")
    checker = ValidityChecker(design, margins, obstacles, asm, mode)
    if not checker.is_valid(q0[None])[0]:
        return early(PlanStatus.INVALID_START, f"invalid start: {checker.explain(q0)}", mode)
    if timing != "none":
        from planner.timing.torque import gravity_at_start

        held = gravity_at_start(design, q0, asm, limits, inertia, gravity)  # type: ignore[arg-type]
        if held is not None:
            return early(PlanStatus.INVALID_START, held, mode)
    p0 = fb.p[0]
    poly = Polyline(np.vstack([p0[None], pts]))
    slot = WORKING_MODES.index(mode)
    asm_sign = 1 if asm == "+" else -1
    walker = Walker(design, checker, poly, q0, slot, asm_sign)
    events = (
        inspect_cartesian(design, start, pts, margins=margins, deadline=deadline) if inspect else ()
    )

    # 1. probes: the first broken rule along the polyline, bisected
    end_s = poly.length
    stop_rule, q_stop_bad, p_stop_bad = "", None, None
    if poly.length > 0:
        n = max(2, math.ceil(poly.length / PROBE_STEP) + 1)
        step = poly.length / (n - 1)
        s_prev, q_prev = 0.0, q0  # the last valid probe
        for c0 in range(1, n, PROBE_CHUNK):
            check_deadline(deadline, "while probing the Cartesian path")
            c1 = min(c0 + PROBE_CHUNK, n)
            s_lin = np.arange(c0, c1) * step
            if c1 == n:
                s_lin[-1] = poly.length
            corners = poly.cum[(poly.cum > s_prev) & (poly.cum < s_lin[-1])]
            s_probe = np.unique(np.concatenate([s_lin, corners]))
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
            end_s = a
            stop_rule, q_stop_bad = bad_reason, bad_q
            p_stop_bad = poly.at(np.array([b]))[0]
            break

    # 2-3. joint waypoints up to end_s: chords within the tolerance, motions certified
    tol_chord = chord_share * tol
    n0 = max(1, math.ceil(end_s / INITIAL_STEP))
    s = np.unique(np.concatenate([np.linspace(0.0, end_s, n0 + 1), poly.cum[poly.cum < end_s]]))
    if end_s == 0.0:
        s = np.zeros(1)
    q, ok, w, _ = walker.posture_at(s, q0)
    q[0], ok[0], w[0] = q0, True, fb.w[0]
    if len(s) > 1:
        q[1:] = unwrap_chain(np.nan_to_num(q[1:]), q0)
    if not np.all(ok):  # a waypoint between probes missed the branch: cut there
        cut = int(np.argmax(~ok))
        s, q, w = s[:cut], q[:cut], w[:cut]
        end_s = float(s[-1])
        stop_rule = stop_rule or "workspace"
    certified = 0  # pieces [0, certified) are certified (chord and motion)
    rep = None
    backoff = 0.0
    bound = np.zeros(max(len(s) - 1, 0))
    cut_reason = ""
    for _ in range(MAX_REFINEMENTS):
        if certified >= len(s) - 1:
            break
        check_deadline(deadline, "while refining the Cartesian path")
        # chord bounds of the uncertified pieces
        tail = slice(certified, len(s) - 1)
        b_tail = chord_deviation_bound(
            design,
            q[tail],
            q[certified + 1 :],
            w[tail],
            w[certified + 1 :],
            poly.at(s[tail]),
            poly.at(s[certified + 1 :]),
            asm,
        )
        bound = np.concatenate([bound[:certified], b_tail])
        too_far = b_tail > tol_chord
        short = np.diff(s[certified:]) <= MIN_PIECE
        split = too_far & ~short
        if np.any(too_far & short):
            first_stuck = certified + int(np.argmax(too_far & short))
            if not np.any(split[: first_stuck - certified]):
                # cannot follow the line within the tolerance here: stop before the piece
                s, q, w = s[: first_stuck + 1], q[: first_stuck + 1], w[: first_stuck + 1]
                bound = bound[:first_stuck]
                end_s, cut_reason = float(s[-1]), "path_tolerance"
                q_stop_bad = None
                p_stop_bad = poly.at(np.array([end_s]))[0]
                continue
        if np.any(split):
            # each piece over the tolerance is cut into n equal parts at once, n from the
            # bound's quadratic decay with the piece's length (f and the second-derivative
            # term both scale with its square): one round where halving would take several;
            # a part still over the tolerance is split again in the next round
            pieces = certified + np.flatnonzero(split)
            n_parts = np.clip(np.ceil(np.sqrt(b_tail[split] / tol_chord)), 2, MAX_PARTS).astype(int)
            idx = np.repeat(pieces, n_parts - 1)
            frac = np.concatenate([np.arange(1, n) / n for n in n_parts])
            s_mid = s[idx] + frac * (s[idx + 1] - s[idx])
            qm, okm, wm, _ = walker.posture_at(s_mid, q[idx])
            valid_m = okm.copy()
            if np.any(okm):
                valid_m[okm] = checker.is_valid(qm[okm])
            if not np.all(valid_m):
                # a midpoint between two valid probes breaks a rule: cut before it
                first = int(np.argmax(~valid_m))
                k = int(idx[first])
                s, q, w = s[: k + 1], q[: k + 1], w[: k + 1]
                end_s = float(s[-1])
                cut_reason = "midpoint"
                q_stop_bad = qm[first] if okm[first] else None
                p_stop_bad = poly.at(np.array([s_mid[first]]))[0]
                stop_rule = (
                    str(checker.check_states(qm[first][None]).reason[0])
                    if okm[first]
                    else "workspace"
                )
                keep = idx < k
                idx, s_mid, qm, wm = idx[keep], s_mid[keep], qm[keep], wm[keep]
            s = np.insert(s, idx + 1, s_mid)
            q = np.insert(q, idx + 1, qm, axis=0)
            w = np.insert(w, idx + 1, wm)
            bound = bound[:certified]
            continue
        # every chord is within the tolerance: certify the motions
        rep = checker.check_path(q[certified:], certify=True)
        if rep.valid:
            certified = len(s) - 1
            break
        k = certified + rep.bad_motion
        certified = k
        piece = s[k + 1] - s[k]
        if k + 1 == len(s) - 1 and end_s < poly.length and piece <= BACKOFF_PIECE:
            # the final piece ends on a margin (the bisected boundary), where no motion can be
            # certified (margin 0): pull the end back, by growing steps. The steps are tried
            # in order as one at a time would (the first end whose motion certifies is kept;
            # an end that breaks a rule, or a step beyond half the piece, ends the pull-back),
            # but their postures come from one batched inverse kinematics.
            first_step = BACKOFF_START if backoff == 0.0 else 4.0 * backoff
            steps = first_step * 4.0 ** np.arange(16)
            pulled = np.cumsum(steps)
            fits = steps < 0.5 * (piece - np.concatenate([[0.0], pulled[:-1]]))
            n_try = int(np.argmin(fits)) if not np.all(fits) else len(fits)
            accepted = False
            if n_try > 0:
                s_try = float(s[-1]) - pulled[:n_try]
                qm, okm, wm, _ = walker.posture_at(s_try, q[k])
                valid_m = okm.copy()
                if np.any(okm):
                    valid_m[okm] = checker.is_valid(qm[okm])
                for j in range(n_try):
                    backoff = float(steps[j])
                    if not valid_m[j]:
                        break
                    s[-1], q[-1], w[-1] = s_try[j], qm[j], wm[j]
                    end_s = float(s_try[j])
                    rep = checker.check_path(q[certified:], certify=True)
                    if rep.valid:
                        accepted = True
                        break
                else:
                    backoff = float(4.0 * steps[n_try - 1])  # the next step is too large
                piece = s[k + 1] - s[k]
            else:
                backoff = first_step
            if accepted:
                bound = bound[:certified]
                continue
        if piece > MIN_PIECE:
            # split at the midpoint; the final piece of a path that stops on a rule's boundary
            # also at 3/4 and 7/8: the margin shrinks towards that end, so its second half
            # fails in turn (three halving rounds in one)
            stops_short = k + 1 == len(s) - 1 and end_s < poly.length
            frac = GRADED_SPLIT if stops_short else GRADED_SPLIT[:1]
            s_mid = s[k] + np.asarray(frac) * (s[k + 1] - s[k])
            qm, okm, wm, _ = walker.posture_at(s_mid, q[k])
            valid_m = okm.copy()
            if np.any(okm):
                valid_m[okm] = checker.is_valid(qm[okm])
            n_ok = int(np.argmin(valid_m)) if not np.all(valid_m) else len(frac)
            if n_ok > 0:
                # every later piece whose motion does not certify either is halved in the
                # same round: one piece per round would need as many rounds as there are
                # such pieces (thousands on a long robot, where every initial piece moves
                # a link farther than its clearance)
                more, s_more, q_more, w_more = _halve_uncertified(
                    walker, checker, s, q, k + 1, len(s) - 2 if stops_short else len(s) - 1
                )
                at = np.concatenate([np.full(n_ok, k + 1), more + 1])
                s = np.insert(s, at, np.concatenate([s_mid[:n_ok], s_more]))
                q = np.insert(q, at, np.concatenate([qm[:n_ok], q_more]), axis=0)
                w = np.insert(w, at, np.concatenate([wm[:n_ok], w_more]))
                bound = bound[:certified]
                continue
        # the motion out of waypoint k cannot be certified: stop at k
        t_bad = rep.t
        q_stop_bad = q[k] + t_bad * (q[k + 1] - q[k])
        p_stop_bad = forward_batch(design, q_stop_bad, asm).p[0]
        stop_rule = rep.reason
        s, q, w = s[: k + 1], q[: k + 1], w[: k + 1]
        bound = bound[:k]
        end_s = float(s[-1])
        cut_reason = "motion"
    else:
        # the rounds ran out before every piece was certified (a path needing more splits
        # than MAX_REFINEMENTS allows): the certified pieces are the answer, the rest not done
        # (the rule of the uncertified motion, not one found farther along the line)
        uncertified = rep.reason if rep is not None and not rep.valid else ""
        stop_rule = uncertified or stop_rule or "path_tolerance"
        s, q, w = s[: certified + 1], q[: certified + 1], w[: certified + 1]
        bound = bound[:certified]
        end_s, cut_reason = float(s[-1]), "rounds"
    bound = bound[: len(s) - 1]

    fraction = 1.0 if poly.length == 0.0 else min(end_s / poly.length, 1.0)
    if end_s >= poly.length:
        fraction = 1.0
    stop = None
    status = PlanStatus.SOLVED if fraction == 1.0 else PlanStatus.NO_PATH
    message = f"solved: P follows the polyline in working mode {mode} ({len(s)} waypoints)"
    if status is PlanStatus.NO_PATH:
        rule = stop_rule or "path_tolerance"
        if cut_reason == "path_tolerance":
            rule = "path_tolerance"
        p_end = poly.at(np.array([end_s]))[0]
        if cut_reason == "rounds":
            value, sentence = (
                float("nan"),
                (
                    f"{rule}: the motion on from here was not certified within "
                    f"{MAX_REFINEMENTS} refinement passes (the path up to here is)"
                ),
            )
        elif rule == "path_tolerance":
            value = float(bound.max()) if len(bound) else float("nan")
            sentence = (
                f"path_tolerance: no certified joint path keeps P within {tol:g} m of the line "
                "here (the chord bound grows without limit: a singularity is near)"
            )
        else:
            value, sentence = _describe(
                design,
                checker,
                rule,
                q_stop_bad,
                p_stop_bad if p_stop_bad is not None else p_end,
            )
        where = f" at P = {_fmt_point(p_end)}, {100 * fraction:.1f} % along the path"
        ahead = [e for e in events if e.fraction >= fraction - 1e-9 and e.entering]
        hint = f"; ahead: {ahead[0].detail} at {100 * ahead[0].fraction:.1f} %" if ahead else ""
        message = sentence + where + hint
        stop = StopPoint(rule, value, p_end, fraction, sentence + where)

    # measures of the joint path
    path = PlanPath(q.copy(), (Segment(mode, asm, 0, len(q) - 1),), ())
    p_way = poly.at(s)
    p_way[0] = p0
    report = checker.check_path(q, certify=False)
    planning_time = time.perf_counter() - t0

    trajectory, timing_error, timing_time = None, "", 0.0
    dev_measured = float("nan")
    blend_bound = 0.0
    if timing != "none" and len(q) >= 2 and (status is PlanStatus.SOLVED or time_partial):
        t1 = time.perf_counter()
        budget = np.full(len(q), tol)
        budget[1:-1] -= np.maximum(bound[:-1], bound[1:])
        dev, gain = blend_allowance(design, q, budget)
        blend_bound = float(np.max(gain[dev > 0] * dev[dev > 0], initial=0.0))

        def timed(method: str):
            return time_path(
                design,
                q,
                limits,
                method=method,
                assembly_mode=asm,
                sample_rate_hz=sample_rate_hz,
                max_cartesian_speed=cartesian_speed,
                max_deviation=dev,
                check_states=checker.is_valid,
                check_resolution=check_resolution or DEFAULT_CHECK_RESOLUTION,
                inertia=inertia,
                gravity=gravity,
                deadline=deadline,
            )

        try:
            trajectory = timed(timing)
        except TimingDeadlineError as exc:
            raise DeadlineError(str(exc)) from exc
        except TimingError as exc:
            timing_error = str(exc)
            if timing == "ruckig":
                # ruckig's moves between through-states may stray farther than the small
                # blend allowance that the tolerance leaves; toppra's blends cannot
                try:
                    trajectory = timed("toppra")
                    timing_error = f"ruckig failed ({exc}); timed with toppra instead"
                except TimingError as exc2:
                    timing_error = f"ruckig: {exc}; toppra: {exc2}"
        timing_time = time.perf_counter() - t1
        if trajectory is not None:
            tc = trajectory.curve.check_times(min(check_resolution or 1e-3, 1e-3))
            qt = trajectory.curve.evaluate(tc)[0]
            pt = forward_batch(design, qt, asm).p
            dev_measured = float(np.max(distance_to_polyline_3d(poly.vertices, pt)))
    if trajectory is None and len(q) >= 2:
        dense = np.concatenate(
            [q[i] + np.linspace(0, 1, 9)[:, None] * (q[i + 1] - q[i]) for i in range(len(q) - 1)]
        )
        dev_measured = float(
            np.max(distance_to_polyline_3d(poly.vertices, forward_batch(design, dense, asm).p))
        )
    elif len(q) < 2:
        dev_measured = 0.0
    diagnostics = CartesianDiagnostics(
        planning_time_s=planning_time,
        timing_time_s=timing_time,
        path_length=report.length,
        cartesian_length=end_s,
        max_kappa_A=report.max_kappa_A,
        min_serial_margin=report.min_serial_margin,
        min_clearance=report.min_clearance,
        chord_bound=float(bound.max()) if len(bound) else 0.0,
        max_path_deviation=dev_measured,
        blend_deviation_bound=blend_bound,
        waypoints=len(q),
    )
    if timing_error:
        message += f" (timing: {timing_error})"
    return CartesianResult(
        status,
        message,
        fraction,
        path,
        poly.vertices,
        s,
        p_way,
        stop,
        trajectory,
        timing_error,
        events,
        mode,
        asm,
        diagnostics,
    )
