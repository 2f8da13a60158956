"""The pre-check of a straight tool path (:func:`inspect_cartesian`): where the polyline
start-P -> waypoints leaves the workspace of the start's working mode or meets a serial or
parallel singular surface, before any planning.

The serial surfaces are closed forms (spheres about A and B, a cylinder about the axis AB),
met by each straight segment at the roots of quadratics; kappa(A) and the joint limits are
probed along the working mode's branch and bisected (:mod:`planner.cartesian.walk`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.cartesian.chords import cd_length
from planner.cartesian.result import PathEvent
from planner.cartesian.walk import (
    BISECT_TOL,
    PROBE_STEP,
    Polyline,
    as_points,
    branch_ik,
    narrow_bracket,
    unwrap_chain,
    unwrap_to,
)
from planner.design import Design
from planner.exceptions import check_deadline
from planner.kinematics import WORKING_MODES, forward_batch
from planner.planning.problem import JointPosture
from planner.planning.single_mode import posture_mode
from planner.validity import Margins

#: Most probes of the pre-check's probed rules (kappa_max, joint limits, parallel
#: singularities): bounds its time and memory whatever the polyline's length.
MAX_INSPECT_PROBES = 20_000

__all__ = ["BranchSamples", "inspect_cartesian", "inspect_with_branch"]


@dataclass(frozen=True, slots=True, eq=False)
class BranchSamples:
    """The inverse kinematics of the working mode's branch (slot ``slot``, assembly sign
    ``asm_sign``) at arc lengths ``s`` (m) of the polyline through ``vertices``, as
    :func:`~planner.cartesian.walk.branch_ik` gives them (q wrapped, ok, w, flipped): the
    pre-check's probes, which the plan's probes at the same points take instead of solving
    them again (:func:`planner.cartesian.certify.probe_polyline`)."""

    vertices: np.ndarray
    slot: int
    asm_sign: int
    s: np.ndarray
    q: np.ndarray
    ok: np.ndarray
    w: np.ndarray
    flipped: np.ndarray


def _sphere_crossings(p0, d, length, centre, radius):
    """Parameters s in (0, length] where |p0 + s d - centre| = radius (d unit)."""
    f = p0 - centre
    b = float(f @ d)
    c = float(f @ f) - radius * radius
    disc = b * b - c
    if disc < 0:
        return []
    r = math.sqrt(disc)
    return [s for s in (-b - r, -b + r) if 0.0 < s <= length]


def _cylinder_crossings(p0, d, length, radius):
    """Parameters where the distance to the y axis (x^2 + z^2) equals radius (radius >= 0);
    for radius 0 the parameter of the closest approach when it touches the axis."""
    px, pz, dx, dz = p0[0], p0[2], d[0], d[2]
    a = dx * dx + dz * dz
    b = px * dx + pz * dz
    c = px * px + pz * pz - radius * radius
    if a < 1e-300:
        return []
    if radius == 0.0:
        s = -b / a
        closest = math.hypot(px + s * dx, pz + s * dz)
        return [s] if 0.0 < s <= length and closest <= 1e-12 else []
    disc = b * b - a * c
    if disc < 0:
        return []
    r = math.sqrt(disc)
    return [s for s in ((-b - r) / a, (-b + r) / a) if 0.0 < s <= length]


def inspect_cartesian(
    design: Design,
    start: JointPosture,
    waypoints: np.ndarray,
    *,
    margins: Margins | None = None,
    probe_step: float = PROBE_STEP,
    deadline: float | None = None,
) -> tuple[PathEvent, ...]:
    """Where the polyline start-P -> waypoints meets the singular surfaces of the start's
    working mode, before planning (a pre-check; obstacles are not considered).

    The serial singular surfaces and the serial margins are closed forms: leg A is stretched
    or folded where |AP| = L1 + L2 or |L2 - L1|, and |sin(theta4 - theta2)| = serial_min where
    |AP|^2 = L1^2 + L2^2 +- 2 L1 L2 sqrt(1 - serial_min^2) (law of cosines in A-C-P); the same
    about B; P is on the axis where x = z = 0, and |w| / (L1 + L2) = serial_min on the cylinder
    of radius serial_min (L1 + L2) about it. Their crossings with each straight segment are
    roots of quadratics. kappa(A) depends on the working mode's inverse kinematics, so the
    kappa_max and parallel surfaces are found by probing every ``probe_step`` m and bisecting;
    so are the joint limits (literal, unwrapped from the start). At most
    :data:`MAX_INSPECT_PROBES` probes: a longer polyline is probed more coarsely (a pre-check's
    hints; :func:`planner.cartesian.plan.plan_cartesian` itself probes every
    :data:`PROBE_STEP` m). Past ``deadline`` (a :func:`time.monotonic` value),
    :class:`~planner.exceptions.DeadlineError`.

    Returns
    -------
    tuple of PathEvent, ordered along the polyline.
    """
    return inspect_with_branch(
        design, start, waypoints, margins=margins, probe_step=probe_step, deadline=deadline
    )[0]


def inspect_with_branch(
    design: Design,
    start: JointPosture,
    waypoints: np.ndarray,
    *,
    margins: Margins | None = None,
    probe_step: float = PROBE_STEP,
    deadline: float | None = None,
    built: tuple[Polyline, str] | None = None,
) -> tuple[tuple[PathEvent, ...], BranchSamples | None]:
    """:func:`inspect_cartesian`'s events, and the inverse kinematics of its probes (None
    when it probed nothing), for the plan's own probes. ``built``: the polyline from P of an
    assembled start through ``waypoints`` and the start's working mode, when the caller has
    built them (the plan), not built again."""
    margins = margins if margins is not None else Margins()
    if built is None:
        fb = forward_batch(design, start.q, start.assembly_mode)
        if not fb.ok[0]:
            return (), None
        poly = Polyline(np.vstack([fb.p[0][None], as_points(waypoints)]))
        mode = posture_mode(design, start)
    else:
        poly, mode = built
    if poly.length == 0.0:
        return (), None
    events = _closed_form_events(design, margins.serial_min, poly)
    # probed: kappa(A) and the joint limits along the working mode's branch
    samples = None
    if mode is not None:
        check_deadline(deadline, "before probing the Cartesian pre-check")
        probed, samples = _probed_events(design, margins, start, mode, poly, probe_step)
        events += probed
    events.sort(key=lambda e: e.fraction)
    return tuple(events), samples


def _event(
    poly: Polyline, kind: str, s_global: float, entering: bool, detail: str, seg: int
) -> PathEvent:
    """The event ``kind`` at arc length ``s_global`` (m) of ``poly``, on its segment
    ``seg``, numbered by the given waypoint that segment leads to."""
    p = poly.at(np.array([s_global]))[0]
    return PathEvent(
        kind,
        int(poly.given_index[seg + 1] - 1),
        s_global / poly.length,
        p,
        entering,
        detail,
    )


def _closed_form_events(design: Design, sm: float, poly: Polyline) -> list[PathEvent]:
    """The closed-form step of :func:`inspect_cartesian`: each segment's crossings with the
    legs' stretched and folded spheres, the spheres of ``sm`` = serial_min about A and B,
    the axis AB and the cylinder of radius ``sm`` (L1 + L2) about it."""
    L1, L2 = design.L1, design.L2
    root = math.sqrt(1.0 - sm * sm)
    centres = {"A": np.array([0.0, -design.L0 / 2, 0.0]), "B": np.array([0.0, design.L0 / 2, 0.0])}
    events: list[PathEvent] = []
    for k in range(len(poly.lengths)):
        p0, d, length = poly.vertices[k], poly.dirs[k], float(poly.lengths[k])
        s0 = float(poly.cum[k])
        for leg, c in centres.items():
            surfaces = (
                (f"leg_{leg}_stretched", L1 + L2, +1),
                (f"leg_{leg}_folded", abs(L2 - L1), -1),
            )
            for kind, radius, outward in surfaces:
                for s in _sphere_crossings(p0, d, length, c, radius):
                    grad = float((p0 + s * d - c) @ d)  # > 0: moving away from the centre
                    entering = grad * outward > 0
                    verb = "leaves" if entering else "enters"
                    detail = f"{kind}: |{leg}P| = {radius:.6g} m, the line {verb} the workspace"
                    events.append(_event(poly, kind, s0 + s, entering, detail, k))
            for sign, which in ((+1, "stretched"), (-1, "folded")):
                radius = math.sqrt(max(L1 * L1 + L2 * L2 + sign * 2 * L1 * L2 * root, 0.0))
                for s in _sphere_crossings(p0, d, length, c, radius):
                    grad = float((p0 + s * d - c) @ d)
                    entering = grad * sign > 0
                    detail = (
                        f"serial_min: |sin(theta{4 if leg == 'A' else 5} - "
                        f"theta{2 if leg == 'A' else 3})| = {sm:g} (leg {leg} near {which}, "
                        f"|{leg}P| = {radius:.6g} m)"
                    )
                    events.append(_event(poly, "serial_min", s0 + s, entering, detail, k))
        for s in _cylinder_crossings(p0, d, length, 0.0):
            detail = "P_on_axis: P meets the axis AB (w = 0)"
            events.append(_event(poly, "P_on_axis", s0 + s, True, detail, k))
        for s in _cylinder_crossings(p0, d, length, sm * design.reach):
            q = p0 + s * d
            entering = float(q[0] * d[0] + q[2] * d[2]) < 0
            detail = (
                f"serial_min: |w| / (L1 + L2) = {sm:g} (P {sm * design.reach:.4g} m from "
                "the axis AB)"
            )
            events.append(_event(poly, "serial_min", s0 + s, entering, detail, k))
    return events


def _kappa_band(
    design: Design, margins: Margins, q: np.ndarray, ok: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """|CD| / (2 L2) of postures q (N, 3) (NaN where not ``ok``), and whether it lies in the
    band of ``margins.kappa_max``."""
    lo, hi = margins.cd_range
    cd = np.where(ok, cd_length(design, np.nan_to_num(q)) / (2 * design.L2), np.nan)
    return cd, (cd >= lo) & (cd <= hi)


def _probed_events(
    design: Design,
    margins: Margins,
    start: JointPosture,
    mode: str,
    poly: Polyline,
    probe_step: float,
) -> tuple[list[PathEvent], BranchSamples]:
    """The probed step of :func:`inspect_cartesian`: along the working mode's branch, every
    ``probe_step`` m (at most :data:`MAX_INSPECT_PROBES` probes), where kappa(A) crosses
    kappa_max and a joint its literal limit (bisected between probes), then the parallel
    singularities (:func:`_parallel_events`); and the probes' inverse kinematics."""
    slot = WORKING_MODES.index(mode)
    asm_sign = 1 if start.assembly_mode == "+" else -1
    n = min(max(2, math.ceil(poly.length / probe_step) + 1), MAX_INSPECT_PROBES)
    s = np.linspace(0.0, poly.length, n)
    q, ok, w, flipped = branch_ik(design, poly.at(s), slot, asm_sign)
    samples = BranchSamples(poly.vertices, slot, asm_sign, s, q.copy(), ok, w, flipped)
    q[0] = start.q
    cd, kappa_ok = _kappa_band(design, margins, q, ok)
    run = np.cumprod(ok).astype(bool)  # the branch exists from the start up to here
    qc = unwrap_chain(np.nan_to_num(q[1:]), start.q) if n > 1 else q
    qc = np.vstack([start.q[None], qc])
    jl_ok = np.all(
        (qc >= np.asarray(design.joint_min) - 1e-12) & (qc <= np.asarray(design.joint_max) + 1e-12),
        axis=1,
    )
    events: list[PathEvent] = []
    for kind, good in (("kappa_max", kappa_ok), ("joint_limits", jl_ok)):
        for i in np.flatnonzero((good[1:] != good[:-1]) & run[1:] & run[:-1]):
            ga = bool(good[i])

            def classify(s_, kind=kind, ga=ga, ref=qc[i]):
                qm, okm, _, _ = branch_ik(design, poly.at(s_), slot, asm_sign)
                if kind == "kappa_max":
                    gm = _kappa_band(design, margins, qm, okm)[1]
                else:
                    qm = unwrap_to(qm, ref)
                    gm = np.all((qm >= design.joint_min) & (qm <= design.joint_max), axis=1)
                return gm == ga, qm, np.full(len(s_), "")

            a, b, _, _ = narrow_bracket(float(s[i]), float(s[i + 1]), classify, BISECT_TOL)
            seg = int(poly.segment_of(np.array([a]))[0])
            if kind == "kappa_max":
                detail = f"kappa_max: kappa(A) = {margins.kappa_max:g}"
            else:
                detail = "joint_limits: a joint reaches its literal limit"
            events.append(_event(poly, kind, 0.5 * (a + b), bool(ga), detail, seg))
    return events + _parallel_events(poly, s, cd, run & ~kappa_ok), samples


def _parallel_events(
    poly: Polyline, s: np.ndarray, cd: np.ndarray, bad: np.ndarray
) -> list[PathEvent]:
    """Parallel singularities among the probes at arc lengths ``s`` (m): |CD| / (2 L2)
    (``cd``) reaching 0 or 1 between probes is inside the kappa band's complement (``bad``,
    on the branch); reported where kappa(A) is largest there."""
    events: list[PathEvent] = []
    if not np.any(bad):
        return events
    n = len(s)
    dist = np.minimum(cd, 1.0 - cd)
    for i in np.flatnonzero(bad):
        if 0 < i < n - 1 and dist[i] <= dist[i - 1] and dist[i] <= dist[i + 1]:
            if dist[i] < 1e-3:
                kind_p = "C=D" if cd[i] < 0.5 else "CD_stretched"
                seg = int(poly.segment_of(np.array([s[i]]))[0])
                detail = f"parallel: C, D and P nearly aligned ({kind_p}), kappa(A) very large"
                events.append(_event(poly, "parallel", float(s[i]), True, detail, seg))
    return events
