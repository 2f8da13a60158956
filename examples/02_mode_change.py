"""A plan whose goal is in another working mode: the path passes a serial singularity.

The robot reaches most points P in several working modes (the sign triple (s_axis, s_A,
s_B)). Asking for a goal in another mode than the start's makes the planner cross a serial
singularity (a *transit*: P on the axis AB, or a leg stretched or folded), where exactly one
sign flips. Run with a service up::

    python examples/02_mode_change.py [SERVER_URL]      # or set PLANNER_URL

The script prints the segments and transits and checks them: the first segment is in the
start's mode, the last in the goal's, consecutive segments share their transit waypoint and
differ in exactly the sign the transit names.
"""

from __future__ import annotations

import os
import sys

from planner.client import PlannerClient

URL = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("PLANNER_URL", "http://127.0.0.1:8000")

START = {"q": [0.2, 1.0, 2.0], "assembly_mode": "+"}  # working mode ++-
GOAL = {"p": [0.449, 0.042, -0.566], "working_mode": "+--"}  # leg A's sign flips
SIGN_INDEX = {"axis": 0, "A": 1, "B": 2}


def main() -> None:
    with PlannerClient(URL, timeout=60) as client:
        start_mode = client.fk(START["q"], START["assembly_mode"]).postures[0].working_mode
        print(f"start in working mode {start_mode}, goal asked in {GOAL['working_mode']}")
        result = client.plan(start=START, goal=GOAL, planner={"seed": 1, "time_budget_s": 5})
        print(f"status: {result.status} ({result.message})")
        if result.status != "solved":
            raise SystemExit(1)
        path = result.path
        for seg in path.segments:
            print(
                f"  segment {seg.working_mode}/{seg.assembly_mode}: "
                f"waypoints {seg.start_index}..{seg.end_index}"
            )
        for transit in path.transits:
            print(
                f"  transit at waypoint {transit.index}: {transit.kind} (flips {transit.flipped})"
            )
        if result.trajectory is not None:
            print(f"duration: {result.trajectory.duration:.3f} s")

        # checks
        assert path.segments[0].working_mode == start_mode
        assert path.segments[-1].working_mode == GOAL["working_mode"]
        assert len(path.transits) == len(path.segments) - 1 >= 1
        for before, after, transit in zip(
            path.segments, path.segments[1:], path.transits, strict=False
        ):
            assert before.end_index == after.start_index == transit.index
            changed = [i for i in range(3) if before.working_mode[i] != after.working_mode[i]]
            assert changed == [SIGN_INDEX[transit.flipped]], (before, after, transit)
    print("mode change: ok")


if __name__ == "__main__":
    main()
