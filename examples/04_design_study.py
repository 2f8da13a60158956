"""A design study: compare the presets, look at one workspace, draw a figure.

Run with a service up::

    python examples/04_design_study.py [SERVER_URL] [OUTDIR]   # or PLANNER_URL, PLANNER_OUT

For each preset design the service says which parallel singularities can occur (erratum 4 of
the conventions: none when 2 L1 < L0 < 2 (L2 - L1)) and the workspace volume; for the
default robot it samples the workspace (checked here against the closed-form volume) and
returns the Cartesian section as a grid; a PNG of that section is written to OUTDIR.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

from planner.client import PlannerClient

URL = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("PLANNER_URL", "http://127.0.0.1:8000")
OUT = Path(
    sys.argv[2] if len(sys.argv) > 2 else os.environ.get("PLANNER_OUT", tempfile.gettempdir())
)


def main() -> None:
    with PlannerClient(URL, timeout=120) as client:
        print(
            f"{'design':<18} {'L0':>5} {'L1':>5} {'L2':>5} {'volume m^3':>11}  parallel singularities"
        )
        for preset in client.designs().presets:
            d = preset.design
            check = client.check_design(d, rel_se=0.05)
            kinds = ", ".join(check.parallel_singularities) or "none"
            print(
                f"{preset.name:<18} {d.L0:>5.2f} {d.L1:>5.2f} {d.L2:>5.2f} "
                f"{check.volume:>11.4f}  {kinds}"
            )
            # check: the rule of erratum 4
            assert check.singularity_free == (2 * d.L1 < d.L0 < 2 * (d.L2 - d.L1))

        ws = client.workspace(resolution=48, rel_se=0.01, joint=False)
        s = ws.sampled_volume
        print(
            f"default robot: closed-form volume {ws.volume:.4f} m^3, sampled "
            f"{s.value:.4f} +- {s.standard_error:.4f} m^3, GCI {ws.gci.value:.3f}"
        )
        # check: without joint limits in the way (full turns), the sample finds the closed form
        assert abs(s.value - ws.volume) < 4 * s.standard_error + 0.005 * ws.volume
        section = ws.cartesian_section
        cells = sum(1 for row in section.reached for mask in row if mask)
        print(f"Cartesian section: {cells} of {48 * 48} cells reached")
        assert 0 < cells < 48 * 48

        png = client.figure("cartesian_section", design=ws.design, resolution=96)
        OUT.mkdir(parents=True, exist_ok=True)
        path = OUT / "default_cartesian_section.png"
        path.write_bytes(png)
        assert png.startswith(b"\x89PNG")
        print(f"figure: {path} ({len(png)} bytes)")
    print("design study: ok")


if __name__ == "__main__":
    main()
