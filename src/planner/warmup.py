"""Compile (or load from numba's on-disk cache) every numba kernel of the library at once.

The first call in a fresh installation compiles for about 10 s; later processes load the
cache in well under a second. The service's workers call :func:`warm_up` when they start,
``make run`` / ``make test`` and the Docker build call ``planner warm-up``, so that no
request's time budget is spent compiling.
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["warm_up"]


def warm_up() -> float:
    """Run every kernel once on a tiny input; returns the seconds it took."""
    t0 = time.perf_counter()
    from planner.design import Design
    from planner.geometry import Box, Capsule, Sphere
    from planner.kinematics import conditioning, forward_batch, inverse_batch
    from planner.validity import Margins, ValidityChecker
    from planner.validity import warm_up as warm_validity

    design = Design.default()
    batch = forward_batch(design, np.array([[0.0, 2.0, 1.0]]), "+")
    inverse_batch(design, batch.p)
    conditioning(design, batch.q, batch.passive, batch.w)
    warm_validity()
    # the clearance kernels of every obstacle type
    obstacles = [
        Sphere([2.0, 2.0, 2.0], 0.1),
        Box([-2.0, 2.0, 2.0], [0.2, 0.2, 0.2], [1.0, 0.0, 0.0, 0.0]),
        Capsule([2.0, -2.0, 2.0], [2.0, -2.0, 2.5], 0.05),
    ]
    checker = ValidityChecker(design, Margins(), obstacles, "+", "+-+")
    q = np.array([[0.0, 2.0, 1.0], [0.1, 2.1, 1.1]])
    checker.check_states(q)
    checker.check_motion(q[0], q[1])
    checker.check_path(q)
    return time.perf_counter() - t0
