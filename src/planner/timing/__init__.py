"""Time parameterisation: turn a planned joint path into a trajectory a controller can follow.

The only package that imports toppra and ruckig. Entry point: :func:`time_path`.

>>> import numpy as np
>>> from planner import Design
>>> from planner.timing import JointLimits, time_path
>>> traj = time_path(Design.default(), np.array([[0, 0.5, 1.0], [0.4, 0.9, 1.2], [0.8, 0.6, 1.5]]),
...                  JointLimits.default(), method="toppra")
>>> bool(traj.duration > 0), traj.q[0].tolist() == [0.0, 0.5, 1.0]
(True, True)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from planner._lazy import lazy_exports

if TYPE_CHECKING:
    from planner.timing.checks import LIMIT_RTOL, StateChecker
    from planner.timing.limits import JointLimits
    from planner.timing.options import (
        DEFAULT_MAX_DEVIATION,
        DEFAULT_SAMPLE_RATE_HZ,
        METHODS,
        TimingOptions,
    )
    from planner.timing.parameterize import DEFAULT_CHECK_RESOLUTION, time_path
    from planner.timing.trajectory import Trajectory

#: Where each exported name lives. Imported on first use (PEP 562), so that a module of the
#: package that needs neither toppra nor ruckig (``planner.timing.export``, which the client
#: uses to convert and write trajectories; ``planner.timing.limits``) loads without them.
_HOMES = {
    "LIMIT_RTOL": "checks",
    "StateChecker": "checks",
    "JointLimits": "limits",
    "DEFAULT_CHECK_RESOLUTION": "parameterize",
    "DEFAULT_MAX_DEVIATION": "options",
    "DEFAULT_SAMPLE_RATE_HZ": "options",
    "METHODS": "options",
    "TimingOptions": "options",
    "time_path": "parameterize",
    "Trajectory": "trajectory",
}


__all__ = [
    "DEFAULT_CHECK_RESOLUTION",
    "DEFAULT_MAX_DEVIATION",
    "DEFAULT_SAMPLE_RATE_HZ",
    "LIMIT_RTOL",
    "METHODS",
    "JointLimits",
    "StateChecker",
    "TimingOptions",
    "Trajectory",
    "time_path",
]

__getattr__, __dir__ = lazy_exports(__name__, _HOMES, __all__)
