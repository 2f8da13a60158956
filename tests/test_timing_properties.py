"""Property test: on arbitrary paths and limits, time_path returns a trajectory that meets
its guarantees or raises one of the product's typed errors, never anything else."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planner import Design, PlannerError
from planner.timing import LIMIT_RTOL, JointLimits, time_path

DESIGN = Design.default()
scale = st.sampled_from([1e-10, 1e-6, 1e-3, 0.1, 1.0, 3.0])
limit = st.floats(min_value=0.05, max_value=50.0)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**31),
    n=st.integers(2, 7),
    step=scale,
    v=st.tuples(limit, limit, limit),
    a=st.tuples(limit, limit, limit),
    j=st.tuples(limit, limit, limit),
    dev=st.sampled_from([0.0, 0.01, 0.05, 1.0]),
    method=st.sampled_from(["toppra", "ruckig"]),
)
def test_guarantees_or_typed_error(seed, n, step, v, a, j, dev, method):
    rng = np.random.default_rng(seed)
    w = np.clip(np.cumsum(rng.uniform(-0.5, 0.5, size=(n, 3)) * step, axis=0), -3.0, 3.0)
    limits = JointLimits(v, a, tuple(x * 20 for x in j))
    try:
        traj = time_path(DESIGN, w, limits, method=method, max_deviation=dev, sample_rate_hz=20)
    except PlannerError:
        return
    assert np.array_equal(traj.q[0], w[0]) and np.array_equal(traj.q[-1], w[-1])
    assert np.all(traj.qd[[0, -1]] == 0)
    assert np.all(np.abs(traj.qd) <= np.asarray(v) * (1 + LIMIT_RTOL))
    assert np.all(np.abs(traj.qdd) <= np.asarray(a) * (1 + LIMIT_RTOL))
    assert np.all(np.diff(traj.t) > 0)
