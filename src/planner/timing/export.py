"""Trajectories as files: CSV written and read, and the parallel arrays of a sampled
trajectory.

The library's :class:`~planner.timing.Trajectory` holds parallel arrays (``t`` (M,), ``q``,
``qd``, ``qdd`` (M, 3)). CSV: a first comment line naming the units, then the header
``t,theta1,theta2,theta3,dtheta1,dtheta2,dtheta3,ddtheta1,ddtheta2,ddtheta3`` (plus
``dddtheta1..3`` when jerks are given, ``tau1..3`` when torques are), one row per sample, floats written with 17
significant digits so that reading gives back the same numbers. The controller's points
layout (``timing.format = "points"``) is the wire's: :mod:`planner.wire.timing`
(:func:`~planner.wire.timing.points_from_arrays`, :func:`~planner.wire.timing.arrays_from_points`).
"""

from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass
from typing import IO

import numpy as np
from numpy.typing import ArrayLike

from planner.exceptions import InputError

__all__ = [
    "CSV_UNITS",
    "JOINT_NAMES",
    "TrajectoryArrays",
    "checked_arrays",
    "read_csv",
    "write_csv",
]

#: Joint names of the points form, in the order of q.
JOINT_NAMES: tuple[str, str, str] = ("theta1", "theta2", "theta3")
#: The first line of a CSV file (a comment naming the units of every column).
CSV_UNITS = "# units: t s; theta rad; dtheta rad/s; ddtheta rad/s^2; dddtheta rad/s^3; tau N m"

_POS = list(JOINT_NAMES)
_VEL = [f"d{n}" for n in JOINT_NAMES]
_ACC = [f"dd{n}" for n in JOINT_NAMES]
_JERK = [f"ddd{n}" for n in JOINT_NAMES]
_TAU = ["tau1", "tau2", "tau3"]


@dataclass(frozen=True, eq=False)
class TrajectoryArrays:
    """A sampled trajectory as parallel arrays (the ``"arrays"`` format).

    Attributes
    ----------
    t : shape (M,), s -- increasing, from 0.
    q, qd, qdd : shape (M, 3) -- rad, rad/s, rad/s^2.
    jerk : shape (M, 3), rad/s^3, or None.
    duration : float, s -- ``t[-1]`` for a trajectory sampled to its end.
    tau : shape (M, 3), N m, or None -- actuator torques.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    jerk: np.ndarray | None = None
    duration: float = float("nan")
    tau: np.ndarray | None = None


def checked_arrays(t, q, qd, qdd, jerk=None) -> tuple[np.ndarray, ...]:
    """The samples as float arrays, checked: t (M,) strictly increasing, q, qd, qdd (and
    jerk, or None) (M, 3), all finite; :class:`~planner.exceptions.InputError` otherwise."""
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.shape[0] < 1:
        raise InputError(f"t must have shape (M,) with M >= 1, got {t.shape}")
    out = [t]
    for name, a in (("q", q), ("qd", qd), ("qdd", qdd), ("jerk", jerk)):
        if a is None:
            out.append(None)
            continue
        a = np.asarray(a, dtype=float)
        if a.shape != (t.shape[0], 3):
            raise InputError(f"{name} must have shape ({t.shape[0]}, 3), got {a.shape}")
        out.append(a)
    if not all(np.all(np.isfinite(a)) for a in out if a is not None):
        raise InputError("trajectory samples must be finite (no NaN or infinity)")
    if np.any(np.diff(t) <= 0):
        raise InputError("t must increase strictly")
    return tuple(out)


def write_csv(
    target: str | os.PathLike | IO[str],
    t: ArrayLike,
    q: ArrayLike,
    qd: ArrayLike,
    qdd: ArrayLike,
    jerk: ArrayLike | None = None,
    tau: ArrayLike | None = None,
) -> None:
    """Write samples as CSV: the units line, the header, one row per sample.

    Parameters
    ----------
    target : path or text file
    t : shape (M,), s
    q, qd, qdd : shape (M, 3), rad, rad/s, rad/s^2
    jerk : shape (M, 3), rad/s^3, optional (adds three columns)
    tau : shape (M, 3), N m, optional (adds the columns tau1..3)
    """
    t, q, qd, qdd, jerk = checked_arrays(t, q, qd, qdd, jerk)
    if tau is not None:
        tau = checked_arrays(t, tau, tau, tau)[1]
    header = ["t", *_POS, *_VEL, *_ACC] + (_JERK if jerk is not None else [])
    header += _TAU if tau is not None else []
    cols = [t[:, None], q, qd, qdd] + ([jerk] if jerk is not None else [])
    cols += [tau] if tau is not None else []
    data = np.hstack(cols)
    buf = io.StringIO()
    buf.write(CSV_UNITS + "\n")
    buf.write(",".join(header) + "\n")
    for row in data:
        buf.write(",".join(f"{x:.17g}" for x in row) + "\n")
    if isinstance(target, (str, os.PathLike)):
        with open(target, "w", encoding="utf-8", newline="") as f:
            f.write(buf.getvalue())
    else:
        target.write(buf.getvalue())


def read_csv(source: str | os.PathLike | IO[str]) -> TrajectoryArrays:
    """Read a CSV written by :func:`write_csv` (comment lines starting with '#' skipped).

    Raises
    ------
    InputError
        A missing column of the header, or a row that is not numbers.
    """
    if isinstance(source, (str, os.PathLike)):
        with open(source, encoding="utf-8", newline="") as f:
            text = f.read()
    else:
        text = source.read()
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise InputError("the CSV has no header")
    rows = list(csv.reader(lines))
    header = [h.strip() for h in rows[0]]
    missing = [h for h in ["t", *_POS, *_VEL, *_ACC] if h not in header]
    if missing:
        raise InputError(f"the CSV header lacks the columns {missing}")
    try:
        data = np.array([[float(x) for x in r] for r in rows[1:]], dtype=float)
    except ValueError as exc:
        raise InputError(f"a CSV row is not numbers: {exc}") from exc
    if data.ndim != 2 or data.shape[0] == 0 or data.shape[1] != len(header):
        raise InputError("the CSV rows must have one value per header column")

    def cols(names: list[str]) -> np.ndarray:
        return data[:, [header.index(n) for n in names]]

    jerk = cols(_JERK) if all(n in header for n in _JERK) else None
    tau = cols(_TAU) if all(n in header for n in _TAU) else None
    t = data[:, header.index("t")]
    return TrajectoryArrays(t, cols(_POS), cols(_VEL), cols(_ACC), jerk, float(t[-1]), tau)
