"""The pre-check of a straight tool path (:func:`inspect_cartesian`): where the polyline
start-P -> waypoints leaves the workspace of the start's working mode or meets a serial or
parallel singular surface, before any planning.

The serial surfaces are closed forms (spheres about A and B, a cylinder about the axis AB),
met by each straight segment at the roots of quadratics; kappa(A) and the joint limits are
probed along the working mode's branch and bisected (:mod:`planner.cartesian.walk`).
"""

from __future__ import annotations

import math

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

__all__ = ["inspect_cartesian"]


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
    margins = margins if margins is not None else Margins()
    fb = forward_batch(design, start.q, start.assembly_mode)
    if not fb.ok[0]:
        return ()
    p_start = fb.p[0]
    poly = Polyline(np.vstack([p_start[None], as_points(waypoints)]))
    if poly.length == 0.0:
        return ()
    L1, L2 = design.L1, design.L2
    sm = margins.serial_min
    root = math.sqrt(1.0 - sm * sm)
    centres = {"A": np.array([0.0, -design.L0 / 2, 0.0]), "B": np.array([0.0, design.L0 / 2, 0.0])}
    events: list[PathEvent] = []

    def add(kind, s_global, entering, detail, seg):
        p = poly.at(np.array([s_global]))[0]
        events.append(
            PathEvent(
                kind,
                int(poly.given_index[seg + 1] - 1),
                s_global / poly.length,
                p,
                entering,
                detail,
            )
        )

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
                    add(
                        kind,
                        s0 + s,
                        entering,
                        f"{kind}: |{leg}P| = {radius:.6g} m, the line {verb} the workspace",
                        k,
                    )
            for sign, which in ((+1, "stretched"), (-1, "folded")):
                radius = math.sqrt(max(L1 * L1 + L2 * L2 + sign * 2 * L1 * L2 * root, 0.0))
                for s in _sphere_crossings(p0, d, length, c, radius):
                    grad = float((p0 + s * d - c) @ d)
                    entering = grad * sign > 0
                    add(
                        "serial_min",
                        s0 + s,
                        entering,
                        f"serial_min: |sin(theta{4 if leg == 'A' else 5} - "
                        f"theta{2 if leg == 'A' else 3})| = {sm:g} (leg {leg} near {which}, "
                        f"|{leg}P| = {radius:.6g} m)",
                        k,
                    )
        for s in _cylinder_crossings(p0, d, length, 0.0):
            add("P_on_axis", s0 + s, True, "P_on_axis: P meets the axis AB (w = 0)", k)
        for s in _cylinder_crossings(p0, d, length, sm * design.reach):
            q = p0 + s * d
            entering = float(q[0] * d[0] + q[2] * d[2]) < 0
            add(
                "serial_min",
                s0 + s,
                entering,
                f"serial_min: |w| / (L1 + L2) = {sm:g} (P {sm * design.reach:.4g} m from "
                "the axis AB)",
                k,
            )

    # probed: kappa(A) and the joint limits along the working mode's branch
    mode = posture_mode(design, start)
    if mode is not None:
        slot = WORKING_MODES.index(mode)
        asm_sign = 1 if start.assembly_mode == "+" else -1
        check_deadline(deadline, "before probing the Cartesian pre-check")
        n = min(max(2, math.ceil(poly.length / probe_step) + 1), MAX_INSPECT_PROBES)
        s = np.linspace(0.0, poly.length, n)
        q, ok, _, _ = branch_ik(design, poly.at(s), slot, asm_sign)
        q[0] = start.q
        lo, hi = margins.cd_range

        def measures(qq, okk):
            cd = np.where(okk, cd_length(design, np.nan_to_num(qq)) / (2 * L2), np.nan)
            kappa_ok = (cd >= lo) & (cd <= hi)
            return cd, kappa_ok

        cd, kappa_ok = measures(q, ok)
        run = np.cumprod(ok).astype(bool)  # the branch exists from the start up to here
        qc = unwrap_chain(np.nan_to_num(q[1:]), start.q) if n > 1 else q
        qc = np.vstack([start.q[None], qc])
        jl_ok = np.all(
            (qc >= np.asarray(design.joint_min) - 1e-12)
            & (qc <= np.asarray(design.joint_max) + 1e-12),
            axis=1,
        )
        for kind, good in (("kappa_max", kappa_ok), ("joint_limits", jl_ok)):
            for i in np.flatnonzero((good[1:] != good[:-1]) & run[1:] & run[:-1]):
                ga = bool(good[i])

                def classify(s_, kind=kind, ga=ga, ref=qc[i]):
                    qm, okm, _, _ = branch_ik(design, poly.at(s_), slot, asm_sign)
                    if kind == "kappa_max":
                        gm = measures(qm, okm)[1]
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
                add(kind, 0.5 * (a + b), bool(ga), detail, seg)
        # parallel singularities: |CD| / (2 L2) reaching 0 or 1 between probes is inside the
        # kappa band's complement; report where kappa(A) is largest there
        bad = run & ~kappa_ok
        if np.any(bad):
            dist = np.minimum(cd, 1.0 - cd)
            for i in np.flatnonzero(bad):
                if 0 < i < n - 1 and dist[i] <= dist[i - 1] and dist[i] <= dist[i + 1]:
                    if dist[i] < 1e-3:
                        kind_p = "C=D" if cd[i] < 0.5 else "CD_stretched"
                        seg = int(poly.segment_of(np.array([s[i]]))[0])
                        add(
                            "parallel",
                            float(s[i]),
                            True,
                            f"parallel: C, D and P nearly aligned ({kind_p}), kappa(A) very large",
                            seg,
                        )
    events.sort(key=lambda e: e.fraction)
    return tuple(events)
