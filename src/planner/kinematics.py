"""Kinematics of the 3-DOF hybrid manipulator: postures, modes, Jacobians, conditioning.

Frame (``docs/conventions.md``): O is the midpoint of AB, +y points from A to B, theta1 turns the
linkage plane about +y. In the plane, u runs along +y and w along
``e(theta1) = (cos theta1, 0, -sin theta1)``, so ``P = (w cos theta1, u, -w sin theta1)``.
Planar angles are measured from A->B, counter-clockwise about the plane normal
``k = (sin theta1, 0, cos theta1)``::

            w (e)
            ^            P
            |          /   \\
            |    L2  /       \\  L2
            |      C           D
            |   L1/             \\ L1
    --------A-----O-----B---------> u (= y)
            |<-L0/2->|<-L0/2->|

Two layers:

* vectorised functions over N postures (:func:`forward_batch`, :func:`inverse_batch`,
  :func:`conditioning`, :func:`link_points`), used by analysis and planning;
* :class:`Manipulator` with one :class:`Posture` at a time, for people.

Angles: actuated joint values given to forward kinematics are kept literal (joint limits are
literal); passive angles and inverse-kinematics solutions are wrapped into (-pi, pi].
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from types import MappingProxyType
from typing import Literal, overload

import numpy as np

from planner import _kernels
from planner.constants import ASSEMBLY_TOL, AXIS_TOL, KAPPA_SOLVABLE, REACH_TOL, SIGN_TOL
from planner.design import Design
from planner.exceptions import AssemblyError, InputError, SingularPostureError

__all__ = [
    "ASSEMBLY_MODES",
    "SERIAL_KINDS",
    "WORKING_MODES",
    "Conditioning",
    "InverseBatch",
    "Manipulator",
    "Posture",
    "PostureBatch",
    "conditioning",
    "forward_batch",
    "forward_velocity",
    "inverse_batch",
    "inverse_in_mode",
    "link_points",
    "mode_label",
    "mode_signs",
    "reach_reason",
    "wrap_angle",
]

#: The eight working modes (s_axis, s_A, s_B), in the slot order of :func:`inverse_batch`.
WORKING_MODES: tuple[str, ...] = ("+++", "++-", "+-+", "+--", "-++", "-+-", "--+", "---")
#: The two assembly modes: sign of sin(theta5 - theta4).
ASSEMBLY_MODES: tuple[str, ...] = ("+", "-")
#: Names of the serial-singularity measures, in the order of the working-mode signs.
SERIAL_KINDS: tuple[str, ...] = ("P_on_axis", "leg_A", "leg_B")

_SIGN_CHAR = {1: "+", -1: "-", 0: "0"}
# For each slot of WORKING_MODES: index of the axis side, leg-A elbow side, leg-B elbow side
# in the inverse kernel's output (0 for '+', 1 for '-').
_SLOT_INDEX = tuple(np.array([0 if m[j] == "+" else 1 for m in WORKING_MODES]) for j in range(3))

AssemblyMode = Literal["+", "-"]


def reach_reason(design: Design, p: Sequence[float] | np.ndarray) -> str | None:
    """Why no posture of ``design`` reaches the point ``p`` (m) in any working mode, or None
    when both legs reach it: without joint limits a leg reaches P exactly when its pivot's
    distance to P lies between |L2 - L1| and L1 + L2 (A = (0, -L0/2, 0), B = (0, +L0/2, 0)).
    The one wording of this reason (``planner ik``, the planner's ``unreachable``)."""
    outer, inner = design.L1 + design.L2, abs(design.L2 - design.L1)
    legs = []
    for leg, pivot_y in (("A", -design.L0 / 2), ("B", design.L0 / 2)):
        r = math.dist([float(x) for x in p], (0.0, pivot_y, 0.0))
        if r > outer:
            legs.append(f"of leg {leg} (|{leg}P| = {r:.6g} m > L1 + L2 = {outer:.6g} m)")
        elif r < inner:
            legs.append(f"of leg {leg} (|{leg}P| = {r:.6g} m < |L2 - L1| = {inner:.6g} m)")
    return f"P is out of reach {' and '.join(legs)}" if legs else None


@overload
def wrap_angle(x: float) -> float: ...
@overload
def wrap_angle(x: np.ndarray) -> np.ndarray: ...
def wrap_angle(x: np.ndarray | float) -> np.ndarray | float:
    """Angle(s) mapped into (-pi, pi]: an array for an array, a float for a float."""
    return np.pi - np.mod(np.pi - np.asarray(x, dtype=float), 2 * np.pi)


def mode_label(signs: np.ndarray) -> str:
    """'+-+'-style label of a sign vector; a 0 sign (exactly on a singularity) is written '0'."""
    return "".join(_SIGN_CHAR[int(s)] for s in np.asarray(signs).ravel().tolist())


def mode_signs(label: str) -> np.ndarray:
    """Signs (int8, +1/-1/0) of a '+-+'-style working-mode or '+'/'-' assembly-mode label:
    the inverse of :func:`mode_label`."""
    return np.array([{"+": 1, "-": -1, "0": 0}[c] for c in label], dtype=np.int8)


def _sign(x: np.ndarray) -> np.ndarray:
    """Sign with a dead band: |x| <= SIGN_TOL (and NaN) counts as 0."""
    x = np.asarray(x)
    return (x > SIGN_TOL).astype(np.int8) - (x < -SIGN_TOL).astype(np.int8)


def _finite_array(name: str, value: object, last: int) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numbers, got {value!r}") from exc
    if arr.ndim == 0 or arr.shape[-1] != last or arr.ndim > 2:
        raise InputError(f"{name} must have shape ({last},) or (N, {last}), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be finite (no NaN or infinity)")
    return arr


def _branch(assembly_mode: object, n: int) -> np.ndarray:
    """Assembly mode(s) as +1/-1 int8 of shape (n,)."""
    if isinstance(assembly_mode, str):
        if assembly_mode not in ASSEMBLY_MODES:
            raise InputError(f"assembly_mode must be '+' or '-', got {assembly_mode!r}")
        return np.full(n, 1 if assembly_mode == "+" else -1, dtype=np.float64)
    arr = np.broadcast_to(np.asarray(assembly_mode, dtype=float), (n,))
    if not np.all(np.abs(arr) == 1):
        raise InputError("assembly_mode must be '+'/'-' or +1/-1 per posture")
    return np.array(arr, dtype=np.float64)  # a writable copy: one compiled signature


# ---------------------------------------------------------------------------- batches
@dataclass(frozen=True, slots=True)
class PostureBatch:
    """Many postures at once; every array shares the leading shape ``S`` ((N,) or (N, 8)).

    Attributes
    ----------
    q : shape S + (3,), rad
        Actuated joints (theta1, theta2, theta3).
    passive : shape S + (2,), rad
        Passive joints (theta4, theta5), in (-pi, pi].
    p : shape S + (3,), m
        Point P in the base frame.
    w : shape S, m
        In-plane coordinate of P normal to AB (signed distance to the axis).
    ok : shape S, bool
        The posture exists. Where False, the other arrays hold NaN.
    """

    design: Design
    q: np.ndarray
    passive: np.ndarray
    p: np.ndarray
    w: np.ndarray
    ok: np.ndarray

    @property
    def serial_measures(self) -> np.ndarray:
        """Shape S + (3,): w / (L1 + L2), sin(theta4 - theta2), sin(theta5 - theta3);
        dimensionless, their signs are the working mode."""
        return np.stack(
            [
                self.w / self.design.reach,
                np.sin(self.passive[..., 0] - self.q[..., 1]),
                np.sin(self.passive[..., 1] - self.q[..., 2]),
            ],
            axis=-1,
        )

    @property
    def working_mode_signs(self) -> np.ndarray:
        """Shape S + (3,), int8 in {-1, 0, +1}: (s_axis, s_A, s_B)."""
        return _sign(self.serial_measures)

    @property
    def assembly_mode_signs(self) -> np.ndarray:
        """Shape S, int8: sign of sin(theta5 - theta4) (0 on the CD-stretched singularity)."""
        return _sign(np.sin(self.passive[..., 1] - self.passive[..., 0]))


def forward_batch(design: Design, q: np.ndarray, assembly_mode: object) -> PostureBatch:
    """Direct kinematics of N postures.

    Parameters
    ----------
    q : array, shape (N, 3) or (3,), rad
        Actuated joints.
    assembly_mode : '+' | '-' | array of +1/-1, shape (N,)
        Which of the two loop closures to take (sign of sin(theta5 - theta4)).

    Returns
    -------
    PostureBatch
        Leading shape (N,). ``ok`` is False where the loop does not close
        (|CD| > 2 L2) or C = D (P undetermined: a parallel singularity).
    """
    q2 = np.ascontiguousarray(np.atleast_2d(_finite_array("q", q, 3)))
    n = q2.shape[0]
    p = np.empty((n, 3))
    passive = np.empty((n, 2))
    dx = np.empty((n, 2))
    w = np.empty(n)
    ok = np.empty(n, dtype=np.bool_)
    _kernels.forward_kernel(
        design.L0,
        design.L1,
        design.L2,
        _kernels.read_only(q2),  # one compiled signature, frozen q or not
        _branch(assembly_mode, n),
        ASSEMBLY_TOL,
        p,
        passive,
        dx,
        w,
        ok,
    )
    np.arctan2(passive, dx, out=passive)
    return PostureBatch(design, q2, passive, p, w, ok)


def forward_velocity(
    design: Design, q: np.ndarray, qd: np.ndarray, assembly_mode: object
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """P (N, 3), m, and its velocity dP/dt = J(q) qd (N, 3), m/s, of postures q (N, 3), rad,
    moving at qd (N, 3), rad/s, in one compiled pass (the loop closure differentiated, see
    :func:`planner._kernels.forward_velocity_kernel`); ``ok`` (N,) is False where the loop
    does not close (P and v NaN) or CD is stretched (v NaN: the velocity is unbounded
    there). P is :func:`forward_batch`'s exactly."""
    q2 = np.ascontiguousarray(np.atleast_2d(_finite_array("q", q, 3)))
    qd2 = np.ascontiguousarray(np.atleast_2d(_finite_array("qd", qd, 3)))
    if qd2.shape != q2.shape:
        raise InputError(f"qd must have the shape of q {q2.shape}, got {qd2.shape}")
    n = q2.shape[0]
    p, v, ok = np.empty((n, 3)), np.empty((n, 3)), np.empty(n, dtype=np.bool_)
    _kernels.forward_velocity_kernel(
        design.L0, design.L1, design.L2, q2, qd2, _branch(assembly_mode, n), ASSEMBLY_TOL, p, v, ok
    )
    return p, v, ok


@dataclass(frozen=True, slots=True)
class InverseBatch(PostureBatch):
    """Inverse kinematics of N points: a :class:`PostureBatch` of leading shape (N, 8), slot k
    being ``WORKING_MODES[k]``, plus ``degenerate`` (N,): points where one leg's angle is
    undetermined (P = A or P = B with L1 = L2), which have no slot ``ok``."""

    degenerate: np.ndarray = None  # type: ignore[assignment]


def inverse_batch(design: Design, p: np.ndarray, *, theta1_on_axis: float = 0.0) -> InverseBatch:
    """Inverse kinematics of N points P into the eight working modes.

    Parameters
    ----------
    p : array, shape (N, 3) or (3,), m
    theta1_on_axis : float, rad
        theta1 reported for a point on the axis AB, where every theta1 gives the same P.

    Returns
    -------
    InverseBatch
        Leading shape (N, 8). A slot is ``ok`` when that working mode reaches P and it is not a
        duplicate: on a serial singularity two modes meet, and only the slot with '+' in the
        vanishing sign is kept (its mode then has a '0' there). Joint limits are not applied.
    """
    p2, ys, xs, leg_ok, degenerate, on_axis, t1 = _inverse_legs(design, p, theta1_on_axis)
    n = p2.shape[0]
    angles = np.arctan2(ys, xs, out=ys)
    ax, sa, sb = _SLOT_INDEX
    q = np.empty((n, 8, 3))
    q[..., 0] = t1[:, ax]
    q[..., 1] = angles[:, ax, 0, sa, 0]
    q[..., 2] = angles[:, ax, 1, sb, 0]
    q = wrap_angle(q)
    passive = np.stack([angles[:, ax, 0, sa, 1], angles[:, ax, 1, sb, 1]], axis=-1)
    ok = leg_ok[:, ax, 0, sa] & leg_ok[:, ax, 1, sb]
    w = np.where(ax == 0, 1.0, -1.0) * np.where(on_axis, 0.0, np.hypot(p2[:, 0], p2[:, 2]))[:, None]
    nan = ~ok
    q[nan] = np.nan
    passive[nan] = np.nan
    w = np.where(nan, np.nan, w)
    p_rep = np.broadcast_to(p2[:, None, :], (n, 8, 3))
    return InverseBatch(design, q, passive, p_rep, w, ok, degenerate)


def inverse_in_mode(
    design: Design, p: np.ndarray, slot: int, *, theta1_on_axis: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Inverse kinematics of N points P in one working mode (``WORKING_MODES[slot]``): the
    values of slot ``slot`` of :func:`inverse_batch`, without the other seven (a walk along
    one branch needs one; the angles of the others are most of inverse_batch's time).

    Returns
    -------
    q : (N, 3), rad, wrapped; passive : (N, 2), rad; w : (N,), m (NaN where not ok);
    ok : (N,) bool, as ``InverseBatch.ok[:, slot]``; degenerate : (N,) bool;
    assembly_signs : (N,) int8, as ``InverseBatch.assembly_mode_signs[:, slot]``.
    """
    p2, ys, xs, leg_ok, degenerate, on_axis, t1 = _inverse_legs(design, p, theta1_on_axis)
    n = p2.shape[0]
    ax, sa, sb = (int(index[slot]) for index in _SLOT_INDEX)
    leg_a = np.arctan2(ys[:, ax, 0, sa], xs[:, ax, 0, sa])  # (N, 2): theta2, theta4
    leg_b = np.arctan2(ys[:, ax, 1, sb], xs[:, ax, 1, sb])  # (N, 2): theta3, theta5
    q = np.empty((n, 3))
    q[:, 0] = t1[:, ax]
    q[:, 1] = leg_a[:, 0]
    q[:, 2] = leg_b[:, 0]
    q = wrap_angle(q)
    passive = np.stack([leg_a[:, 1], leg_b[:, 1]], axis=-1)
    ok = leg_ok[:, ax, 0, sa] & leg_ok[:, ax, 1, sb]
    w = (1.0 if ax == 0 else -1.0) * np.where(on_axis, 0.0, np.hypot(p2[:, 0], p2[:, 2]))
    nan = ~ok
    q[nan] = np.nan
    passive[nan] = np.nan
    w = np.where(nan, np.nan, w)
    signs = _sign(np.sin(passive[:, 1] - passive[:, 0]))
    return q, passive, w, ok, degenerate, signs


def _inverse_legs(design: Design, p: np.ndarray, theta1_on_axis: float) -> tuple[np.ndarray, ...]:
    """The kernel step of :func:`inverse_batch` and :func:`inverse_in_mode`: the points as
    (N, 3), each leg's (y, x) of its joint angles per axis choice and elbow sign (N, 2, 2, 2,
    2), which legs reach (N, 2, 2, 2), the degenerate points, the points on the axis and
    theta1 per axis choice (N, 2)."""
    p2 = np.ascontiguousarray(np.atleast_2d(_finite_array("p", p, 3)))
    n = p2.shape[0]
    ys = np.empty((n, 2, 2, 2, 2))
    xs = np.empty((n, 2, 2, 2, 2))
    leg_ok = np.empty((n, 2, 2, 2), dtype=np.bool_)
    degenerate = np.empty(n, dtype=np.bool_)
    _kernels.inverse_kernel(
        design.L0,
        design.L1,
        design.L2,
        _kernels.read_only(p2),  # one compiled signature, frozen p or not
        REACH_TOL,
        SIGN_TOL,
        AXIS_TOL,
        ys,
        xs,
        leg_ok,
        degenerate,
    )
    on_axis = np.hypot(p2[:, 0], p2[:, 2]) <= AXIS_TOL * design.reach
    t1 = np.stack([np.arctan2(-p2[:, 2], p2[:, 0]), np.arctan2(p2[:, 2], -p2[:, 0])], axis=1)
    t1[on_axis] = float(theta1_on_axis)
    return p2, ys, xs, leg_ok, degenerate, on_axis, t1


def link_points(design: Design, q: np.ndarray, passive: np.ndarray) -> np.ndarray:
    """3-D joint centres of postures, shape S + (5, 3) in the order A, B, C, D, P, m.

    ``q`` has shape S + (3,) and ``passive`` S + (2,); P is rebuilt from C and theta4.
    """
    q = np.asarray(q, dtype=float)
    passive = np.asarray(passive, dtype=float)
    half = design.L0 / 2
    t1, t2, t3 = q[..., 0], q[..., 1], q[..., 2]
    cu = -half + design.L1 * np.cos(t2)
    cw = design.L1 * np.sin(t2)
    du = half + design.L1 * np.cos(t3)
    dw = design.L1 * np.sin(t3)
    pu = cu + design.L2 * np.cos(passive[..., 0])
    pw = cw + design.L2 * np.sin(passive[..., 0])
    c, s = np.cos(t1), np.sin(t1)
    # Filled in place rather than stacked: one allocation, which is most of the cost for the
    # single postures of /v1/fk and /v1/ik.
    out = np.empty((*t1.shape, 5, 3))
    out[..., 0, :] = (0.0, -half, 0.0)
    out[..., 1, :] = (0.0, half, 0.0)
    for k, (uk, wk) in enumerate(((cu, cw), (du, dw), (pu, pw)), start=2):
        out[..., k, 0] = wk * c
        out[..., k, 1] = uk
        out[..., k, 2] = -wk * s
    return out


@dataclass(frozen=True, slots=True)
class Conditioning:
    """Conditioning and singularity margins of one or many postures (arrays of shape S, or
    floats for one posture).

    Attributes
    ----------
    kappa_A : condition number of A (corrected eq. 8), ``max(|cot(d/2)|, |tan(d/2)|)``,
        ``d = theta4 - theta5``; 1 is isotropic, inf is a parallel singularity.
    kappa_B : condition number of B = diag(-L2 w, L1 L2 sin(theta4 - theta2),
        L1 L2 sin(theta5 - theta3)); inf on a serial singularity.
    P_on_axis : |w| / (L1 + L2), serial margin of the theta1 row (0: P on the axis AB).
    leg_A : |sin(theta4 - theta2)| (0: leg A stretched or folded).
    leg_B : |sin(theta5 - theta3)| (0: leg B stretched or folded).
    parallel : distance of theta4 - theta5 to the nearest multiple of pi, rad, in [0, pi/2]
        (0: C, D, P aligned).
    """

    kappa_A: np.ndarray
    kappa_B: np.ndarray
    P_on_axis: np.ndarray
    leg_A: np.ndarray
    leg_B: np.ndarray
    parallel: np.ndarray

    @property
    def serial(self) -> np.ndarray:
        """Shape S + (3,): the serial margins in the order of :data:`SERIAL_KINDS`."""
        return np.stack([self.P_on_axis, self.leg_A, self.leg_B], axis=-1)

    @property
    def min_serial(self) -> np.ndarray:
        """Smallest of the three serial margins."""
        return np.min(self.serial, axis=-1)

    @property
    def nearest_serial_kind(self) -> np.ndarray:
        """Name(s) from :data:`SERIAL_KINDS` of the smallest serial margin."""
        return np.asarray(SERIAL_KINDS)[np.argmin(self.serial, axis=-1)]


def conditioning(
    design: Design, q: np.ndarray, passive: np.ndarray, w: np.ndarray | float
) -> Conditioning:
    """Conditioning of postures given their joints, passive angles and in-plane w (shapes
    S + (3,), S + (2,), S), elementwise. Undefined postures (NaN inputs) give NaN."""
    q = np.asarray(q, dtype=float)
    shape = q.shape[:-1]
    out = np.empty((int(np.prod(shape)), 6))
    _kernels.conditioning_kernel(
        design.L1,
        design.L2,
        _kernels.read_only(q.reshape(-1, 3)),
        _kernels.read_only(np.asarray(passive, dtype=float).reshape(-1, 2)),
        _kernels.read_only(np.broadcast_to(np.asarray(w, dtype=float), shape).reshape(-1)),
        out,
    )
    cols = out.T.reshape((6, *shape))
    return Conditioning(*cols)


# ---------------------------------------------------------------------------- one posture
@dataclass(frozen=True, slots=True, eq=False)
class Posture:
    """One posture of the manipulator.

    Attributes
    ----------
    q : shape (3,), rad -- actuated (theta1, theta2, theta3).
    passive : shape (2,), rad -- (theta4, theta5) in (-pi, pi].
    p : shape (3,), m -- point P.
    points : mapping 'A', 'B', 'C', 'D', 'P' -> shape (3,), m.
    working_mode : '+-+'-style (s_axis, s_A, s_B); '0' where the posture sits exactly on
        that serial singularity.
    assembly_mode : '+' or '-' (sign of sin(theta5 - theta4)); '0' on the CD-stretched
        parallel singularity, where both assembly modes meet.
    """

    q: np.ndarray
    passive: np.ndarray
    p: np.ndarray
    points: Mapping[str, np.ndarray]
    working_mode: str
    assembly_mode: str

    @property
    def w(self) -> float:
        """Signed distance of P from the axis AB in the linkage plane, m."""
        t1 = self.q[0]
        return float(self.p[0] * np.cos(t1) - self.p[2] * np.sin(t1))

    def __repr__(self) -> str:
        return (
            f"Posture(q={np.round(self.q, 6).tolist()}, p={np.round(self.p, 6).tolist()}, "
            f"working_mode={self.working_mode!r}, assembly_mode={self.assembly_mode!r})"
        )


def _postures(batch: PostureBatch) -> list[Posture]:
    """The ``ok`` entries of a flat batch as Posture objects.

    The few postures of one call (/v1/fk, /v1/ik, one posture's analysis) are built in plain
    floats from one ``np.sin`` and one ``np.cos`` over every angle they need: each numpy call
    on such tiny arrays costs a microsecond or more, and the vectorised form
    (:attr:`PostureBatch.working_mode_signs`, :func:`link_points`) made some forty of them,
    most of a single-posture answer's time. The arithmetic is theirs, operation for
    operation (the same IEEE double operations on the same ``np.sin`` / ``np.cos`` values),
    so the postures are the same (``tests/core/test_kinematics.py`` checks them against the
    vectorised form). One posture in one assembly mode (:meth:`Manipulator.posture`) is
    built without a batch: :func:`_one_posture`."""
    flat = batch.ok.reshape(-1)
    q = batch.q.reshape(-1, 3)[flat]
    passive = batch.passive.reshape(-1, 2)[flat]
    p = batch.p.reshape(-1, 3)[flat]
    w = batch.w.reshape(-1)[flat].tolist()
    # per posture: sin of t1, t2, t3, t4, t4 - t2, t5 - t3, t5 - t4; cos of t1, t2, t3, t4
    angles = [
        [t1, t2, t3, t4, t4 - t2, t5 - t3, t5 - t4]
        for (t1, t2, t3), (t4, t5) in zip(q.tolist(), passive.tolist(), strict=True)
    ]
    sines = np.sin(np.array(angles, dtype=float).reshape(-1, 7)).tolist()
    cosines = np.cos(np.array([a[:4] for a in angles], dtype=float).reshape(-1, 4)).tolist()
    d = batch.design
    rows = []
    labels = []
    for s, c, wi in zip(sines, cosines, w, strict=True):
        row, working, assembly = _frame(d, s, c, wi)
        rows.append(row)
        labels.append((working, assembly))
    pts = np.array(rows, dtype=float).reshape(len(q), 5, 3)
    # Boolean indexing made fresh arrays: frozen once, each posture holds read-only row views.
    for a in (q, passive, p, pts):
        a.flags.writeable = False
    return [
        Posture(
            q[i],
            passive[i],
            p[i],
            MappingProxyType(dict(zip("ABCDP", pts[i], strict=True))),
            *labels[i],
        )
        for i in range(len(q))
    ]


def _frame(
    d: Design, sines: Sequence[float], cosines: Sequence[float], w: float
) -> tuple[list[tuple[float, float, float]], str, str]:
    """One posture's points A, B, C, D, P (m) and its working and assembly modes, from the
    sines of (t1, t2, t3, t4, t4 - t2, t5 - t3, t5 - t4), the cosines of (t1, t2, t3, t4) and
    its in-plane w: the arithmetic of :func:`_postures` and :func:`_one_posture` alike."""
    s1, s2, s3, s4, s42, s53, s54 = sines
    c1, c2, c3, c4 = cosines
    half = d.L0 / 2
    cu, cw = -half + d.L1 * c2, d.L1 * s2
    du, dw = half + d.L1 * c3, d.L1 * s3
    pu, pw = cu + d.L2 * c4, cw + d.L2 * s4
    row = [
        (0.0, -half, 0.0),
        (0.0, half, 0.0),
        (cw * c1, cu, -cw * s1),
        (dw * c1, du, -dw * s1),
        (pw * c1, pu, -pw * s1),
    ]
    working = "".join(_sign_char(x) for x in (w / d.reach, s42, s53))
    return row, working, _sign_char(s54)


def _one_posture(design: Design, q: np.ndarray, branch: np.ndarray) -> Posture | None:
    """The posture of one checked q (3,) in one branch (1,) +1/-1, or None where the loop does
    not close: :func:`forward_batch` and :func:`_postures` for one posture without the batch's
    arrays (its (1, n) outputs, the mask, the copies and the list of one). The same kernel,
    the same numpy ``arctan2``, ``sin`` and ``cos`` and the same arithmetic
    (:func:`_frame`), so the same values to the bit (``tests/core/test_kinematics.py`` checks
    it against the batch route)."""
    p, w = np.empty((1, 3)), np.empty(1)
    dy, dx, ok = np.empty((1, 2)), np.empty((1, 2)), np.empty(1, dtype=np.bool_)
    _kernels.forward_kernel(
        design.L0,
        design.L1,
        design.L2,
        _kernels.read_only(q.reshape(1, 3)),
        branch,
        ASSEMBLY_TOL,
        p,
        dy,
        dx,
        w,
        ok,
    )
    if not ok[0]:
        return None
    passive = np.arctan2(dy, dx).reshape(2)
    (t1, t2, t3), (t4, t5) = q.tolist(), passive.tolist()
    sines = np.sin(np.array([t1, t2, t3, t4, t4 - t2, t5 - t3, t5 - t4])).tolist()
    cosines = np.cos(np.array([t1, t2, t3, t4])).tolist()
    row, working, assembly = _frame(design, sines, cosines, float(w[0]))
    pts = np.array(row, dtype=float)
    q_own, p_own = q.copy(), p.reshape(3)
    for a in (q_own, passive, p_own, pts):
        a.flags.writeable = False
    points = MappingProxyType(dict(zip("ABCDP", pts, strict=True)))
    return Posture(q_own, passive, p_own, points, working, assembly)


def _sign_char(x: float) -> str:
    """The mode character of one measure: :func:`_sign` and :func:`mode_label` in one step
    (|x| <= SIGN_TOL, and NaN, is '0')."""
    return "+" if x > SIGN_TOL else "-" if x < -SIGN_TOL else "0"


class Manipulator:
    """Kinematics of one :class:`Design`, one posture at a time.

    >>> m = Manipulator(Design.singularity_free())
    >>> [post.working_mode for post in m.inverse([0.3, 0.1, 0.2])][:2]
    ['+++', '++-']
    """

    def __init__(self, design: Design | None = None) -> None:
        self._design = design if design is not None else Design.default()

    @property
    def design(self) -> Design:
        return self._design

    def __repr__(self) -> str:
        return f"Manipulator({self._design!r})"

    # -- position
    def forward(self, q: np.ndarray) -> list[Posture]:
        """Every posture with actuated joints q: 0, 1 or 2 (one per assembly mode, '+' first).

        One when CD is exactly stretched (both modes meet); none when the loop does not close
        or C = D (P is then undetermined).
        """
        q = _finite_array("q", q, 3)
        if q.ndim != 1:
            raise InputError(f"q must have shape (3,), got {q.shape}")
        batch = forward_batch(self._design, np.stack([q, q]), np.array([1.0, -1.0]))
        found = _postures(batch)
        if len(found) == 2 and found[1].assembly_mode == "0":
            found = found[:1]
        return found

    def posture(self, q: np.ndarray, assembly_mode: AssemblyMode) -> Posture:
        """The posture of q in one assembly mode; :class:`AssemblyError` if it does not exist."""
        q = _finite_array("q", q, 3)
        if q.ndim != 1:
            raise InputError(f"q must have shape (3,), got {q.shape}")
        # q is checked: one posture without forward_batch's second check of it
        found = _one_posture(self._design, q, _branch(assembly_mode, 1))
        if found is None:
            cu = -self._design.L0 / 2 + self._design.L1 * np.cos(q[1])
            du = self._design.L0 / 2 + self._design.L1 * np.cos(q[2])
            cd = float(np.hypot(du - cu, self._design.L1 * (np.sin(q[2]) - np.sin(q[1]))))
            if cd == 0.0:
                raise AssemblyError("q puts C on D: P is undetermined (parallel singularity)")
            raise AssemblyError(
                f"q does not assemble: |CD| = {cd:.6g} m > 2 L2 = {2 * self._design.L2:.6g} m"
            )
        return found

    def inverse(self, p: np.ndarray, *, theta1_on_axis: float = 0.0) -> list[Posture]:
        """Every inverse-kinematics posture of P: up to 8, one per working mode, in the order of
        :data:`WORKING_MODES`. Empty when P is out of reach. Joint limits are not applied.

        Raises
        ------
        SingularPostureError
            P = A or P = B with L1 = L2: that leg's angle is undetermined (a continuum of
            postures; with L0 = 0 this is the base point of erratum 6).
        """
        p = _finite_array("p", p, 3)
        if p.ndim != 1:
            raise InputError(f"p must have shape (3,), got {p.shape}")
        batch = inverse_batch(self._design, p, theta1_on_axis=theta1_on_axis)
        if batch.degenerate[0]:
            raise SingularPostureError(
                "P coincides with a pivot (A or B) and L1 = L2: that leg's angle is undetermined"
            )
        return _postures(batch)

    def within_limits(self, q: np.ndarray) -> bool:
        """Whether the literal joint values lie inside the design's joint limits."""
        q = np.asarray(q, dtype=float)
        d = self._design
        if q.shape == (3,):  # one posture (every answer's): plain floats, no array temporaries
            return all(
                lo <= x <= hi
                for x, lo, hi in zip(q.tolist(), d.joint_min, d.joint_max, strict=True)
            )
        return bool((q >= d.joint_min).all() and (q <= d.joint_max).all())

    # -- velocity
    def jacobians(self, posture: Posture) -> tuple[np.ndarray, np.ndarray]:
        """(A, B) of eq. (2)-(4) in our frame: ``A p_dot = B q_dot``, shapes (3, 3).

        ``A = [L2 k^T; (p - c)^T; (p - d)^T]`` with k the plane normal, and
        ``B = diag(-L2 w, L1 L2 sin(theta4 - theta2), L1 L2 sin(theta5 - theta3))``.
        """
        d = self._design
        t1 = posture.q[0]
        k = np.array([np.sin(t1), 0.0, np.cos(t1)])
        p, c, dd = posture.points["P"], posture.points["C"], posture.points["D"]
        a = np.stack([d.L2 * k, p - c, p - dd])
        t4, t5 = posture.passive
        b = np.diag(
            [
                -d.L2 * posture.w,
                d.L1 * d.L2 * np.sin(t4 - posture.q[1]),
                d.L1 * d.L2 * np.sin(t5 - posture.q[2]),
            ]
        )
        return a, b

    def cartesian_velocity(self, posture: Posture, qd: np.ndarray) -> np.ndarray:
        """Velocity of P, shape (3,), m/s, for joint rates qd (3,), rad/s.

        Raises :class:`SingularPostureError` at a parallel singularity (A not invertible).
        """
        qd = _finite_array("qd", qd, 3)
        a, b = self.jacobians(posture)
        if not self.conditioning(posture).kappa_A <= KAPPA_SOLVABLE:
            raise SingularPostureError(
                "A is singular here (C, D, P aligned): the velocity of P is undetermined"
            )
        return np.linalg.solve(a, b @ qd)

    def conditioning(self, posture: Posture) -> Conditioning:
        """kappa(A), kappa(B) and the serial and parallel margins of one posture (floats)."""
        c = conditioning(self._design, posture.q, posture.passive, np.float64(posture.w))
        # one posture's margins are floats (the class's docstring), its fields typed as arrays
        return Conditioning(**{f.name: float(getattr(c, f.name)) for f in fields(Conditioning)})  # type: ignore[arg-type]
