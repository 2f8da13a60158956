"""The sentences of a straight tool path that stops short (:mod:`planner.cartesian.plan`): the
rule broken where the path ends, its measured value and its bound, with just enough digits to
tell them apart."""

from __future__ import annotations

import numpy as np

from planner.design import Design
from planner.kinematics import conditioning, forward_batch
from planner.validity import ValidityChecker

__all__ = ["describe_stop", "format_point"]


def _fmt_value(value: float, bound: float) -> str:
    """``value`` with just enough digits to differ from ``bound`` (at least 4)."""
    for digits in range(4, 17):
        a, b = f"{value:.{digits}g}", f"{bound:.{digits}g}"
        if a != b:
            return a
    return repr(value)


def _joint_limit_text(i: int, value: float, bound: float) -> str:
    """ "joint_limits: theta<i+1> = value rad > joint_max[i] = bound rad" (or < joint_min), the
    bound with the value's digits: a bound written with fewer reads as another number (pi as
    "3.14159" beside a theta2 of "3.14159266")."""
    rel = "<" if value < bound else ">"
    shown = _fmt_value(value, bound)
    digits = sum(c.isdigit() for c in shown.split("e")[0].lstrip("-0."))
    return (
        f"joint_limits: theta{i + 1} = {shown} rad {rel} "
        f"joint_{'min' if rel == '<' else 'max'}[{i}] = {bound:.{max(6, digits)}g} rad"
    )


def format_point(p: np.ndarray) -> str:
    """A point as "(x, y, z)" with 4 significant digits, m."""
    return "(" + ", ".join(f"{x:.4g}" for x in p) + ")"


def describe_stop(
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
        q_lo, q_hi = np.asarray(design.joint_min), np.asarray(design.joint_max)
        i = int(np.argmax(np.maximum(q_lo - q_bad, q_bad - q_hi)))
        bound = q_lo[i] if q_bad[i] < q_lo[i] else q_hi[i]
        return float(q_bad[i]), _joint_limit_text(i, float(q_bad[i]), float(bound))
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
        gap = float(rep.clearance[0])
        return gap, (
            f"clearance: link clearance {_fmt_value(gap, m.clearance)} m < "
            f"margins.clearance = {m.clearance:g} m"
        )
    return float("nan"), checker.explain(q_bad)
