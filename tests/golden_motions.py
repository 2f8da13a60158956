"""The seeded motions whose answers a refactor must not change: plans (joint and Cartesian
goals, obstacles, a working-mode change, the goal options, Ruckig, torque limits), sequences
(stops, corners passed, the mode choice for time) and straight tool paths, each a wire request
run through the service's own job functions in this process (no HTTP, no pool).

``python tests/golden_motions.py --record`` writes ``golden_motions.json`` beside this file from the
code as it stands; ``tests/test_golden_motions.py`` replays every request and compares
the answer with the record (statuses, messages, modes and counts exactly; numbers to 1e-6 of
their own scale, what a change of machine may move in the last digits, never a change of
answer). The search budget is generous (30 s): a seeded search that ends within its budget
gives the same path whatever the budget, and a slow machine must not cut one short. Timings
of the computation itself (``diagnostics`` times) are left out.

Re-record only for a change of answer that is meant, and say so in the commit.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

OUT = sys.stdout
HERE = Path(__file__).resolve().parent
RECORD = HERE / "golden_motions.json"

DESIGN = {"L0": 0.5, "L1": 0.2, "L2": 0.6, "link_radius": 0.02}
MARGINS = {"kappa_max": 10.0, "serial_min": 0.05, "clearance": 0.01}
START = {"q": [0.0, 2.0, 1.0], "assembly_mode": "+"}
PLANNER = {"seed": 1, "time_budget_s": 30.0}
BASE = {"design": DESIGN, "start": START, "margins": MARGINS, "planner": PLANNER}
OBSTACLES = [
    {"type": "sphere", "center": [0.549, -0.025, -0.376], "radius": 0.1},
    {"type": "box", "center": [0.0, 0.0, -0.95], "size": [2.0, 2.0, 0.1]},
]
PICK_START = {"q": [0.90975, 2.76741, 1.04726], "assembly_mode": "+"}
PICK = [0.35, -0.1, -0.45]


def at_posture(q: list[float], assembly_mode: str = "+") -> list[float]:
    """P of the joint posture ``q`` of the golden design, m (a Cartesian target there)."""
    import numpy as np

    from planner.design import Design
    from planner.kinematics import forward_batch

    design = Design(**DESIGN)
    return forward_batch(design, np.asarray(q, dtype=float), assembly_mode).p[0].tolist()


def _at(dy: float, dz: float) -> list[float]:
    return [PICK[0], PICK[1] + dy, PICK[2] + dz]


def _cycle(stop: bool) -> list[dict[str, Any]]:
    corner = {"stop": stop, "blend": 0.0 if stop else 0.05}
    return [
        {"goal": {"p": _at(0, 0.05)}, **corner},
        {"goal": {"p": _at(0.3, 0.05)}, **corner},
        {"goal": {"p": _at(0.3, 0)}},
    ]


#: name -> (job kind, request body)
CASES: dict[str, tuple[str, dict[str, Any]]] = {
    "plan_free": ("plan", {**BASE, "goal": {"q": [0.5, 2.2, 1.1], "assembly_mode": "+"}}),
    "plan_obstacles": (
        "plan",
        {**BASE, "goal": {"q": [1.2, 2.3, 1.3], "assembly_mode": "+"}, "obstacles": OBSTACLES},
    ),
    "plan_mode_change": (
        "plan",
        {
            **BASE,
            "goal": {
                "q": [2.1628673977784247, -0.6760414321727777, -0.0438376661931823],
                "assembly_mode": "+",
            },
        },
    ),
    "plan_cartesian_any": (
        "plan",
        {**BASE, "goal": {"p": [0.3, 0.2, -0.5], "working_mode": "any"}},
    ),
    "plan_prefer_tolerance": (
        "plan",
        {
            **BASE,
            "goal": {
                "p": [0.3, -0.1, -0.5],
                "working_mode": "any",
                "prefer": "best_conditioned",
                "tolerance": 0.01,
            },
        },
    ),
    "plan_ruckig": (
        "plan",
        {
            **BASE,
            "goal": {"q": [0.5, 2.2, 1.1], "assembly_mode": "+"},
            "timing": {"method": "ruckig", "sample_rate_hz": 200},
        },
    ),
    "plan_torque": (
        "plan",
        {
            **BASE,
            "goal": {"q": [0.6, 2.3, 1.2], "assembly_mode": "+"},
            "limits": {"torque": [40.0, 40.0, 40.0]},
        },
    ),
    "sequence_stops": (
        "sequence",
        {
            "start": PICK_START,
            "targets": _cycle(True),
            "cycle": True,
            "timing": {"sample_rate_hz": 200},
        },
    ),
    "sequence_corners": (
        "sequence",
        {
            "start": PICK_START,
            "targets": _cycle(False),
            "cycle": True,
            "timing": {"sample_rate_hz": 200},
        },
    ),
    "sequence_fixed_joint": (
        "sequence",
        {
            **BASE,
            "targets": [
                {"goal": {"q": [0.5, 2.2, 1.1], "assembly_mode": "+"}},
                {
                    "goal": {"q": [0.8, 2.4, 1.2], "assembly_mode": "+"},
                    "stop": False,
                    "blend": 0.02,
                },
                {"goal": {"q": [0.2, 2.1, 1.0], "assembly_mode": "+"}},
            ],
            "objective": "fixed",
        },
    ),
    "cartesian_line": (
        "cartesian",
        {"start": PICK_START, "waypoints": [_at(0.2, 0.05)], "timing": {"sample_rate_hz": 200}},
    ),
    "cartesian_polyline": (
        "cartesian",
        {
            "start": PICK_START,
            "waypoints": [_at(0, 0.05), _at(0.3, 0.05), _at(0.3, 0)],
            "path_tolerance": 0.001,
            "limits": {"cartesian_speed": 0.25, "velocity_scaling": 0.5},
            "timing": {"method": "toppra"},
        },
    ),
    "cartesian_out_of_reach": ("cartesian", {"start": PICK_START, "waypoints": [[1.2, 0.3, 0.1]]}),
}

#: keys whose values are the computation's own times, or vary with them
VOLATILE = {
    "planning_time",
    "solve_time",
    "timing_time",
    "elapsed",
    "elapsed_s",
    "time_s",
    "request_id",
}


def run(kind: str, body: dict[str, Any]) -> dict[str, Any]:
    """The answer of one wire request by the service's job function, as JSON data."""
    from planner import wire

    if kind == "plan":
        from planner.endpoints.plan import plan as job

        request: Any = wire.PlanRequest.model_validate(body)
    elif kind == "sequence":
        from planner.endpoints.sequence import sequence as job

        request = wire.SequenceRequest.model_validate(body)
    else:
        from planner.endpoints.cartesian import cartesian as job

        request = wire.CartesianRequest.model_validate(body)
    return strip(json.loads(job(request).model_dump_json()))


def strip(value: Any) -> Any:
    """``value`` without the volatile keys (at any depth) and without any ``diagnostics``
    entry that is a time."""
    if isinstance(value, dict):
        return {
            k: strip(v) for k, v in value.items() if k not in VOLATILE and not k.endswith("_time_s")
        }
    if isinstance(value, list):
        return [strip(v) for v in value]
    return value


def differences(expected: Any, actual: Any, where: str = "") -> list[str]:
    """Where ``actual`` differs from ``expected``: exact for strings, booleans, None, keys and
    lengths; numbers within 1e-6 relative (1e-9 absolute)."""
    out: list[str] = []
    if isinstance(expected, dict) and isinstance(actual, dict):
        for k in sorted(set(expected) | set(actual)):
            if k not in expected or k not in actual:
                out.append(f"{where}.{k}: present in only one")
            else:
                out += differences(expected[k], actual[k], f"{where}.{k}")
    elif isinstance(expected, list) and isinstance(actual, list):
        if len(expected) != len(actual):
            out.append(f"{where}: length {len(actual)} != {len(expected)}")
        else:
            for i, (e, a) in enumerate(zip(expected, actual, strict=True)):
                out += differences(e, a, f"{where}[{i}]")
    elif (
        isinstance(expected, bool) or isinstance(actual, bool) or expected is None or actual is None
    ):
        if expected != actual:
            out.append(f"{where}: {actual!r} != {expected!r}")
    elif isinstance(expected, int | float) and isinstance(actual, int | float):
        if not math.isclose(expected, actual, rel_tol=1e-6, abs_tol=1e-9):
            out.append(f"{where}: {actual!r} != {expected!r}")
    elif expected != actual:
        out.append(f"{where}: {actual!r} != {expected!r}")
    return out[:20]


def main() -> int:
    if sys.argv[1:] != ["--record"]:
        OUT.write(f"{__doc__}\n")
        return 2
    record = {}
    for name, (kind, body) in CASES.items():
        record[name] = run(kind, body)
        OUT.write(f"{name}: {record[name].get('status')}\n")
        OUT.flush()
    RECORD.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
    OUT.write(f"wrote {RECORD} ({RECORD.stat().st_size // 1024} KiB)\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
