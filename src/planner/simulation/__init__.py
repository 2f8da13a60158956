"""The simulated robot (``docs/simulation.md``): a trajectory run on the product's MJCF model
in MuJoCo, under a controller, and what the run measures (the tracking error, the settle
times, the realised duration); its record as a ROS 2 bag (:mod:`planner.simulation.bag`).

The only room of the library that imports ``mujoco`` (:mod:`planner.simulation.engine`) and
the ROS 2 bag libraries (:mod:`planner.simulation.bag`). Core: no wire formats, no HTTP.
"""

from __future__ import annotations

from planner.simulation.controller import CONTROLLER_KINDS, Controller
from planner.simulation.engine import (
    DEFAULT_HOLD_S,
    DEFAULT_RATE_HZ,
    DEFAULT_SETTLE_TOLERANCE_MM,
    ENGINE,
    MAX_SIMULATION_SAMPLES,
    simulate,
)
from planner.simulation.reference import Reference, Stop, find_stops
from planner.simulation.result import Simulation, Tracking

__all__ = [
    "CONTROLLER_KINDS",
    "DEFAULT_HOLD_S",
    "DEFAULT_RATE_HZ",
    "DEFAULT_SETTLE_TOLERANCE_MM",
    "ENGINE",
    "MAX_SIMULATION_SAMPLES",
    "Controller",
    "Reference",
    "Simulation",
    "Stop",
    "Tracking",
    "find_stops",
    "simulate",
]
