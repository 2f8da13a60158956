"""Validity of postures and of straight joint-space motions inside one working mode.

A posture q is *valid* for a segment in working mode ``(s_axis, s_A, s_B)`` and assembly mode
``s`` when every rule holds (checked in this order; the first broken one is the *reason*):

1. ``joint_limits``: ``joint_min <= q <= joint_max`` (literal values, never wrapped);
2. ``assembly``: the loop closes (0 < |CD| <= 2 L2); forward kinematics then takes the
   segment's assembly mode;
3. ``kappa_max``: kappa(A) <= ``margins.kappa_max`` (away from parallel singularities);
4. ``working_mode``: every signed serial measure has the segment's sign;
5. ``serial_min``: |w| / (L1 + L2), |sin(theta4 - theta2)| and |sin(theta5 - theta3)| are all
   >= ``margins.serial_min``;
6. ``clearance``: every link capsule (AC, BD, CP, DP, radius ``link_radius``) is at least
   ``margins.clearance`` from every obstacle.

Motions are the straight joint-space segments between two postures. :meth:`ValidityChecker.
check_motion` certifies a whole segment, it does not sample it at a fixed step; the argument
is in its docstring. Everything runs in compiled numba kernels over many states at once.

The package has six modules, one job each: :mod:`planner.validity.margins` (``Margins``
and their defaults), :mod:`planner.validity.checker` (``ValidityChecker`` and its helpers:
what callers use), :mod:`planner.validity.reports` (the records it returns), and three of
compiled kernels, private: :mod:`planner.validity._kernels` (one posture's measures and their
rates), :mod:`planner.validity._certificate` (a motion's certificate) and
:mod:`planner.validity._path_kernels` (a whole path's certificate and diagnostics).
Every public name is importable from ``planner.validity`` itself; the certificate's
compiled kernel is public too, ``certify_motion`` (the certificate of
:meth:`ValidityChecker.check_motion` over a checker's ``_prm`` and ``packed`` arrays), for
compiled callers that run it in their own loops (:mod:`planner.planning.compiled_rrt`), with
its variants for such loops: ``certify_between`` (the ends' measures given,
``measure_posture``, ``N_MEASURES`` per posture), ``certify_extension`` (a search's
extension) and ``blocked_near`` (a motion refused at one posture near where another broke a
rule).

Why kappa(A) is checked through |CD|: the apex angle of the isosceles triangle C-P-D is
``gamma = |theta4 - theta5|`` (mod pi) and ``|CD| = 2 L2 sin(gamma / 2)``, so (corrected eq. 8)
``kappa(A) = max(cot(gamma/2), tan(gamma/2)) <= K`` exactly when
``|CD| / (2 L2)`` lies in ``[1 / sqrt(1 + K^2), K / sqrt(1 + K^2)]``. |CD| depends on theta2 and
theta3 only and moves by at most ``L1 (|dtheta2| + |dtheta3|)``, a global bound.
"""

from planner.validity._certificate import (
    blocked_near,
    certify_between,
    certify_extension,
    certify_motion,
    measure_posture,
)
from planner.validity._kernels import N_MEASURES, REASONS
from planner.validity.checker import (
    DEFAULT_COARSE_STEP,
    DIAGNOSTIC_STEP,
    MIN_CERTIFIED_STEP,
    ValidityChecker,
    assembly_reason,
    densify,
    warm_up,
)
from planner.validity.margins import (
    DEFAULT_CLEARANCE,
    DEFAULT_KAPPA_MAX,
    DEFAULT_SERIAL_MIN,
    Margins,
)
from planner.validity.reports import MotionReport, PathReport, StateReport

__all__ = [
    "DEFAULT_CLEARANCE",
    "DEFAULT_COARSE_STEP",
    "DEFAULT_KAPPA_MAX",
    "DEFAULT_SERIAL_MIN",
    "DIAGNOSTIC_STEP",
    "MIN_CERTIFIED_STEP",
    "N_MEASURES",
    "REASONS",
    "Margins",
    "MotionReport",
    "PathReport",
    "StateReport",
    "ValidityChecker",
    "assembly_reason",
    "blocked_near",
    "certify_between",
    "certify_extension",
    "certify_motion",
    "densify",
    "measure_posture",
    "warm_up",
]
