"""The simulated robot: computed-torque tracking of the Adept cycle at its torque-limited
timing, on the default design (``docs/simulation.md``).

    .venv/bin/python benchmarks/simulation.py [--repeats 3] [--payloads 0.1 2]

The cycle is the product's (``place_adept_cycle``: every target a stop, toppra under the
limits of ``benchmarks/cycle_optimum.py``: velocity 12 rad/s, acceleration 400 rad/s^2,
torque 24 / 12 / 12 N m, sampled at the control rate, 1 kHz), run on the MJCF model in
MuJoCo with the actuators saturating at the same torques. For each payload and controller:

* the tracking error of P (max, RMS; goal: max <= 0.5 mm with computed torque);
* the planned cycle time against the realised one (the final settle within 0.1 mm; goal:
  within 2 %), the worst settle time at the intermediate stops, the saturated samples;
* the speed of the simulation against real time: simulated seconds (the cycle and the hold
  until settled) per second of the whole call's CPU time (model, feed-forward, loop) and of
  its wall time (medians of ``--repeats``; goal: >= 10x). On a shared machine the wall time
  includes the waits for a core: the header's load average says how shared it was.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

from _machine import print_machine

from planner import Design
from planner.dynamics import Inertia
from planner.sequence.adept import place_adept_cycle
from planner.simulation import ENGINE, Controller, Reference, simulate
from planner.timing import JointLimits, TimingOptions

VELOCITY, ACCELERATION, TORQUE = (12.0,) * 3, (400.0,) * 3, (24.0, 12.0, 12.0)
RATE_HZ = 1000.0


def with_payload(design: Design, mass: float) -> Inertia:
    base = Inertia.default(design)
    return Inertia(base.proximal, base.distal, mass, base.base_inertia, base.rotor)


def main() -> None:
    print_machine()
    print(f"load average (1 min): {os.getloadavg()[0]:.1f}")
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--payloads", type=float, nargs="+", default=[0.1, 2.0])
    args = parser.parse_args()
    design = Design.default()
    limits = JointLimits(VELOCITY, ACCELERATION, torque=TORQUE)
    timing = TimingOptions(method="toppra", sample_rate_hz=RATE_HZ)
    print(
        f"{ENGINE}; Adept cycle (all stops) on the default design at its torque-limited "
        f"timing (torque {'/'.join(f'{x:g}' for x in TORQUE)} N m), control at "
        f"{RATE_HZ:g} Hz, actuators saturating at the same torques"
    )
    header = (
        f"{'payload':>7} {'controller':>15} {'P max mm':>9} {'P rms mm':>9} "
        f"{'planned s':>9} {'realised s':>10} {'diff %':>7} {'stop settle s':>13} "
        f"{'sat.':>5} {'x real (CPU)':>12} {'x real (wall)':>13}"
    )
    print(header)
    print("-" * len(header))
    for mass in args.payloads:
        inertia = with_payload(design, mass)
        placed = place_adept_cycle(design, timing=timing, limits=limits, inertia=inertia)
        traj = placed.result.trajectory
        ref = Reference(traj.t, traj.q, traj.qd, traj.qdd)
        for kind in ("computed_torque", "pd"):
            cpu, wall = [], []
            for _ in range(args.repeats):
                w0, c0 = time.perf_counter(), time.process_time()
                sim = simulate(
                    design,
                    ref,
                    inertia=inertia,
                    controller=Controller(kind),
                    rate_hz=RATE_HZ,
                    torque_limits=TORQUE,
                    assembly_mode=placed.start.assembly_mode,
                )
                wall.append(time.perf_counter() - w0)
                cpu.append(time.process_time() - c0)
            simulated = sim.t[-1] - sim.t[0]
            real = sim.realised_duration
            diff = "-" if real is None else f"{100 * (real / sim.planned_duration - 1):.2f}"
            inner = [s for s in sim.settle_times[:-1]]
            settle = "none" if any(s is None for s in inner) else f"{max(inner, default=0.0):.4f}"
            print(
                f"{mass:>7g} {kind:>15} {sim.tracking.p_max_mm:>9.4f} "
                f"{sim.tracking.p_rms_mm:>9.4f} {sim.planned_duration:>9.4f} "
                f"{'not settled' if real is None else f'{real:.4f}':>10} {diff:>7} "
                f"{settle:>13} {sim.saturated:>5} "
                f"{simulated / statistics.median(cpu):>12.1f} "
                f"{simulated / statistics.median(wall):>13.1f}"
            )
    print(
        "goals (computed torque): P max <= 0.5 mm; realised cycle within 2 % of the planned; "
        ">= 10x real time"
    )


if __name__ == "__main__":
    main()
