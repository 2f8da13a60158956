"""The validity checker: :class:`Margins`, :class:`ValidityChecker` and their helpers.

The rules and the order in which they are checked are those of :mod:`planner.validity`; the
work is done by the compiled kernels of :mod:`planner.validity._kernels`, to which the checker
hands its design, margins and modes packed once into a parameter vector.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np

from planner.design import Design
from planner.exceptions import InputError
from planner.geometry import Obstacle, PackedObstacles, pack_obstacles
from planner.kinematics import ASSEMBLY_MODES, WORKING_MODES
from planner.validity._certificate import certify_motion
from planner.validity._kernels import (
    M_CLEAR_RAW,
    M_KAPPA,
    M_REASON,
    M_SERIAL_RAW,
    N_MEASURES,
    REASONS,
    evaluate,
    evaluate_many,
    pack_params,
)
from planner.validity._path_kernels import certify_path, path_extremes
from planner.validity.margins import (
    Margins,
)
from planner.validity.reports import MotionReport, PathReport, StateReport

__all__ = [
    "DEFAULT_COARSE_STEP",
    "DIAGNOSTIC_STEP",
    "MIN_CERTIFIED_STEP",
    "ValidityChecker",
    "assembly_reason",
    "densify",
    "warm_up",
]

#: Shortest joint-space piece (max-norm, rad) that the motion certificate subdivides to; a
#: motion whose margins cannot be certified at this scale is rejected (conservative).
MIN_CERTIFIED_STEP = 1e-4
#: Default max-norm step (rad) of the first sampling of a motion, before certification
#: subdivides where margins are tight. Any value is sound; this one is tuned for speed.
DEFAULT_COARSE_STEP = 0.08

#: Max-norm step (rad) of the samples along a path whose extremes :meth:`ValidityChecker.
#: check_path` reports (diagnostics only: validity is certified, not sampled).
DIAGNOSTIC_STEP = 0.02


def densify(waypoints: np.ndarray, step: float) -> np.ndarray:
    """Waypoints (N, 3) with samples added so that no max-norm step exceeds ``step`` rad."""
    w = np.asarray(waypoints, dtype=float)
    parts = [w[:1]]
    for a, b in pairwise(w):
        n = max(1, math.ceil(float(np.max(np.abs(b - a))) / step))
        parts.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.vstack(parts)


@dataclass(frozen=True, slots=True, eq=False)
class ValidityChecker:
    """Validity of postures and motions of one design in one working and assembly mode.

    Parameters
    ----------
    design : Design
    margins : Margins
    obstacles : sequence of Sphere, Box, Capsule, Points (:mod:`planner.geometry`)
    assembly_mode : '+' | '-'
    working_mode : one of :data:`planner.kinematics.WORKING_MODES`, e.g. '+-+'
    coarse_step : float, rad
        First sampling step of :meth:`check_motion` (max-norm); speed only, never soundness.
    serial_rules : bool, default True
        False drops rules 4 and 5 (working mode and serial margin; the measures are still
        reported). For motions that end on a serial singularity (mode-change transits), whose
        mode signs the caller checks itself; every other rule stays certified.

    Examples
    --------
    >>> from planner.design import Design
    >>> chk = ValidityChecker(Design.default(), Margins(), [], "+", "+-+")
    >>> chk.check_states([[0.0, 2.0, 1.0]]).reason.tolist()
    ['valid']
    """

    design: Design
    margins: Margins = field(default_factory=Margins)
    obstacles: Sequence[Obstacle] = ()
    assembly_mode: str = "+"
    working_mode: str = "+++"
    coarse_step: float = DEFAULT_COARSE_STEP
    serial_rules: bool = True
    _warm: bool = field(default=True, repr=False)
    #: the obstacles already packed (by the checker :meth:`with_mode` derives this one from):
    #: a checker family packs its obstacles once
    _packed_from: PackedObstacles | None = field(default=None, repr=False, compare=False)
    _packed: PackedObstacles = field(init=False, repr=False)
    _prm: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.assembly_mode not in ASSEMBLY_MODES:
            raise InputError(f"assembly_mode must be '+' or '-', got {self.assembly_mode!r}")
        if self.working_mode not in WORKING_MODES:
            raise InputError(
                f"working_mode must be one of {', '.join(WORKING_MODES)}, got {self.working_mode!r}"
            )
        if not (math.isfinite(self.coarse_step) and self.coarse_step > 0):
            raise InputError(f"coarse_step must be > 0, got {self.coarse_step}")
        object.__setattr__(self, "obstacles", tuple(self.obstacles))
        packed = self._packed_from
        object.__setattr__(
            self, "_packed", pack_obstacles(self.obstacles) if packed is None else packed
        )
        object.__setattr__(self, "_packed_from", None)
        prm = pack_params(
            self.design,
            self.margins,
            self.assembly_mode,
            self.working_mode,
            serial_rules=self.serial_rules,
        )
        object.__setattr__(self, "_prm", prm)
        if self._warm:
            warm_up()

    def with_mode(self, working_mode: str, *, serial_rules: bool | None = None) -> ValidityChecker:
        """The same checker for another working mode (and optionally serial rules on/off),
        sharing this one's packed obstacle arrays (built once per family)."""
        return ValidityChecker(
            self.design,
            self.margins,
            self.obstacles,
            self.assembly_mode,
            working_mode,
            self.coarse_step,
            self.serial_rules if serial_rules is None else serial_rules,
            _packed_from=self._packed,
        )

    def with_margins(self, margins: Margins) -> ValidityChecker:
        """The same checker with other margins, sharing this one's packed obstacle arrays."""
        return ValidityChecker(
            self.design,
            margins,
            self.obstacles,
            self.assembly_mode,
            self.working_mode,
            self.coarse_step,
            self.serial_rules,
            _packed_from=self._packed,
        )

    @property
    def params(self) -> np.ndarray:
        """The design, margins and modes packed for the compiled kernels (the ``prm``
        argument of :func:`planner.validity.certify_motion`)."""
        return self._prm

    @property
    def packed(self) -> PackedObstacles:
        """The obstacles packed with their trees (:func:`planner.geometry.pack_obstacles`),
        built once and shared by every checker :meth:`with_mode` derives from this one."""
        return self._packed

    # ------------------------------------------------------------------ states
    def _measures(self, q: np.ndarray, full: bool) -> np.ndarray:
        # writable (a copy of a frozen array), as every other caller passes it: numba compiles
        # read-only arrays separately
        q = np.require(_states(q), requirements=["C", "W"])
        out = np.empty((q.shape[0], N_MEASURES))
        evaluate_many(q, self._prm, *self._packed, full, out)
        return out

    def is_valid(self, q: np.ndarray) -> np.ndarray:
        """Shape (N,) bool: which postures q (N, 3) are valid (fast path, stops at the first
        broken rule of each posture)."""
        return self._measures(q, False)[:, M_REASON] == 0.0

    def is_valid_one(self, q0: float, q1: float, q2: float) -> bool:
        """Validity of one posture given as three floats (the cheapest call, for OMPL)."""
        out = np.empty(N_MEASURES)
        evaluate(q0, q1, q2, self._prm, *self._packed, False, out)
        return bool(out[M_REASON] == 0.0)

    def check_states(self, q: np.ndarray) -> StateReport:
        """Validity, first broken rule and every measure of postures q, shape (N, 3), rad."""
        m = self._measures(q, True)
        reason = np.asarray(REASONS, dtype=object)[m[:, M_REASON].astype(int)]
        closed = m[:, M_KAPPA] > -np.inf
        nan = np.full(len(m), np.nan)
        return StateReport(
            valid=m[:, M_REASON] == 0.0,
            reason=reason,
            kappa_A=np.where(closed, m[:, M_KAPPA], nan),
            serial_margin=np.where(closed, m[:, M_SERIAL_RAW], nan),
            clearance=np.where(closed, m[:, M_CLEAR_RAW], nan),
        )

    def explain(self, q: np.ndarray) -> str:
        """A sentence naming the first rule posture q (3,) breaks and the measured value
        (``'valid'`` when none)."""
        q = _states(q)[0]
        r = self.check_states(q[None])
        reason = str(r.reason[0])
        m, d = self.margins, self.design
        if reason == "valid":
            return "valid"
        if reason == "joint_limits":
            lo, hi = np.asarray(d.joint_min), np.asarray(d.joint_max)
            i = int(np.argmax(np.maximum(lo - q, q - hi)))
            return (
                f"joint_limits: q[{i}] = {q[i]:.10g} rad lies outside [{lo[i]:.10g}, {hi[i]:.10g}]"
            )
        if reason == "assembly":
            return assembly_reason(d, q)
        if reason == "kappa_max":
            return (
                f"kappa_max: kappa_A = {r.kappa_A[0]:.10g} > margins.kappa_max = {m.kappa_max:.10g}"
            )
        if reason == "working_mode":
            return (
                f"working_mode: the posture is not in working mode {self.working_mode} "
                f"(signed serial measure {r.serial_margin[0]:.10g})"
            )
        if reason == "serial_min":
            return (
                f"serial_min: serial measure {r.serial_margin[0]:.10g} < "
                f"margins.serial_min = {m.serial_min:.10g}"
            )
        return (
            f"clearance: link clearance {r.clearance[0]:.10g} m < "
            f"margins.clearance = {m.clearance:.10g} m"
        )

    # ------------------------------------------------------------------ motions
    def check_motion(
        self, q_a: np.ndarray, q_b: np.ndarray, *, ends_known_valid: bool = False
    ) -> MotionReport:
        """Certify the straight joint-space motion ``q_a -> q_b`` (every posture on it valid).

        Algorithm: sample the motion every ``coarse_step`` (max-norm, rad) and reject it at
        the first invalid sample; then certify each piece [t_a, t_b] between samples with
        Lipschitz bounds, splitting it at its midpoint (which is checked) until certified,
        and rejecting the motion when a piece shorter than :data:`MIN_CERTIFIED_STEP` cannot be.

        Proof that no violation is skipped, whatever the step. Let g be one of three margins
        along the motion, each >= 0 exactly where its rule holds: the |CD| band margin
        (kappa rule), the signed serial margin (mode and serial rules), the clearance margin.
        If g is L-Lipschitz in t on [t_a, t_b], then for every t there
        ``g(t) >= (g(t_a) + g(t_b) - L (t_b - t_a)) / 2`` (the two cones from the ends meet
        there). A piece is accepted only when that bound is >= 0 for all three margins, so
        every posture of it keeps every margin. The constants (``_kernels.rates``), for the
        motion ``q_a + t dq``:

        * |CD|: C and D move by L1 |dtheta2| and L1 |dtheta3|: ``L = L1 (|dq2| + |dq3|)``,
          valid everywhere. Certifying it first (lower bound ``b >= 0`` on the piece) keeps
          |CD| at least ``b`` inside its band, hence |sin(theta4 - theta5)| >= s on the piece,
          s the least apex sine over that shrunk band (>= 1 / K), and the passive rates are
          at most ``r45 = L1 (|dq2| + |dq3|) / (L2 s)`` (``_kernels.rates_at`` and
          ``_kernels.sin_apex_min``);
        * serial: ``r45 + |dq2|``, ``r45 + |dq3|`` (sin of a difference of angles) and
          ``(L1 |dq2| + L2 r45) / (L1 + L2)`` (w), the largest of the three for their minimum;
        * clearance: a link point at distance r <= L1 + L2 from the axis AB moves by
          ``r |dq1|`` normal to the plane (the turn about AB) and, within the plane, by at
          most its in-plane motion v (L1 |dq2| for C, and for P that of C or D plus
          ``L2 r45``, or P's velocity from the two loop constraints
          ``(v_P - v_C) . e4 = (v_P - v_D) . e5 = 0`` at most
          ``L1 hypot(|dq2|, |dq3|) / sqrt(1 - sqrt(1 - s^2))``; a point between two link
          ends moves at most as fast as the faster end): orthogonal parts, so at most
          ``hypot(r |dq1|, v)``; on a piece, r is bounded by the largest distance from the
          axis measured at its ends plus the cones of v (``_kernels.rates_at``); a distance
          to a fixed obstacle is 1-Lipschitz in the link's points. The proximal links AC and
          BD lie within L1 of the axis and move in-plane at most as C or D, so their clearance
          has the smaller rate ``hypot(min(L1, r) |dq1|, L1 max(|dq2|, |dq3|))``: a piece is
          accepted when the distal links' own clearance margin (measured first, at no extra
          walk) passes with every link's rate and the least margin (a lower bound of the
          proximal links') passes with the proximal rate, which is tighter than the least
          margin with every link's rate wherever a proximal link is the closest.

        Joint limits hold on the whole motion when they hold at its ends (a box is convex);
        the loop closes and the assembly mode holds while |CD| stays in its kappa band
        (0 < |CD| < 2 L2); the working mode cannot flip while the signed serial margin stays
        positive. So an accepted motion has no violation of any depth; the only loss is that
        motions grazing a margin more closely than the Lipschitz bounds resolve at
        :data:`MIN_CERTIFIED_STEP` are rejected, which is the safe side. Postures exactly on
        a margin (margin 0) have no certified motion.

        Parameters
        ----------
        q_a, q_b : array, shape (3,), rad
        ends_known_valid : bool
            Skip the rule checks of the two end postures (their measures are still computed).
            Only for callers that checked them already, e.g. a planner's tree nodes.
        """
        # copies: writable, as the compiled planners pass them (one compiled signature)
        qa = np.array(_states(q_a)[0])
        qb = np.array(_states(q_b)[0])
        r, t = certify_motion(
            qa, qb, self._prm, *self._packed, self.coarse_step, MIN_CERTIFIED_STEP, ends_known_valid
        )
        return MotionReport(r == 0, REASONS[r], float(t))

    def motion_valid(self, q_a: np.ndarray, q_b: np.ndarray) -> bool:
        """:meth:`check_motion` ends included, as a bool, for float arrays of shape (3,)
        (copied: numba compiles read-only arrays separately)."""
        r = certify_motion(
            np.array(q_a, dtype=float),
            np.array(q_b, dtype=float),
            self._prm,
            *self._packed,
            self.coarse_step,
            MIN_CERTIFIED_STEP,
            False,
        )
        return r[0] == 0

    def motion_test(self) -> Callable[[np.ndarray, np.ndarray], bool]:
        """The certified motion test as a plain function ``(q_a, q_b) -> bool``, for a caller
        that runs it in a loop, e.g. OMPL's ``MotionValidator.checkMotion``.

        The same certificate as :meth:`check_motion` (ends included), with the checker's
        compiled parameters bound once: no input validation and no copies per call. Hence
        ``q_a`` and ``q_b`` must be writable, C-contiguous float64 arrays of shape (3,), rad
        (numba compiles read-only arrays separately); :meth:`motion_valid` accepts anything.
        """
        prm, packed, step = self._prm, self._packed, self.coarse_step

        def valid(q_a: np.ndarray, q_b: np.ndarray) -> bool:
            r = certify_motion(q_a, q_b, prm, *packed, step, MIN_CERTIFIED_STEP, False)
            return r[0] == 0

        return valid

    def check_path(
        self, waypoints: np.ndarray, *, sample_step: float = DIAGNOSTIC_STEP, certify: bool = True
    ) -> PathReport:
        """Certify every straight motion of a waypoint path (N, 3), rad, and measure it.

        Validity comes from :meth:`check_motion` on each consecutive pair (waypoints
        included); ``certify=False`` skips it (only for motions certified already) and
        reports the path valid. The extremes are taken over the waypoints and samples every
        ``sample_step`` rad (max-norm); they are diagnostics, not the certificate.
        """
        q = np.require(_states(waypoints), requirements=["C", "W"])  # as in _measures
        bad, reason, t = -1, 0, 1.0
        if certify and len(q) == 1:
            reason = int(self._measures(q, False)[0, M_REASON])
            bad = 0 if reason else -1
        elif certify:
            reasons = np.zeros(len(q) - 1, dtype=np.int64)
            ts = np.zeros(len(q) - 1)
            bad = int(
                certify_path(
                    q, self._prm, *self._packed, self.coarse_step, MIN_CERTIFIED_STEP, reasons, ts
                )
            )
            if bad >= 0:
                reason, t = int(reasons[bad]), float(ts[bad])
        ext = np.empty(3)
        path_extremes(q, float(sample_step), self._prm, *self._packed, ext)
        return PathReport(
            valid=bad < 0,
            bad_motion=bad,
            reason=REASONS[reason],
            t=t,
            min_clearance=float(ext[0]),
            max_kappa_A=float(ext[1]),
            min_serial_margin=float(ext[2]),
            length=_path_length(q),
        )


def _path_length(q: np.ndarray) -> float:
    """Sum of the Euclidean lengths of a path's motions, q (N, 3) rad: ``np.linalg.norm``'s
    arithmetic (the squares summed along each row, their roots summed) without its
    per-call dispatch, the same number to the bit."""
    d = q[1:] - q[:-1]
    return float(np.sqrt((d * d).sum(axis=1)).sum())


_WARM = False


def warm_up() -> None:
    """Load (or compile) every numba kernel once, so that the first plan's budget is spent on
    planning. Called by the first :class:`ValidityChecker`; about 0.3 s from numba's cache."""
    global _WARM
    if _WARM:
        return
    _WARM = True
    chk = ValidityChecker(Design(0.5, 0.2, 0.6), Margins(), (), "+", "+-+", _warm=False)
    q = np.array([[0.0, 2.0, 1.0], [0.1, 2.1, 1.1]])
    chk.check_states(q)
    chk.is_valid(q)
    chk.is_valid_one(0.0, 2.0, 1.0)
    chk.check_motion(q[0], q[1])
    chk.motion_valid(q[0], q[1])
    chk.check_path(q)


def assembly_reason(design: Design, q: np.ndarray) -> str:
    """Why posture q (3,) does not assemble, with the measured |CD| (the loop closes only for
    0 < |CD| <= 2 L2)."""
    q = np.asarray(q, dtype=float)
    c = np.array([-design.L0 / 2 + design.L1 * np.cos(q[1]), design.L1 * np.sin(q[1])])
    d = np.array([design.L0 / 2 + design.L1 * np.cos(q[2]), design.L1 * np.sin(q[2])])
    cd = float(np.hypot(*(d - c)))
    if cd == 0.0:
        return "assembly: C = D (|CD| = 0 m), P is undetermined"
    return f"assembly: the loop does not close, |CD| = {cd:.10g} m > 2 L2 = {2 * design.L2:.10g} m"


def _states(q: object) -> np.ndarray:
    try:
        arr = np.asarray(q, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"q must be numbers, got {q!r}") from exc
    arr = np.atleast_2d(arr)
    if arr.ndim != 2 or arr.shape[1] != 3:
        shape = np.asarray(q, dtype=float).shape  # as given, before atleast_2d
        raise InputError(f"q must have shape (3,) or (N, 3), got {shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError("q must be finite (no NaN or infinity)")
    return np.ascontiguousarray(arr)
