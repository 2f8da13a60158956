"""A pick-and-place cycle: up, across, down and back, as one trajectory, twice.

Start a service first (``planner serve``), then::

    python examples/06_pick_and_place.py [SERVER_URL] [OUT_DIR]      # or set PLANNER_URL

Two requests to ``POST /v1/sequence`` for the same cycle (the start is the pick point;
lift 50 mm, move 300 mm across, lower 50 mm onto the place point, and back to the start):
first at rest at every target, then passing through the two top corners within 0.05 rad.
The working modes of the Cartesian targets are chosen for the shortest cycle (objective
"time", the default); the message names them and the runner-up. The script checks, from the
samples alone, that the times strictly increase, that the trajectory is at rest at each
stop and moving at each corner passed through, and that passing through the corners made
the cycle shorter; it writes the faster trajectory as CSV.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from planner.client import PlannerClient, write_csv

URL = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("PLANNER_URL", "http://127.0.0.1:8000")
OUT = Path(sys.argv[2]) if len(sys.argv) > 2 else Path(tempfile.mkdtemp())

START = {"q": [0.90975, 2.76741, 1.04726], "assembly_mode": "+"}  # rad: the pick posture
PICK = np.array([0.35, -0.1, -0.45])  # m: P at START (checked below with fk)
LIFT, ACROSS = 0.05, 0.3  # m


def at(dy: float, dz: float) -> list[float]:
    """A point offset from the pick point, m."""
    return (PICK + np.array([0.0, dy, dz])).tolist()


def cycle(corners_stop: bool) -> list[dict]:
    corner = {"stop": corners_stop, "blend": 0.0 if corners_stop else 0.05}
    return [
        {"goal": {"p": at(0, LIFT)}, **corner},
        {"goal": {"p": at(ACROSS, LIFT)}, **corner},
        {"goal": {"p": at(ACROSS, 0)}},  # the place point: a stop
    ]


def main() -> None:
    with PlannerClient(URL, timeout=120) as client:
        p = np.asarray(client.fk(START["q"], "+").postures[0].p)
        print(f"start: P = {p.round(4).tolist()}")
        assert np.linalg.norm(p - PICK) < 1e-4, "the start is the pick point"
        times = {}
        for stop in (True, False):
            r = client.sequence(
                start=START, targets=cycle(stop), cycle=True, timing={"sample_rate_hz": 200}
            )
            label = "stops at every target" if stop else "passing the top corners"
            print(f"{label}: status: {r.status}, cycle time {r.cycle_time:.3f} s")
            print(f"  {r.message}")
            if r.status != "solved":
                raise SystemExit(1)
            t, qd = np.asarray(r.trajectory.t), np.asarray(r.trajectory.qd)
            assert np.all(np.diff(t) > 0), "times must strictly increase"
            for leg in r.legs:
                i = int(np.argmin(np.abs(t - leg.end_time)))
                speed = float(np.linalg.norm(qd[i]))
                passing = not stop and leg.target_index in (0, 1)
                print(
                    f"  target {leg.target_index}: {leg.working_mode}, "
                    f"t {leg.start_time:.3f}..{leg.end_time:.3f} s, speed {speed:.3f} rad/s"
                )
                assert (speed > 0.05) if passing else (speed <= 1e-9), "rest or speed"
            times[stop] = r.cycle_time
            if not stop:
                write_csv(r.trajectory, OUT / "pick_and_place.csv")
        gain = 1 - times[False] / times[True]
        print(f"check: passing the corners saves {100 * gain:.1f} % of the cycle")
        assert gain > 0
        print(f"trajectory CSV: {OUT / 'pick_and_place.csv'}")
        print("pick and place: ok")


if __name__ == "__main__":
    main()
