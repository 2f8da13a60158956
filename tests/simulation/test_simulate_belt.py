"""A belt pick executed on the simulated robot (MuJoCo, the default computed-torque
controller): the simulated tool point, read from the physics engine, stays within 0.5 mm of
the part over the whole dwell."""

from __future__ import annotations

import numpy as np
import pytest

from planner import Design, SequenceTarget, solve_sequence
from planner.kinematics import WORKING_MODES, inverse_batch
from planner.planning import CartesianTarget, JointPosture
from planner.sequence import MovingTarget
from planner.timing import TimingOptions

pytest.importorskip("mujoco")


def test_the_simulated_tool_stays_on_the_part_over_the_dwell():
    from planner.simulation import Reference, simulate

    design = Design.default()
    bin_point = np.array([-0.2, 0.25, -0.45])
    start = JointPosture(inverse_batch(design, bin_point).q[0, WORKING_MODES.index("+-+")], "+")
    part = MovingTarget([-0.7, 0.0, -0.45], "any", [0.5, 0.0, 0.0], 0.0)
    dwell = 0.2
    targets = [SequenceTarget(part, dwell=dwell), SequenceTarget(CartesianTarget(bin_point))]
    r = solve_sequence(design, start, targets, timing=TimingOptions(sample_rate_hz=1000))
    assert r.solved, r.message
    tr, meet = r.trajectory, r.legs[0].meet_time
    sim = simulate(design, Reference(tr.t, tr.q, tr.qd, tr.qdd))
    span = (sim.t >= meet) & (sim.t <= meet + dwell)
    assert span.sum() >= 150
    err = np.linalg.norm(sim.p[span] - part.at(sim.t[span]), axis=1)
    assert err.max() < 5e-4
