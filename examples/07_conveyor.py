"""Picking from a belt: ten parts at 0.5 m/s, each met on the move and placed at a bin.

Start a service first (``planner serve``), then::

    python examples/07_conveyor.py [SERVER_URL] [OUT_DIR]      # or set PLANNER_URL

The belt runs along x at 0.5 m/s; ten parts enter at x = -0.75 m, 0.6 to 1.2 m apart. For
each part the robot, resting at the bin, asks ``POST /v1/sequence`` for one pick: a moving
target (the part: ``p`` at time ``t0`` and its ``velocity``) held for a ``dwell`` of 0.1 s,
then the bin (a stop). The service chooses where and when to meet the part (and in which
working mode); the answer's first leg says when (``meet_time``) and where (``meet_point``).
A part the robot can no longer meet comes back ``unreachable`` and is missed. The script
checks, from the samples alone, that the tool point is on the part over the whole dwell, and
prints the picks per minute.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from planner.client import PlannerClient

URL = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("PLANNER_URL", "http://127.0.0.1:8000")
OUT = Path(sys.argv[2]) if len(sys.argv) > 2 else Path(tempfile.mkdtemp())

BIN = [-0.2, 0.25, -0.45]  # m: the place point
HOME = {"q": [1.98902066, 1.68682059, -0.4043776], "assembly_mode": "+"}  # P at the bin
ENTRY = np.array([-0.75, 0.0, -0.45])  # m: where the parts enter the belt
SPEED, DWELL = 0.5, 0.1  # m/s, s


def main() -> None:
    gaps = np.random.default_rng(7).uniform(0.6, 1.2, 10) / SPEED
    arrivals = np.cumsum(gaps) - gaps[0]  # s: when each part is at ENTRY
    with PlannerClient(URL, timeout=120) as client:
        start, clock, picks, missed = HOME, 0.0, 0, 0
        for k, a in enumerate(arrivals):
            part = {"p": ENTRY.tolist(), "velocity": [SPEED, 0, 0], "t0": float(a - clock)}
            r = client.sequence(
                start=start,
                targets=[{"goal": part, "dwell": DWELL}, {"goal": {"p": BIN}}],
                timing={"sample_rate_hz": 500},
            )
            if r.status != "solved":
                print(f"part {k}: missed ({r.status}: {r.message[:120]}...)")
                missed += 1
                continue
            leg = r.legs[0]
            t, p = np.asarray(r.trajectory.t), np.asarray(r.trajectory.p)
            span = (t >= leg.meet_time) & (t <= leg.meet_time + DWELL)
            on_part = ENTRY + np.outer(t[span] - part["t0"], [SPEED, 0, 0])
            err = float(np.max(np.linalg.norm(p[span] - on_part, axis=1)))
            assert err < 1e-4, f"P leaves the part by {err * 1e3:.3f} mm"
            print(
                f"part {k}: met at {clock + leg.meet_time:.3f} s at "
                f"{np.round(leg.meet_point, 3).tolist()} in {leg.working_mode}, "
                f"at rest at the bin at {clock + r.cycle_time:.3f} s; P on the part within "
                f"{err * 1e3:.2g} mm"
            )
            picks += 1
            clock += r.cycle_time
            start = {"q": r.trajectory.q[-1], "assembly_mode": "+"}
        print(f"check: P on the part over every dwell; {picks} picked, {missed} missed")
        print(f"picks per minute: {60.0 * picks / clock:.1f}")
        print("conveyor: ok")


if __name__ == "__main__":
    main()
