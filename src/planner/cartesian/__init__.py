"""Straight tool paths: P along a polyline within a tolerance, certified chord by chord, and
timed (:func:`planner.cartesian.plan.plan_cartesian`). Its own room beside
:mod:`planner.planning` (the joint-space searches with OMPL, which this family never calls):
it walks the inverse kinematics of one working mode along the line
(:mod:`~planner.cartesian.walk`), bounds the deviation of each joint-space chord
(:mod:`~planner.cartesian.chords`), says where and why a line stops
(:mod:`~planner.cartesian.inspection`), and answers a
:class:`~planner.cartesian.result.CartesianResult`.
"""

from planner.cartesian.plan import StraightMotion, plan_cartesian
from planner.cartesian.result import CartesianDiagnostics, CartesianResult, PathEvent, StopPoint

__all__ = [
    "CartesianDiagnostics",
    "CartesianResult",
    "PathEvent",
    "StopPoint",
    "StraightMotion",
    "plan_cartesian",
]
