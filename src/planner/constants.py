"""Named numerical tolerances shared by the kinematics, analysis and planning code."""

from __future__ import annotations

__all__ = ["ASSEMBLY_TOL", "KAPPA_SOLVABLE", "REACH_TOL", "SIGN_TOL"]

#: Relative slack on |CD| <= 2 L2 when closing the loop (round-off of a stretched CD).
ASSEMBLY_TOL = 1e-12
#: Slack on |cos| <= 1 in inverse kinematics: a point this close outside a leg's reach is
#: taken as on its boundary (stretched or folded), not unreachable.
REACH_TOL = 1e-9
#: A dimensionless sign measure (sin of a joint difference, w / (L1 + L2)) at most this large
#: in magnitude is written '0': the posture is on that singularity. Not smaller, because the
#: measures grow like the square root of a distance near a boundary: a point 1e-16 m inside a
#: leg's reach (one rounding) already gives sin(theta4 - theta2) ~ 1e-8.
SIGN_TOL = 1e-7
#: Largest kappa(A) at which A is still inverted (a Cartesian velocity is computed); beyond,
#: the posture is treated as parallel-singular.
KAPPA_SOLVABLE = 1e7
