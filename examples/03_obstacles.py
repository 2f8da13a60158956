"""An obstacle scene: a ball in the way of the straight motion and a floor plate.

Run with a service up::

    python examples/03_obstacles.py [SERVER_URL]      # or set PLANNER_URL

The planner keeps every link capsule (AC, BD, CP, DP, radius ``link_radius``) at least
``margins.clearance`` from every obstacle. The script checks this itself on the timed
trajectory: it asks the service for the joint centres of sampled postures and measures the
distance from each link segment to the ball.
"""

from __future__ import annotations

import os
import sys

import numpy as np

from planner.client import PlannerClient

URL = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("PLANNER_URL", "http://127.0.0.1:8000")

START = {"q": [0.2, 1.0, 2.0], "assembly_mode": "+"}
GOAL = {"q": [1.0, 1.0, 2.0], "assembly_mode": "+"}
BALL = {"type": "sphere", "center": [0.623, -0.013, -0.426], "radius": 0.08}  # on P's way
FLOOR = {
    "type": "box",
    "center": [0.0, 0.0, -0.75],
    "size": [2.0, 2.0, 0.1],
    "quaternion": [1.0, 0.0, 0.0, 0.0],
}
CLEARANCE = 0.01  # m
LINK_RADIUS = 0.02  # m, the default robot's


def segment_distance(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
    """Distance from point c to the segment a-b."""
    t = np.clip(np.dot(c - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
    return float(np.linalg.norm(a + t * (b - a) - c))


def main() -> None:
    with PlannerClient(URL, timeout=60) as client:
        result = client.plan(
            start=START,
            goal=GOAL,
            obstacles=[BALL, FLOOR],
            margins={"clearance": CLEARANCE},
            planner={"seed": 1, "time_budget_s": 5},
        )
        print(f"status: {result.status} ({result.message})")
        if result.status != "solved":
            raise SystemExit(1)
        print(f"waypoints: {len(result.path.waypoints)} (a straight move would hit the ball)")
        print(f"min clearance reported: {result.diagnostics.min_clearance:.4f} m")
        print(f"duration: {result.trajectory.duration:.3f} s")

        # checks: the reported clearance and our own distance from the links to the ball
        assert result.diagnostics.min_clearance >= CLEARANCE - 1e-9
        centre = np.array(BALL["center"])
        samples = np.linspace(0, len(result.trajectory.t) - 1, 30).astype(int)
        worst = np.inf
        for k in samples:
            q = result.trajectory.q[k]
            pts = {n: np.array(v) for n, v in client.fk(q, "+").postures[0].points.items()}
            for a, b in (("A", "C"), ("C", "P"), ("B", "D"), ("D", "P")):
                gap = segment_distance(pts[a], pts[b], centre) - BALL["radius"] - LINK_RADIUS
                worst = min(worst, gap)
        print(f"check: smallest link-to-ball gap on 30 trajectory samples: {worst:.4f} m")
        assert worst >= CLEARANCE - 1e-6, worst
    print("obstacles: ok")


if __name__ == "__main__":
    main()
