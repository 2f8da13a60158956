"""The torque-limited optimum as the yardstick: the minimum-time Adept cycle of the closed
chain under the motors' torque limits, solved as an optimal-control problem, beside the
product's torque-limited cycle.

    .venv/bin/python benchmarks/cycle_optimum.py [--nodes 30] [--payloads 0.1 1 2]

For the default design and the paper's optimum (L0 = 0, L1 = L2 = 0.4 m), at each payload:

* the product's cycle (``solve_sequence``, toppra, ``limits.torque``), every target a stop and
  with the four top corners passed (blend 90 % of half the shorter adjacent leg, as in
  ``benchmarks/sequences.py``); the modes are the placement's (``objective="fixed"``);
* the optimum of the same motion (``benchmarks/_closed_chain_ocp.py``: CasADi and IPOPT,
  direct collocation of the chain's own Lagrangian dynamics derived there, not the
  product's): the same targets in the same working modes, at rest where the product stops,
  through the same joint-space balls where it passes, under the same velocity,
  acceleration, torque and joint limits and the same validity margins (kappa(A), serial
  measures); its path is free, the product's follows its planned legs;
* the ratio product / optimum (goal: <= 1.15), and the optimum's torques re-checked densely
  with the product's inverse dynamics (the largest |tau| / limit between the nodes).

The limits: velocity 12 rad/s and acceleration 400 rad/s^2 on every joint (a servo behind a
1:5 reduction: they bind only on the shortest moves), torque 24 / 12 / 12 N m (theta1 carries
the whole linkage about AB; about 1.5 x the largest gravity torque of the cycle at 2 kg). The
motors, not a guess at joint limits, set the cycle, as on the commercial robots.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _closed_chain_ocp import dense_samples, lagrangian_model, minimum_time
from _machine import print_machine

from planner import Design
from planner.dynamics import DEFAULT_GRAVITY, Inertia, inverse_dynamics
from planner.sequence.adept import adept_targets, place_adept_cycle
from planner.sequence.solve import solve_sequence
from planner.timing import JointLimits, TimingOptions
from planner.validity import Margins

VELOCITY, ACCELERATION, TORQUE = (12.0,) * 3, (400.0,) * 3, (24.0, 12.0, 12.0)
CORNERS = (0, 1, 3, 4)  # the top corners among the five targets
DESIGNS = {"default": Design.default(), "paper-optimum": Design.paper_optimum()}


def with_payload(design: Design, mass: float) -> Inertia:
    base = Inertia.default(design)
    return Inertia(base.proximal, base.distal, mass, base.base_inertia, base.rotor)


def product_cycles(design, inertia, limits, timing):
    """The product's placed all-stops cycle and its corners-passed variant."""
    placed = place_adept_cycle(design, timing=timing, limits=limits, inertia=inertia)
    stops = placed.result
    legs = [leg.plan.diagnostics.path_length for leg in stops.legs]
    blends = [0.0] * 5
    for i in CORNERS:
        blends[i] = 0.9 * 0.5 * min(legs[i], legs[i + 1])
    flags = [i not in CORNERS for i in range(5)]
    modes = [leg.working_mode for leg in stops.legs]
    passed = solve_sequence(
        design,
        placed.start,
        adept_targets(placed.pick, placed.h, placed.d, modes[:5], flags, blends),
        cycle=True,
        objective="fixed",
        timing=timing,
        limits=limits,
        inertia=inertia,
    )
    postures = np.array(
        [placed.start.q, *[stops.path.waypoints[leg.waypoint_index] for leg in stops.legs]]
    )
    return placed, stops, passed, postures, blends, modes


def optimum(model, postures, modes, stops, radii, guess, args, design, margins):
    """The optimal-control optimum; where IPOPT fails from the first start (a local
    infeasibility), again from twice the durations with the exact Hessian."""
    result = None
    for scale, exact in ((1.0, False), (2.0, True)):
        result = minimum_time(
            model,
            postures,
            stops,
            modes,
            velocity=np.array(VELOCITY),
            acceleration=np.array(ACCELERATION),
            torque=np.array(TORQUE),
            joint_limits=design.joint_limits,
            kappa_max=margins.kappa_max,
            serial_min=margins.serial_min,
            guess_durations=scale * np.asarray(guess),
            radii=radii,
            nodes=args.nodes,
            exact_hessian=exact,
        )
        if result.solved:
            break
    return result


def dense_ratio(result, design, inertia, assembly_mode) -> float:
    """The optimum's largest |tau| / limit between its nodes, by the product's dynamics."""
    _, q, qd, qdd = dense_samples(result)
    tau = inverse_dynamics(
        design, inertia, q, qd, qdd, assembly_mode=assembly_mode, gravity=DEFAULT_GRAVITY
    ).tau
    return float(np.max(np.abs(tau) / np.array(TORQUE)))


def main() -> None:
    print_machine()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", type=int, default=30, help="intervals per segment")
    parser.add_argument("--payloads", type=float, nargs="+", default=[0.1, 1.0, 2.0])
    parser.add_argument(
        "--designs", nargs="+", default=list(DESIGNS), choices=list(DESIGNS), help="which designs"
    )
    args = parser.parse_args()
    limits = JointLimits(VELOCITY, ACCELERATION, torque=TORQUE)
    timing = TimingOptions(method="toppra", sample_rate_hz=200)
    margins = Margins()
    print(
        f"limits: velocity {VELOCITY[0]:g} rad/s, acceleration {ACCELERATION[0]:g} rad/s^2, "
        f"torque {'/'.join(f'{x:g}' for x in TORQUE)} N m; gravity {DEFAULT_GRAVITY}; "
        f"{args.nodes} intervals per segment"
    )
    print()
    header = (
        f"{'design':<15} {'payload':>7} {'variant':<8} {'product [s]':>11} "
        f"{'optimum [s]':>11} {'ratio':>6} {'goal':>5} {'tau/limit':>9} {'ipopt [s]':>9}  status"
    )
    print(header)
    for name in args.designs:
        design = DESIGNS[name]
        for mass in args.payloads:
            inertia = with_payload(design, mass)
            placed, stops, passed, postures, blends, modes = product_cycles(
                design, inertia, limits, timing
            )
            model = lagrangian_model(design, inertia, DEFAULT_GRAVITY, placed.start.assembly_mode)
            leg_times = np.array([leg.end_time - leg.start_time for leg in stops.legs])
            passing = [True, *[i not in CORNERS for i in range(5)], True]
            variants = (
                ("stops", stops, [True] * 7, [0.0] * 7),
                ("passed", passed, passing, [0.0, *blends, 0.0]),
            )
            for variant, product, flags, radii in variants:
                t0 = time.perf_counter()
                best = optimum(
                    model, postures, modes, flags, radii, leg_times, args, design, margins
                )
                wall = time.perf_counter() - t0
                ratio = product.cycle_time / best.total if best.solved else float("nan")
                print(
                    f"{name:<15} {mass:>7g} {variant:<8} {product.cycle_time:>11.4f} "
                    f"{best.total:>11.4f} {ratio:>6.3f} {'ok' if ratio <= 1.15 else ('NOT' if best.solved else '-'):>5} "
                    f"{dense_ratio(best, design, inertia, placed.start.assembly_mode):>9.3f} "
                    f"{wall:>9.1f}  {best.status}"
                )


if __name__ == "__main__":
    main()
