"""A first plan: the default robot moves P from a start posture to a Cartesian goal.

Start a service first (``planner serve``), then::

    python examples/01_first_plan.py [SERVER_URL]      # or set PLANNER_URL

The client validates the request locally, the service plans a valid joint path (joint limits,
kappa(A) and serial margins) and times it with toppra. The script prints the outcome and
checks it: the path starts at the start posture and P ends on the goal.
"""

from __future__ import annotations

import os
import sys

import numpy as np

from planner.client import PlannerClient

URL = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("PLANNER_URL", "http://127.0.0.1:8000")

START = {"q": [0.2, 1.0, 2.0], "assembly_mode": "+"}  # rad, and the assembly mode
GOAL = {"p": [0.408, -0.013, -0.635], "working_mode": "any"}  # m: where P should go


def main() -> None:
    with PlannerClient(URL, timeout=60) as client:
        result = client.plan(start=START, goal=GOAL, planner={"seed": 1})
        print(f"status: {result.status} ({result.message})")
        if result.status != "solved":
            raise SystemExit(1)
        path, trajectory = result.path, result.trajectory
        print(f"waypoints: {len(path.waypoints)}, working mode: {path.segments[0].working_mode}")
        print(f"duration: {trajectory.duration:.3f} s, {len(trajectory.t)} samples at 100 Hz")
        print(
            f"smallest serial margin: {result.diagnostics.min_serial_margin:.3f}, "
            f"largest kappa(A): {result.diagnostics.max_kappa_A:.2f}"
        )

        # checks: the path leaves from the start and P arrives on the goal
        assert np.allclose(path.waypoints[0], START["q"], atol=1e-9)
        end = client.fk(path.waypoints[-1], path.segments[-1].assembly_mode).postures[0]
        error = np.linalg.norm(np.subtract(end.p, GOAL["p"]))
        assert error < 1e-6, error
        assert np.allclose(trajectory.q[-1], path.waypoints[-1], atol=1e-9)
        print(f"check: P ends {error:.1e} m from the goal")
    print("first plan: ok")


if __name__ == "__main__":
    main()
