"""An independent re-check of a ``POST /v1/plan`` answer against its request (wire JSON).

Why it exists: the planner certifies its own paths, and a test that asked the planner's own
validity code whether a plan is valid would only prove that the code agrees with itself. This
checker re-derives everything from the formulas of ``docs/conventions.md``, written here
again with numpy alone: it imports nothing from ``planner`` (the library's defaults are
copied in :data:`DEFAULT_DESIGN`, :data:`DEFAULT_MARGINS` and :data:`DEFAULT_LIMITS`, and
``tests/test_plan_checker.py`` asserts that the copies match the library).

What a solved answer must satisfy (:func:`check_plan` lists every rule that fails):

* the path starts at the request's start; it ends at the joint goal, or with P on the
  Cartesian goal (within the goal's ``tolerance``, default 0) in the requested working mode;
* every waypoint and every trajectory sample lies within the literal joint limits;
* the segments and transits follow the wire's index rules: the segments cover the waypoints
  in order, consecutive segments share the transit waypoint, they differ in exactly the
  transit's ``flipped`` sign, and every segment keeps the start's assembly mode;
* every posture along every straight joint-space piece between waypoints (sampled at most
  :data:`STEP` rad apart per joint) and along the trajectory assembles in that assembly mode,
  has kappa(A) <= ``kappa_max`` and link clearance >= ``clearance``, and keeps its segment's
  working mode with every serial measure >= ``serial_min``; on the two pieces that touch a
  transit the flipped measure is exempt from ``serial_min`` but keeps its sign up to the
  transit posture, where it vanishes as the transit's ``kind`` says (P on the axis, leg
  stretched: cos(theta4 - theta2) > 0, leg folded: cos < 0);
* the trajectory starts at the start and ends at the path's end, at rest; its time axis runs
  from 0 to ``duration`` and increases; its velocities, accelerations (and jerks when given)
  respect the limits at the samples, and the samples are consistent with each other by
  finite differences (the change of q between samples is the integral of qd, the change of
  qd is bounded by the acceleration limit).

Clearance is exact up to round-off: along a link segment, the signed distance to a convex
obstacle (sphere, capsule, box) is a convex function of the segment parameter, so a
golden-section search finds its minimum. A point cloud is measured by a second route, a k-d
tree over its points queried at samples of each link (:func:`_cloud_distance`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Any

import numpy as np

__all__ = [
    "DEFAULT_DESIGN",
    "DEFAULT_LIMITS",
    "DEFAULT_MARGINS",
    "STEP",
    "PlanCheck",
    "check_plan",
    "postures",
]

#: The robot of a request without ``design`` (``Design.default()`` of the library).
DEFAULT_DESIGN: dict[str, Any] = {
    "L0": 0.5,
    "L1": 0.2,
    "L2": 0.6,
    "link_radius": 0.02,
    "joint_min": [-math.pi] * 3,
    "joint_max": [math.pi] * 3,
}
#: Margins of a request without ``margins`` (``planner.validity.Margins()`` of the library).
DEFAULT_MARGINS: dict[str, float] = {"kappa_max": 10.0, "serial_min": 0.05, "clearance": 0.01}
#: Joint rate limits of a request without ``limits`` (``JointLimits.default()``; its jerk, asked by
#: none, is what a trajectory that reports a jerk keeps: ruckig's ``RUCKIG_DEFAULT_JERK``).
DEFAULT_LIMITS: dict[str, list[float]] = {
    "velocity": [2.0] * 3,
    "acceleration": [8.0] * 3,
    "jerk": [200.0] * 3,
}
#: Corner allowance of the timing when ``timing.max_deviation`` is absent, rad.
DEFAULT_MAX_DEVIATION = 0.05

#: Largest joint step (rad, per joint) between two checked postures of a straight piece.
STEP = 0.002
#: Round-off allowed on the joint limits (rad), the start and a joint goal.
JOINT_TOL = 1e-9
#: Round-off allowed on a margin (relative for kappa, absolute for serial and clearance).
MARGIN_TOL = 1e-9
#: How close to 0 the flipped measure must come at a transit posture.
TRANSIT_TOL = 1e-6
#: A posture whose serial measures are all farther than this from 0 has a working mode.
SIGN_EPS = 1e-6
#: A Cartesian goal is reached when P is within this (plus the goal's tolerance), m.
GOAL_TOL = 1e-6
#: Relative round-off allowed on a rate limit at a sample.
LIMIT_RTOL = 1e-6

_FLIPPED_INDEX = {"axis": 0, "A": 1, "B": 2}
_KIND_FLIPS = {
    "P_on_axis": "axis",
    "leg_A_stretched": "A",
    "leg_A_folded": "A",
    "leg_B_stretched": "B",
    "leg_B_folded": "B",
}
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
_GOLDEN_ITERATIONS = 70  # 0.618^70 ~ 2e-15 of the link length


# ------------------------------------------------------------------------- kinematics
@dataclass
class Postures:
    """Postures of N joint vectors in one assembly mode, from the formulas of the frame.

    ``points`` maps "A", "B", "C", "D", "P" to (N, 3) arrays in the base frame; ``measures``
    is (N, 3): w / (L1 + L2), sin(theta4 - theta2), sin(theta5 - theta3) (their signs are the
    working mode); ``kappa`` is kappa(A); ``assembly`` is sin(theta5 - theta4); ``ok`` says
    the loop closes with C != D."""

    q: np.ndarray
    points: dict[str, np.ndarray]
    theta4: np.ndarray
    theta5: np.ndarray
    measures: np.ndarray
    kappa: np.ndarray
    assembly: np.ndarray
    ok: np.ndarray


def postures(design: dict[str, Any], q: np.ndarray, branch: int) -> Postures:
    """Direct kinematics of q (N, 3) in assembly mode ``branch`` (+1 or -1).

    In the linkage plane (u along +y, w along e(theta1) = (cos theta1, 0, -sin theta1)):
    A = (-L0/2, 0), B = (L0/2, 0), C = A + L1 (cos theta2, sin theta2), D likewise from B
    with theta3; P is the apex of the isosceles triangle C-P-D (|CP| = |DP| = L2) on the side
    where sin(theta5 - theta4) has the sign of ``branch``. A plane point (u, w) is
    (w cos theta1, u, -w sin theta1) in 3-D."""
    L0, L1, L2 = float(design["L0"]), float(design["L1"]), float(design["L2"])
    q = np.atleast_2d(np.asarray(q, dtype=float))
    t1, t2, t3 = q[:, 0], q[:, 1], q[:, 2]
    cu, cw = -L0 / 2 + L1 * np.cos(t2), L1 * np.sin(t2)
    du, dw = L0 / 2 + L1 * np.cos(t3), L1 * np.sin(t3)
    vu, vw = du - cu, dw - cw
    d = np.hypot(vu, vw)
    ok = (d > 1e-12) & (d <= 2 * L2 * (1 + 1e-12))
    safe = np.where(d > 1e-12, d, 1.0)
    h = np.sqrt(np.clip(L2 * L2 - d * d / 4, 0.0, None))
    # unit normal of CD turned +90 degrees: cross(P - C, P - D) = branch * h * |CD|
    pu = (cu + du) / 2 + branch * h * (-vw / safe)
    pw = (cw + dw) / 2 + branch * h * (vu / safe)
    t4 = np.arctan2(pw - cw, pu - cu)
    t5 = np.arctan2(pw - dw, pu - du)

    def to3(u: np.ndarray, w: np.ndarray) -> np.ndarray:
        return np.stack([w * np.cos(t1), u, -w * np.sin(t1)], axis=1)

    n = len(q)
    points = {
        "A": np.tile([0.0, -L0 / 2, 0.0], (n, 1)),
        "B": np.tile([0.0, L0 / 2, 0.0], (n, 1)),
        "C": to3(cu, cw),
        "D": to3(du, dw),
        "P": to3(pu, pw),
    }
    measures = np.stack([pw / (L1 + L2), np.sin(t4 - t2), np.sin(t5 - t3)], axis=1)
    c = np.abs(np.cos(t4 - t5))
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = np.where(c < 1.0, np.sqrt((1 + c) / (1 - c)), np.inf)  # corrected eq. (8)
    kappa = np.where(ok, kappa, np.inf)
    return Postures(q, points, t4, t5, measures, kappa, np.sin(t5 - t4), ok)


def _label(signs: np.ndarray) -> str:
    return "".join("+" if s > 0 else "-" for s in signs)


def _mode_signs(label: str) -> np.ndarray:
    return np.array([1.0 if ch == "+" else -1.0 for ch in label])


# ------------------------------------------------------------------------- clearance
def _rotation(quaternion: list[float]) -> np.ndarray:
    """Rotation matrix of a quaternion [w, x, y, z] (normalised first); its columns are the
    box's own axes in the base frame."""
    w, x, y, z = np.asarray(quaternion, dtype=float) / np.linalg.norm(quaternion)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _signed_distance(x: np.ndarray, ob: dict[str, Any]) -> np.ndarray:
    """Signed distance of points x (N, 3) to one obstacle (negative inside)."""
    kind = ob.get("type")
    if kind == "sphere":
        return np.linalg.norm(x - np.asarray(ob["center"], float), axis=1) - float(ob["radius"])
    if kind == "capsule":
        a, b = np.asarray(ob["a"], float), np.asarray(ob["b"], float)
        ab = b - a
        s = np.clip((x - a) @ ab / max(float(ab @ ab), 1e-300), 0.0, 1.0)
        return np.linalg.norm(a + s[:, None] * ab - x, axis=1) - float(ob["radius"])
    if kind == "box":
        rot = _rotation(ob.get("quaternion", [1.0, 0.0, 0.0, 0.0]))
        local = (x - np.asarray(ob["center"], float)) @ rot
        excess = np.abs(local) - np.asarray(ob["size"], float) / 2
        outside = np.linalg.norm(np.maximum(excess, 0.0), axis=1)
        return outside + np.minimum(excess.max(axis=1), 0.0)
    raise ValueError(f"unknown obstacle type {kind!r}")


def _segment_distance(a: np.ndarray, b: np.ndarray, ob: dict[str, Any]) -> np.ndarray:
    """Least signed distance from the segments a-b (N, 3 each) to a convex obstacle: the
    signed distance along a segment is convex in its parameter, so golden-section search
    converges to the minimum; both ends are evaluated too."""
    ab = b - a
    lo, hi = np.zeros(len(a)), np.ones(len(a))
    x1 = hi - _GOLDEN * (hi - lo)
    x2 = lo + _GOLDEN * (hi - lo)
    f1 = _signed_distance(a + x1[:, None] * ab, ob)
    f2 = _signed_distance(a + x2[:, None] * ab, ob)
    for _ in range(_GOLDEN_ITERATIONS):
        left = f1 <= f2  # the minimum lies in [lo, x2]
        hi = np.where(left, x2, hi)
        lo = np.where(left, lo, x1)
        nx1 = hi - _GOLDEN * (hi - lo)
        nx2 = lo + _GOLDEN * (hi - lo)
        new = np.where(left, nx1, nx2)
        fn = _signed_distance(a + new[:, None] * ab, ob)
        f2, f1 = np.where(left, f1, fn), np.where(left, fn, f2)
        x2, x1 = np.where(left, x1, nx2), np.where(left, nx1, x2)
    ends = np.minimum(_signed_distance(a, ob), _signed_distance(b, ob))
    return np.minimum(np.minimum(f1, f2), ends)


#: Spacing (m) of the samples of a link at which a point cloud's distance is measured.
CLOUD_SPACING = 1e-3


def _cloud_distance(a: np.ndarray, b: np.ndarray, ob: dict[str, Any]) -> np.ndarray:
    """Least distance from the segments a-b (N, 3 each) to a point cloud (every point a ball
    of one radius), by a second route: scipy's k-d tree over the cloud queried at samples of
    each segment at most :data:`CLOUD_SPACING` apart. Sampling can only miss the closest
    point of a segment, so the value is at most CLOUD_SPACING / 2 above the true distance,
    never below it: a clearance it finds too small is too small."""
    from scipy.spatial import cKDTree

    tree = cKDTree(np.asarray(ob["points"], dtype=float))
    length = float(np.max(np.linalg.norm(b - a, axis=1), initial=0.0))
    s = np.linspace(0.0, 1.0, max(2, math.ceil(length / CLOUD_SPACING) + 1))
    x = a[:, None, :] + s[None, :, None] * (b - a)[:, None, :]
    d, _ = tree.query(x.reshape(-1, 3))
    return d.reshape(len(a), -1).min(axis=1) - float(ob["radius"])


def clearance(post: Postures, obstacles: list[dict[str, Any]], link_radius: float) -> np.ndarray:
    """Least distance from the link capsules AC, BD, CP, DP to every obstacle, per posture
    (+inf without obstacles)."""
    out = np.full(len(post.q), np.inf)
    for i, j in (("A", "C"), ("B", "D"), ("C", "P"), ("D", "P")):
        for ob in obstacles:
            if ob.get("type") == "points":
                d = _cloud_distance(post.points[i], post.points[j], ob) - link_radius
            else:
                d = _segment_distance(post.points[i], post.points[j], ob) - link_radius
            out = np.minimum(out, d)
    return out


# ------------------------------------------------------------------------- helpers
def _dense(a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:
    """The straight joint-space motion a -> b, both ends included, at most ``step`` rad
    apart per joint."""
    n = max(1, math.ceil(float(np.max(np.abs(b - a))) / step))
    return a + (b - a) * (np.arange(n + 1) / n)[:, None]


def _dense_polyline(q: np.ndarray, step: float) -> np.ndarray:
    parts = [q[:1]] + [_dense(a, b, step)[1:] for a, b in pairwise(q)]
    return np.vstack(parts)


def _distance_to_pieces(x: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For points x (M, 3): index of the nearest straight piece w[i] -> w[i + 1] and the
    distance to it (joint space, Euclidean)."""
    best = np.full(len(x), np.inf)
    idx = np.zeros(len(x), dtype=int)
    for i in range(len(w) - 1):
        a, ab = w[i], w[i + 1] - w[i]
        den = float(ab @ ab)
        s = np.clip((x - a) @ ab / den, 0.0, 1.0) if den > 0 else np.zeros(len(x))
        d = np.linalg.norm(a + s[:, None] * ab - x, axis=1)
        closer = d < best
        best[closer], idx[closer] = d[closer], i
    return idx, best


def _merged(defaults: dict[str, Any], given: dict[str, Any] | None) -> dict[str, Any]:
    """``defaults`` overridden by the non-null fields of ``given``."""
    out = dict(defaults)
    out.update({k: v for k, v in (given or {}).items() if v is not None})
    return out


@dataclass
class PlanCheck:
    """Outcome of :func:`check_plan`: ``failures`` (one sentence per broken rule, empty when
    the plan holds), the worst values measured, and whether anything was checked at all
    (only a solved answer has a path)."""

    checked: bool = False
    failures: list[str] = field(default_factory=list)
    worst: dict[str, float] = field(default_factory=dict)
    postures_checked: int = 0

    @property
    def ok(self) -> bool:
        """True when the answer was checked and no rule failed."""
        return self.checked and not self.failures

    def fail(self, message: str) -> None:
        """Record one broken rule."""
        self.failures.append(message)

    def __str__(self) -> str:
        head = "OK" if self.ok else ("FAILED" if self.checked else "NOT CHECKED")
        worst = ", ".join(f"{k}={v:.6g}" for k, v in self.worst.items())
        lines = [f"{head}: {self.postures_checked} postures; {worst}"]
        return "\n".join(lines + [f"  - {f}" for f in self.failures])


# ------------------------------------------------------------------------- the check
def check_plan(
    request: dict[str, Any],
    response: dict[str, Any],
    *,
    step: float = STEP,
    start_state: dict[str, Any] | None = None,
    lead_in_s: float = 0.0,
):
    """Re-check a /v1/plan ``response`` against its ``request`` (both wire JSON dicts).

    Absent request fields take the library's defaults (:data:`DEFAULT_DESIGN`,
    :data:`DEFAULT_MARGINS`, :data:`DEFAULT_LIMITS`). Returns a :class:`PlanCheck`; an
    answer whose status is not "solved" is returned unchecked (``checked`` False) unless it
    carries a path anyway, which is a failure.

    A moving start (``start_state``: ``{"q", "qd", "qdd"}``, the state the trajectory must
    begin in, instead of rest; its time axis may start at any ``t[0]``, a replacement's
    ``at``): the first sample must be that state to 1e-9, and the trajectory's first
    ``lead_in_s`` seconds (its lead-in onto the path) are held to every validity rule and
    limit but not to the path's corner allowance."""
    report = PlanCheck()
    if response.get("status") != "solved":
        if response.get("path") or response.get("trajectory"):
            report.checked = True
            report.fail(f"status {response.get('status')!r} carries a path or trajectory")
        return report
    report.checked = True
    design = _merged(DEFAULT_DESIGN, request.get("design"))
    margins = _merged(DEFAULT_MARGINS, request.get("margins"))
    limits = _merged(DEFAULT_LIMITS, request.get("limits"))
    obstacles = list(request.get("obstacles") or [])
    start, goal = request["start"], request["goal"]
    asm = start.get("assembly_mode", "+")
    branch = 1 if asm == "+" else -1
    lo, hi = np.asarray(design["joint_min"], float), np.asarray(design["joint_max"], float)

    path = response.get("path") or {}
    w = np.asarray(path.get("waypoints") or [], dtype=float).reshape(-1, 3)
    if len(w) < 2:
        report.fail(f"the path has {len(w)} waypoint(s); a path needs at least 2")
        return report
    segments = list(path.get("segments") or [])
    transits = list(path.get("transits") or [])

    # ends of the path
    if np.max(np.abs(w[0] - np.asarray(start["q"], float))) > JOINT_TOL:
        report.fail(f"waypoint 0 {w[0].tolist()} is not the start {start['q']}")
    end = postures(design, w[-1:], branch)
    if "q" in goal:
        tol = JOINT_TOL + float(goal.get("tolerance") or 0.0)
        if np.max(np.abs(w[-1] - np.asarray(goal["q"], float))) > tol:
            report.fail(f"the last waypoint {w[-1].tolist()} is not the goal {goal['q']}")
        if goal.get("assembly_mode", asm) != asm:
            report.fail(f"the goal's assembly mode {goal['assembly_mode']} is not the start's")
    else:
        miss = float(np.linalg.norm(end.points["P"][0] - np.asarray(goal["p"], float)))
        if miss > GOAL_TOL + float(goal.get("tolerance") or 0.0):
            report.fail(f"P ends {miss:.3e} m from the Cartesian goal")
        want = goal.get("working_mode", "any")
        got = _label(end.measures[0])
        if want != "any" and got != want:
            report.fail(f"the goal posture is in working mode {got}, {want} was asked")

    # joint limits, literal
    for k in np.flatnonzero(np.any((w < lo - JOINT_TOL) | (w > hi + JOINT_TOL), axis=1)):
        report.fail(f"waypoint {k} {w[k].tolist()} leaves the joint limits")

    # wire index rules of segments and transits
    before = len(report.failures)
    if not segments:
        report.fail("a solved path has no segments")
        return report
    if segments[0]["start_index"] != 0 or segments[-1]["end_index"] != len(w) - 1:
        report.fail("the segments do not run from the first waypoint to the last")
    if len(transits) != len(segments) - 1:
        report.fail(
            f"{len(segments)} segments need {len(segments) - 1} transits, got {len(transits)}"
        )
    for k, seg in enumerate(segments):
        if seg["assembly_mode"] != asm:
            report.fail(f"segment {k} is in assembly mode {seg['assembly_mode']}, start in {asm}")
        if not 0 <= seg["start_index"] < seg["end_index"] <= len(w) - 1:
            report.fail(f"segment {k} has indices {seg['start_index']}..{seg['end_index']}")
    for k, (a, b, t) in enumerate(zip(segments[:-1], segments[1:], transits, strict=False)):
        if not a["end_index"] == b["start_index"] == t["index"]:
            report.fail(
                f"transit {k} at {t['index']} is not where segment {k} ends "
                f"({a['end_index']}) and {k + 1} begins ({b['start_index']})"
            )
        diff = [i for i in range(3) if a["working_mode"][i] != b["working_mode"][i]]
        if diff != [_FLIPPED_INDEX.get(t["flipped"], -1)]:
            report.fail(
                f"transit {k}: {a['working_mode']} -> {b['working_mode']} does not flip "
                f"exactly the {t['flipped']!r} sign"
            )
        if _KIND_FLIPS.get(t["kind"]) != t["flipped"]:
            report.fail(f"transit {k}: kind {t['kind']} does not flip {t['flipped']!r}")
    if len(report.failures) > before:
        return report  # the dense walk needs a consistent segmentation

    # transit postures: on the named serial singularity
    for k, t in enumerate(transits):
        i = t["index"]
        if np.max(np.abs(np.asarray(t["q"], float) - w[i])) > 1e-12:
            report.fail(f"transit {k}: q {t['q']} is not waypoint {i}")
        pt = postures(design, w[i : i + 1], branch)
        c = _FLIPPED_INDEX[t["flipped"]]
        m = pt.measures[0]
        if not pt.ok[0] or abs(m[c]) > TRANSIT_TOL:
            report.fail(
                f"transit {k} ({t['kind']}): the {t['flipped']} measure is {m[c]:.3g}, not 0"
            )
        leg = {"A": (pt.theta4[0], w[i, 1]), "B": (pt.theta5[0], w[i, 2])}.get(t["flipped"])
        if leg is not None:
            stretched = math.cos(leg[0] - leg[1]) > 0
            if stretched != t["kind"].endswith("stretched"):
                actual = "stretched" if stretched else "folded"
                report.fail(f"transit {k} is {t['kind']} but leg {t['flipped']} is {actual}")

    # dense walk along the path, piece by piece
    smin, kmax, cmin = margins["serial_min"], margins["kappa_max"], margins["clearance"]
    radius = float(design["link_radius"])
    worst = {"kappa_A": 0.0, "clearance": math.inf, "serial": math.inf}
    ends_at = {t["index"]: _FLIPPED_INDEX[t["flipped"]] for t in transits}
    for k, seg in enumerate(segments):
        signs = _mode_signs(seg["working_mode"])
        for i in range(seg["start_index"], seg["end_index"]):
            q = _dense(w[i], w[i + 1], step)
            post = postures(design, q, branch)
            report.postures_checked += len(q)
            where = f"segment {k}, piece {i}-{i + 1}"
            _common_rules(report, post, obstacles, radius, kmax, cmin, lo, hi, branch, where, worst)
            signed = post.measures * signs
            exempt = np.zeros((len(q), 3), dtype=bool)
            if i + 1 == seg["end_index"] and i + 1 in ends_at:  # ends on a transit
                exempt[:, ends_at[i + 1]] = True
                _sign_kept(report, signed[:-1, ends_at[i + 1]], where)
            if i == seg["start_index"] and i in ends_at:  # starts on a transit
                exempt[:, ends_at[i]] = True
                _sign_kept(report, signed[1:, ends_at[i]], where)
            kept = np.where(exempt, np.inf, signed)
            low = float(kept.min())
            worst["serial"] = min(worst["serial"], low)
            if low < smin - MARGIN_TOL:
                j = np.unravel_index(int(np.argmin(kept)), kept.shape)
                report.fail(
                    f"{where}: signed serial measure {j[1]} is {low:.6g} < serial_min "
                    f"{smin} for working mode {seg['working_mode']}"
                )

    trajectory = response.get("trajectory")
    if trajectory:
        _check_trajectory(
            report,
            request,
            trajectory,
            w,
            segments,
            transits,
            design,
            margins,
            limits,
            obstacles,
            branch,
            step,
            worst,
            start_state,
            lead_in_s,
        )
    report.worst = worst
    return report


def _sign_kept(report: PlanCheck, signed: np.ndarray, where: str) -> None:
    """The flipped measure keeps its segment's sign everywhere but on the transit posture."""
    if len(signed) and float(signed.min()) <= 0.0:
        report.fail(
            f"{where}: the flipped measure changes sign before the transit "
            f"({float(signed.min()):.3g})"
        )


def _common_rules(report, post, obstacles, radius, kmax, cmin, lo, hi, branch, where, worst):
    """Rules every checked posture obeys: assembly, joint limits, kappa(A), clearance."""
    if not post.ok.all() or np.any(post.assembly * branch <= 0):
        report.fail(f"{where}: a posture does not assemble in the start's assembly mode")
    if np.any((post.q < lo - JOINT_TOL) | (post.q > hi + JOINT_TOL)):
        report.fail(f"{where}: a posture leaves the joint limits")
    kappa = float(post.kappa.max())
    worst["kappa_A"] = max(worst["kappa_A"], kappa)
    if kappa > kmax * (1 + MARGIN_TOL):
        report.fail(f"{where}: kappa(A) reaches {kappa:.6g} > kappa_max {kmax}")
    if obstacles:
        clear = float(clearance(post, obstacles, radius).min())
        worst["clearance"] = min(worst["clearance"], clear)
        if clear < cmin - MARGIN_TOL:
            report.fail(f"{where}: link clearance falls to {clear:.6g} m < {cmin} m")


def _check_trajectory(
    report,
    request,
    traj,
    w,
    segments,
    transits,
    design,
    margins,
    limits,
    obstacles,
    branch,
    step,
    worst,
    start_state=None,
    lead_in_s=0.0,
):
    """The timed trajectory: time axis, ends at rest, rate limits and finite differences,
    then every sample (and the chords between them, densified) against the validity rules
    of the segment it follows."""
    t = np.asarray(traj.get("t") or [], float)
    q = np.asarray(traj.get("q") or [], float).reshape(-1, 3)
    qd = np.asarray(traj.get("qd") or [], float).reshape(-1, 3)
    qdd = np.asarray(traj.get("qdd") or [], float).reshape(-1, 3)
    if not (len(t) == len(q) == len(qd) == len(qdd)) or len(t) < 2:
        report.fail(
            f"trajectory arrays have lengths t {len(t)}, q {len(q)}, qd {len(qd)}, qdd {len(qdd)}"
        )
        return
    dt = np.diff(t)
    t0 = float(t[0]) if start_state is not None else 0.0  # a replacement: the running clock
    t = t - t0
    if abs(t[0]) > 1e-12 or np.any(dt <= 0) or abs(t[-1] - float(traj["duration"])) > 1e-9:
        report.fail("trajectory time axis does not increase from 0 to duration")
        return
    if np.max(np.abs(q[0] - w[0])) > JOINT_TOL or np.max(np.abs(q[-1] - w[-1])) > JOINT_TOL:
        report.fail("trajectory does not begin at the start and end at the path's end")
    first = np.zeros((2, 3)) if start_state is None else None
    if start_state is not None:
        first = np.array([start_state.get("qd", [0.0] * 3), start_state.get("qdd", [0.0] * 3)])
        if np.max(np.abs(q[0] - np.asarray(start_state["q"], float))) > 1e-9:
            report.fail("trajectory does not begin in the start state's posture")
        if np.max(np.abs(qdd[0] - first[1])) > 1e-9:
            report.fail("trajectory does not begin with the start state's acceleration")
    if np.max(np.abs(qd[0] - first[0])) > 1e-9 or np.max(np.abs(qd[-1])) > 1e-9:
        report.fail("trajectory does not begin in the start state and end at rest")
    vmax, amax = np.asarray(limits["velocity"], float), np.asarray(limits["acceleration"], float)
    if np.any(np.abs(qd) > vmax * (1 + LIMIT_RTOL)):
        report.fail(f"velocity reaches {np.max(np.abs(qd) / vmax):.6g} of its limit")
    if np.any(np.abs(qdd) > amax * (1 + LIMIT_RTOL)):
        report.fail(f"acceleration reaches {np.max(np.abs(qdd) / amax):.6g} of its limit")
    if traj.get("jerk") is not None:
        jmax = np.asarray(limits["jerk"], float)
        jerk = np.asarray(traj["jerk"], float).reshape(-1, 3)
        if np.any(np.abs(jerk) > jmax * (1 + LIMIT_RTOL)):
            report.fail(f"jerk reaches {np.max(np.abs(jerk) / jmax):.6g} of its limit")
    # finite differences: |dq| <= vmax dt and |dqd| <= amax dt (mean value theorem), and dq
    # is the trapezoid of qd up to amax dt^2 / 2 (qd is amax-Lipschitz)
    dq, dqd = np.diff(q, axis=0), np.diff(qd, axis=0)
    slack = 1 + 1e-6
    if np.any(np.abs(dq) > vmax * dt[:, None] * slack + 1e-12):
        report.fail("q moves faster between samples than the velocity limit allows")
    if np.any(np.abs(dqd) > amax * dt[:, None] * slack + 1e-12):
        report.fail("qd changes faster between samples than the acceleration limit allows")
    trapezoid = (qd[:-1] + qd[1:]) / 2 * dt[:, None]
    if np.any(np.abs(dq - trapezoid) > amax * dt[:, None] ** 2 / 2 * slack + 1e-12):
        report.fail("q and qd disagree: the change of q is not the integral of qd")
    if traj.get("p") is not None:
        p = np.asarray(traj["p"], float).reshape(-1, 3)
        off = float(np.max(np.linalg.norm(p - postures(design, q, branch).points["P"], axis=1)))
        if off > 1e-9:
            report.fail(f"trajectory p is {off:.3g} m away from P(q)")

    # validity of the motion: samples and the chords between them
    dense = _dense_polyline(q, step)
    post = postures(design, dense, branch)
    report.postures_checked += len(dense)
    smin = margins["serial_min"]
    _common_rules(
        report,
        post,
        obstacles,
        float(design["link_radius"]),
        margins["kappa_max"],
        margins["clearance"],
        np.asarray(design["joint_min"], float),
        np.asarray(design["joint_max"], float),
        branch,
        "trajectory",
        worst,
    )
    timing = request.get("timing") or {}
    near = timing.get("max_deviation")
    near = DEFAULT_MAX_DEVIATION if near is None else float(near)
    piece, dist = _distance_to_pieces(dense, w)
    if lead_in_s > 0.0:  # the lead-in of a moving start: not held to the corner allowance
        after = int(np.searchsorted(t, lead_in_s, side="right"))
        held = _dense_polyline(q[max(after - 1, 0) :], step)
        _, dist = _distance_to_pieces(held, w)
    if float(dist.max()) > near + 1e-6:
        report.fail(f"trajectory strays {float(dist.max()):.4g} rad from the path (allowed {near})")
    seg_of = np.zeros(len(w) - 1, dtype=int)
    for k, seg in enumerate(segments):
        seg_of[seg["start_index"] : seg["end_index"]] = k
    signs = np.array([_mode_signs(s["working_mode"]) for s in segments])[seg_of[piece]]
    signed = post.measures * signs
    exempt = np.zeros(signed.shape, dtype=bool)
    for tr in transits:  # within the corner allowance of a crossing q_in -> q_t -> q_out
        i = tr["index"]
        _, d = _distance_to_pieces(dense, w[i - 1 : i + 2])
        exempt[d <= near + 1e-9, _FLIPPED_INDEX[tr["flipped"]]] = True
    kept = np.where(exempt, np.inf, signed)
    low = float(kept.min())
    worst["serial"] = min(worst["serial"], low)
    if low < smin - MARGIN_TOL:
        report.fail(
            f"trajectory: signed serial measure falls to {low:.6g} < serial_min {smin} "
            "away from the transits (or leaves its segment's working mode)"
        )
    # the working modes follow the segments in order
    defined = np.all(np.abs(post.measures) > SIGN_EPS, axis=1)
    seen = [_label(s) for s in post.measures[defined]]
    walk = [m for k, m in enumerate(seen) if k == 0 or m != seen[k - 1]]
    expected = [s["working_mode"] for s in segments]
    if walk != expected:
        report.fail(f"trajectory visits working modes {walk}, the segments are {expected}")
