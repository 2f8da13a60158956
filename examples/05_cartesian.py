"""Straight tool paths: P moves on straight lines, and stops where a rule would break.

Start a service first (``planner serve``), then::

    python examples/05_cartesian.py [SERVER_URL] [OUT_DIR]      # or set PLANNER_URL

Two requests to ``POST /v1/cartesian``. The first moves P from the start's position through
two points at 0.25 m/s at half the joint speed limits, timed by toppra, and gets the
trajectory in a controller's shape (``timing.format = "points"``); the script checks that P
stays within the 1 mm path tolerance of the polyline at every sample and writes the
trajectory as CSV. The second line runs out of the working mode's workspace: the answer is
``no_path`` with the share of the line achieved and the rule that stopped it.
"""

from __future__ import annotations

import os
import sys
import tempfile
from itertools import pairwise
from pathlib import Path

import numpy as np

from planner.client import PlannerClient, to_arrays, write_csv

URL = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("PLANNER_URL", "http://127.0.0.1:8000")
OUT = Path(sys.argv[2]) if len(sys.argv) > 2 else Path(tempfile.mkdtemp())

START = {"q": [-0.2187, 2.8609, 0.2807], "assembly_mode": "+"}  # rad, and the assembly mode
WAYPOINTS = [[0.45, 0.3, 0.1], [0.45, 0.2, 0.0]]  # m: P goes through these in order
TOLERANCE = 1e-3  # m: the largest distance of P from the polyline


def distance_to_polyline(vertices: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance (m) of each point (N, 3) to the polyline through ``vertices`` (K, 3)."""
    best = np.full(len(points), np.inf)
    for a, b in pairwise(vertices):
        ab = b - a
        t = np.clip((points - a) @ ab / max(float(ab @ ab), 1e-300), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(points - (a + t[:, None] * ab), axis=1))
    return best


def main() -> None:
    with PlannerClient(URL, timeout=60) as client:
        result = client.cartesian(
            start=START,
            waypoints=WAYPOINTS,
            path_tolerance=TOLERANCE,
            timing={"method": "toppra", "format": "points"},
            limits={"cartesian_speed": 0.25, "velocity_scaling": 0.5},
        )
        print(f"status: {result.status}, fraction {result.fraction:.3f} ({result.message})")
        if result.status != "solved":
            raise SystemExit(1)
        traj = result.trajectory
        print(
            f"duration: {traj.duration:.3f} s, {len(traj.points)} points of joints "
            f"{', '.join(traj.joint_names)}"
        )

        # check: P stays within the tolerance of the polyline, by the service's kinematics of
        # each sample (POST /v1/fk) against the straight segments
        p0 = client.fk(START["q"], START["assembly_mode"]).postures[0].p
        vertices = np.array([p0, *WAYPOINTS])
        q = np.array([pt.positions for pt in traj.points[:: max(1, len(traj.points) // 40)]])
        p = np.array([client.fk(qi, START["assembly_mode"]).postures[0].p for qi in q])
        worst = float(np.max(distance_to_polyline(vertices, p)))
        assert worst <= TOLERANCE, worst
        print(f"check: P within {worst * 1e3:.3f} mm of the polyline (tolerance 1 mm)")

        csv = OUT / "cartesian.csv"
        write_csv(traj, csv)
        assert len(csv.read_text().splitlines()) == len(to_arrays(traj).t) + 2  # units, header
        print(f"trajectory CSV: {csv}")

        # a line out of the workspace: P cannot be farther than L1 + L2 from A and B
        short = client.cartesian(start=START, waypoints=[[1.2, 0.3, 0.1]])
        print(f"status: {short.status}, fraction {short.fraction:.3f}")
        print(f"stopped: {short.message}")
        assert short.status == "no_path" and 0.0 < short.fraction < 1.0
    print("cartesian: ok")


if __name__ == "__main__":
    main()
