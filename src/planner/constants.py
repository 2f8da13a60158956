"""Named numerical tolerances (and the few names and bounds) shared by the kinematics, validity, analysis and planning code.

One place for every tolerance that decides whether the loop closes, whether a point is on a
singular set, or how close to a boundary still counts as on it. The numba kernels take them
as arguments (or in their parameter vector), never as module globals: numba's on-disk cache
would freeze a global's value at compile time.
"""

from __future__ import annotations

from typing import Literal, get_args

__all__ = [
    "ANSWER_RESERVE_S",
    "ASSEMBLY_TOL",
    "AXIS_TOL",
    "CIRCLES_MEET_TOL",
    "KAPPA_SOLVABLE",
    "MAX_POINTS",
    "MAX_SEQUENCE_TARGETS",
    "PLANNERS",
    "REACH_TOL",
    "SIGN_TOL",
    "PlannerName",
]

#: Planner names accepted by :class:`planner.planning.PlanOptions` (each works with a motion
#: validator that answers the two-state ``checkMotion`` only, the one the ompl wheel honours
#: from Python): the one list, kept here (light to import) so that the wire's
#: ``planner.name`` takes it as its type without loading the planning room.
PlannerName = Literal["rrtconnect", "rrt", "rrtstar", "prmstar", "bitstar", "aorrtc", "lbkpiece"]
#: The same names as a tuple, in that order.
PLANNERS: tuple[str, ...] = get_args(PlannerName)

#: Relative slack of the loop closure: the loop closes when 0 < |CD|^2 <= 4 L2^2 (1 +
#: ASSEMBLY_TOL) (:func:`planner._kernels.close_loop`, used by the kinematics and the validity
#: rules alike). A stretched CD computed from rounded cosines lands a few ulps (~1e-16
#: relative) either side of 2 L2; 1e-12 keeps it assembled with room to spare, while no
#: posture that misses closing by a measurable amount (1e-12 of L2 is a picometre for a
#: metre-long link) is taken as assembled.
ASSEMBLY_TOL = 1e-12
#: P is on the axis AB (w = 0, theta1 undetermined) when its distance to the axis is at most
#: AXIS_TOL (L1 + L2); with L1 = L2 a point that close to a pivot is the degenerate base
#: point (erratum 6). Relative to the reach, so that it scales with the robot; 1e-12 is four
#: orders above round-off of coordinates of order L1 + L2 and far below any real offset.
AXIS_TOL = 1e-12
#: Slack on |cos| <= 1 where the singularity loci intersect two circles (a link's end on
#: its circle and at a given distance from a second point, ``planner.analysis.loci``): two
#: circles tangent up to round-off (a cosine a few ulps beyond 1) still meet, at one point.
#: 1e-12 is some 10^4 ulps of a cosine: room for round-off, too little to let two circles
#: that miss each other by a measurable amount meet.
CIRCLES_MEET_TOL = 1e-12
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
#: Time a job keeps back from its searches before a deadline, s: for the timing and the
#: answer (:func:`planner.solve`'s deadline policy; the service's design check keeps four of
#: them for its sampling). A search that runs out then ends as ``no_path`` with time left to
#: answer, not as a missed deadline.
ANSWER_RESERVE_S = 0.25

#: Most targets of one sequence (:func:`planner.solve_sequence`; the service's
#: ``PLANNER_MAX_SEQUENCE_TARGETS`` may lower it): 64 legs of a few milliseconds each keep a
#: sequence within a request's budget, and a production cycle rarely has more than a few
#: dozen targets.
MAX_SEQUENCE_TARGETS = 64
#: Most points of the point clouds of one obstacle set (all clouds of a request or a scene
#: together): a depth camera's frame thinned to a few millimetres. Their JSON fits the
#: service's default body limit (32 MiB; about 65 bytes a point at full float precision).
MAX_POINTS = 250_000
