"""Write three solved /v1/plan request/response pairs (free space, obstacles, a working-mode
change) into a directory, as NAME.request.json and NAME.response.json, for an external plan
checker to re-check (``.ci/run`` does so when one is available beside the repository).

The plans come from the in-process service (FastAPI's TestClient, one worker process), with
the design and margins written out in full so that a checker needs no defaults.

    .venv/bin/python .ci/write_plans.py OUT_DIR
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: How long the service may take to warm its worker, s (as tests/conftest.py).
READY_TIMEOUT_S = 300.0

DESIGN = {
    "L0": 0.5,
    "L1": 0.2,
    "L2": 0.6,
    "link_radius": 0.02,
    "joint_min": [-3.141592653589793] * 3,
    "joint_max": [3.141592653589793] * 3,
}
MARGINS = {"kappa_max": 10.0, "serial_min": 0.05, "clearance": 0.01}
START = {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"}
COMMON = {
    "design": DESIGN,
    "start": START,
    "margins": MARGINS,
    "planner": {"seed": 1, "time_budget_s": 5.0},
}
SCENES = {
    "free_space": {"goal": {"q": [0.5, 2.2, 1.1], "assembly_mode": "+"}},
    "obstacles": {
        "goal": {"q": [1.2, 2.3, 1.3], "assembly_mode": "+"},
        "obstacles": [
            {"type": "sphere", "center": [0.549, -0.025, -0.376], "radius": 0.1},
            {
                "type": "box",
                "center": [0.0, 0.0, -0.95],
                "size": [2.0, 2.0, 0.1],
                "quaternion": [1.0, 0.0, 0.0, 0.0],
            },
        ],
    },
    "mode_change": {  # +-+ -> +++ through one leg-A transit
        "goal": {
            "q": [2.1628673977784247, -0.6760414321727777, -0.0438376661931823],
            "assembly_mode": "+",
        }
    },
}


def main(out: Path) -> int:
    """Plan every scene and write its pair; 1 if a scene is not solved."""
    sys.path.insert(0, str(ROOT))
    from fastapi.testclient import TestClient

    from planner_api.app import create_app
    from planner_api.settings import Settings

    out.mkdir(parents=True, exist_ok=True)
    # localhost: a keyless service answers the loopback names only (PLANNER_ALLOWED_HOSTS)
    with TestClient(create_app(Settings(workers=1)), base_url="http://localhost") as client:
        # as a load balancer would: no request before the worker is warm (a first warm-up
        # on a slow machine can take longer than one request's budget)
        end = time.monotonic() + READY_TIMEOUT_S
        while client.get("/v1/ready").status_code != 200:
            if time.monotonic() > end:
                sys.stderr.write(f"write_plans: not ready after {READY_TIMEOUT_S:g} s\n")
                return 1
            time.sleep(0.2)
        for name, scene in SCENES.items():
            body = {**COMMON, **scene}
            answer = client.post("/v1/plan", json=body).json()
            if answer.get("status") != "solved":
                status, message = answer.get("status"), answer.get("message")
                sys.stderr.write(f"write_plans: {name} is {status}: {message}\n")
                return 1
            (out / f"{name}.request.json").write_text(json.dumps(body))
            (out / f"{name}.response.json").write_text(json.dumps(answer))
    return 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1])))
