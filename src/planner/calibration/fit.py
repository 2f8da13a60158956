"""Kinematic calibration: a nominal design and measured points P -> the identified model.

Method (``docs/calibration.md``): nonlinear least squares (:func:`scipy.optimize.least_squares`,
Levenberg-Marquardt) of the residuals of :mod:`planner.calibration.model` with their analytic
Jacobian, over the parameters asked for and identifiable. Steps:

1. Branch of every measurement. The passive joints are not measured, so the loop's assembly
   branch decides P: the measured ``assembly_mode`` when given; else the branch whose
   working mode is the measured ``working_mode``; else the branch whose nominal P (through
   the current frame estimate) is nearest the measured point.
2. A first frame by a rigid fit (Kabsch) of the measured points onto the nominal P (repeated
   with step 1 until the branches settle), when the frame is identified.
3. Identifiability: the Jacobian's columns (at the first estimate, for the points that the
   model predicts there: the postures' identifiability, not the data's misfit), scaled to
   unit norm, are taken in the order
   lengths, frame position, frame rotation, offsets[1], offsets[2], offsets[0]; a column that
   leaves the smallest singular value of those already taken below :data:`RANK_TOL` is a
   rank-deficient direction: that parameter is held at its nominal value and named in
   ``unidentified``. With the tracker's frame free, ``offsets[0]`` always is: turning theta1's
   zero turns every P about AB exactly as turning the frame about y does.
4. Least squares over the rest; standard deviations from ``sigma^2 (J^T J)^-1`` with
   ``sigma^2`` the residual variance (3 N - k degrees of freedom); the condition number is
   that of the scaled Jacobian of the identified parameters.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from planner.calibration.model import (
    FULL_NAMES,
    loop_state,
    measurement_jacobian,
    residuals,
    rotation_matrix,
)
from planner.design import MIN_LENGTH, Design
from planner.exceptions import InputError

__all__ = [
    "IDENTIFY_DEFAULT",
    "IDENTIFY_OPTIONS",
    "RANK_TOL",
    "CalibrationResult",
    "Measurements",
    "calibrate",
]

#: What ``identify`` may hold.
IDENTIFY_OPTIONS: tuple[str, ...] = ("lengths", "leg_lengths", "offsets", "frame")
#: The default of ``identify``.
IDENTIFY_DEFAULT: tuple[str, ...] = ("lengths", "offsets", "frame")
#: A parameter whose unit-scaled Jacobian column brings the smallest singular value of the
#: columns taken before it below this is held (a rank-deficient direction).
RANK_TOL = 1e-7
_MODES = {"+": 1.0, "-": -1.0}


@dataclass(frozen=True, eq=False)
class Measurements:
    """N measurements: ``q`` (N, 3) rad as commanded, ``p`` (N, 3) m in the tracker's frame,
    and per measurement an optional ``working_mode`` ('+-+' ...) and ``assembly_mode``
    ('+' | '-'); None where not measured."""

    q: np.ndarray
    p: np.ndarray
    working_mode: Sequence[str | None] = ()
    assembly_mode: Sequence[str | None] = ()

    def __post_init__(self) -> None:
        q = np.asarray(self.q, dtype=float)
        p = np.asarray(self.p, dtype=float)
        for name, arr in (("q", q), ("p", p)):
            if arr.ndim != 2 or arr.shape[1] != 3:
                raise InputError(f"{name} must have shape (N, 3), got {arr.shape}", field=name)
            for i in np.flatnonzero(~np.all(np.isfinite(arr), axis=1)):
                raise InputError(
                    f"measurements[{i}].{name} must be finite, got {arr[i].tolist()}",
                    field=("measurements", int(i), name),
                )
        if q.shape != p.shape:
            raise InputError(
                f"q and p must have the same rows, got {q.shape[0]} and {p.shape[0]}",
                field="measurements",
            )
        n = q.shape[0]
        for name in ("working_mode", "assembly_mode"):
            given = list(getattr(self, name)) or [None] * n
            if len(given) != n:
                raise InputError(f"{name} must have one entry per measurement", field=name)
            object.__setattr__(self, name, tuple(given))
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "p", p)

    def __len__(self) -> int:
        return int(self.q.shape[0])


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """The identified model (names and units: ``docs/calibration.md``).

    ``design``: the nominal design with L0, L1, L2 identified (with the legs apart: L1 and
    L2 the means of the two legs', the four in ``leg_lengths``); ``offsets`` (3,) rad added to
    q before the kinematics; ``frame_position`` (3,) m and ``frame_rotation`` (3,) rad
    (tracker -> base: ``p_base = R p + t``); ``residuals`` (N,) m, the distance of every
    measured point from the identified model's; ``std`` by parameter name (identified
    ones); ``unidentified``: the names held at nominal; ``assembly_modes`` (N,) the branch
    used for each measurement."""

    design: Design
    offsets: np.ndarray
    frame_position: np.ndarray
    frame_rotation: np.ndarray
    residuals: np.ndarray
    std: dict[str, float]
    condition_number: float
    unidentified: list[str]
    parameters: dict[str, float]
    assembly_modes: list[str]
    leg_lengths: dict[str, float] | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def residual_rms(self) -> float:
        """RMS of the per-measurement distances, m."""
        return float(np.sqrt(np.mean(self.residuals**2)))

    @property
    def residual_max(self) -> float:
        """Largest per-measurement distance, m."""
        return float(np.max(self.residuals))

    def predict(self, q: np.ndarray, assembly_mode: str | np.ndarray = "+") -> np.ndarray:
        """P (N, 3) in the tracker's frame of postures ``q`` (N, 3) by the identified model."""
        full = _full_of(self)
        q2 = np.atleast_2d(np.asarray(q, dtype=float))
        branch = _branch_array(assembly_mode, q2.shape[0])
        p3 = loop_state(full, q2, branch).p3
        r = rotation_matrix(self.frame_rotation)
        return (p3 - self.frame_position) @ r


def _branch_array(mode: str | np.ndarray, n: int) -> np.ndarray:
    if isinstance(mode, str):
        return np.full(n, _MODES[mode])
    return np.asarray(mode, dtype=float)


def _full_of(result: CalibrationResult) -> np.ndarray:
    return np.array([result.parameters[name] for name in FULL_NAMES])


def _parameter_map(identify: Iterable[str]) -> tuple[list[str], np.ndarray]:
    """The asked parameters' names, in identification priority, and T (14, k): the full
    vector's change per unit change of each."""
    asked = list(identify)
    for i, item in enumerate(asked):
        if item not in IDENTIFY_OPTIONS:
            raise InputError(
                f"identify[{i}] must be one of {', '.join(IDENTIFY_OPTIONS)}, got {item!r}",
                field=("identify", i),
            )
    columns: list[tuple[str, dict[int, float]]] = []
    if "leg_lengths" in asked:
        columns += [(FULL_NAMES[i], {i: 1.0}) for i in range(5)]
    elif "lengths" in asked:
        columns += [("L0", {0: 1.0}), ("L1", {1: 1.0, 2: 1.0}), ("L2", {3: 1.0, 4: 1.0})]
    if "frame" in asked:
        columns += [(FULL_NAMES[i], {i: 1.0}) for i in range(8, 14)]
    if "offsets" in asked:
        columns += [(FULL_NAMES[i], {i: 1.0}) for i in (6, 7, 5)]
    t = np.zeros((len(FULL_NAMES), len(columns)))
    for j, (_, entries) in enumerate(columns):
        for i, v in entries.items():
            t[i, j] = v
    return [name for name, _ in columns], t


def _nominal(design: Design, frame: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    full = np.zeros(len(FULL_NAMES))
    full[:5] = (design.L0, design.L1, design.L1, design.L2, design.L2)
    if frame is not None:
        full[8:11], full[11:14] = frame
    return full


def _candidates(full: np.ndarray, m: Measurements) -> np.ndarray:
    """Allowed branches (N, 2) for (+1, -1) by the measured modes (InputError if none)."""
    n = len(m)
    allowed = np.zeros((n, 2), dtype=bool)
    states = [loop_state(full, m.q, np.full(n, b)) for b in (1.0, -1.0)]
    for i in range(n):
        ok = [bool(s.ok[i]) for s in states]
        if not any(ok):
            raise InputError(
                f"measurements[{i}].q = {m.q[i].tolist()} does not assemble in the nominal "
                "design (|CD| exceeds 2 L2, or C = D): no posture of the design reaches it",
                field=("measurements", i, "q"),
            )
        am, wm = m.assembly_mode[i], m.working_mode[i]
        for k, b in enumerate(("+", "-")):
            allowed[i, k] = ok[k] and (am is None or am == b)
            if wm is not None and allowed[i, k]:
                signs = "".join("+" if x > 0 else "-" for x in states[k].working_mode_signs[i])
                allowed[i, k] = signs == wm
        if not allowed[i].any():
            which = "assembly_mode" if wm is None else "working_mode"
            raise InputError(
                f"measurements[{i}]: no assembly branch of the nominal design at q = "
                f"{m.q[i].tolist()} has the measured {which} "
                f"{(am if wm is None else wm)!r}",
                field=("measurements", i, which),
            )
    return allowed


def _choose_branches(full: np.ndarray, m: Measurements, allowed: np.ndarray) -> np.ndarray:
    """The branch of each measurement: the only allowed one, else the one whose P is
    nearest the measured point through the frame of ``full``."""
    n = len(m)
    r = rotation_matrix(full[11:14])
    target = m.p @ r.T + full[8:11]
    dist = np.stack(
        [
            np.linalg.norm(loop_state(full, m.q, np.full(n, b)).p3 - target, axis=1)
            for b in (1.0, -1.0)
        ],
        axis=1,
    )
    dist[~allowed] = np.inf
    return np.where(dist[:, 0] <= dist[:, 1], 1.0, -1.0)


def _rigid_fit(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Kabsch: (t, phi) minimising sum |R src + t - dst|^2."""
    from scipy.spatial.transform import Rotation

    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    h = (src - cs).T @ (dst - cd)
    u, _, vt = np.linalg.svd(h)
    sign = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    r = vt.T @ np.diag([1.0, 1.0, sign]) @ u.T
    return cd - r @ cs, Rotation.from_matrix(r).as_rotvec()


def _initial(
    full: np.ndarray, m: Measurements, allowed: np.ndarray, fit_frame: bool
) -> tuple[np.ndarray, np.ndarray]:
    """(full with a first frame, branches): steps 1 and 2 of the module docstring."""
    branch = _choose_branches(full, m, allowed)
    if not fit_frame or len(m) < 3:
        return full, branch
    for _ in range(5):
        p3 = loop_state(full, m.q, branch).p3
        full = full.copy()
        full[8:11], full[11:14] = _rigid_fit(m.p, p3)
        again = _choose_branches(full, m, allowed)
        if np.array_equal(again, branch):
            break
        branch = again
    return full, branch


def _structural_jacobian(full: np.ndarray, q: np.ndarray, branch: np.ndarray) -> np.ndarray:
    """The measurement Jacobian at ``full`` for the points the model itself predicts: the
    identifiability of the postures, free of the measurements' misfit (a misfit of a few mm
    would blur an exact dependency, e.g. offsets[0] against the frame, into a weak one)."""
    r = rotation_matrix(full[11:14])
    p = (loop_state(full, q, branch).p3 - full[8:11]) @ r
    return measurement_jacobian(full, q, branch, p)


def _select(jac: np.ndarray) -> list[int]:
    """Columns of ``jac`` taken in order while the scaled set stays of full rank."""
    norms = np.linalg.norm(jac, axis=0)
    taken: list[int] = []
    for j in range(jac.shape[1]):
        if norms[j] == 0:
            continue
        trial = jac[:, [*taken, j]] / norms[[*taken, j]]
        if np.linalg.svd(trial, compute_uv=False)[-1] > RANK_TOL:
            taken.append(j)
    return taken


def calibrate(
    design: Design,
    measurements: Measurements,
    *,
    identify: Iterable[str] = IDENTIFY_DEFAULT,
    frame: tuple[np.ndarray, np.ndarray] | None = None,
) -> CalibrationResult:
    """Identify the model from ``measurements`` (module docstring).

    Parameters
    ----------
    design : the nominal design (its lengths are the starting point and the prior of any
        length held)
    measurements : :class:`Measurements`
    identify : subset of :data:`IDENTIFY_OPTIONS`
    frame : (position (3,) m, rotation vector (3,) rad) of the tracker, a first guess (or the
        known frame when "frame" is not identified); default the identity

    Raises
    ------
    InputError
        Fewer measurements than the parameters need (3 equations each, one more than the
        parameters), a measurement whose q does not assemble, a measured mode that no branch
        has (each named by its index).
    """
    identify = tuple(identify)
    names, tmap = _parameter_map(identify)
    n = len(measurements)
    if 3 * n < len(names) + 1:
        raise InputError(
            f"{n} measurements give {3 * n} equations; identifying {len(names)} parameters "
            f"needs at least {math.ceil((len(names) + 1) / 3)} measurements",
            field="measurements",
        )
    guess = None if frame is None else (np.asarray(frame[0], float), np.asarray(frame[1], float))
    full0 = _nominal(design, guess)
    allowed = _candidates(full0, measurements)
    full0, branch = _initial(full0, measurements, allowed, "frame" in identify)
    q, p = measurements.q, measurements.p
    keep = _select(_structural_jacobian(full0, q, branch) @ tmap)
    tk = tmap[:, keep]

    def fun(x: np.ndarray) -> np.ndarray:
        return residuals(full0 + tk @ x, q, branch, p).ravel()

    def jac(x: np.ndarray) -> np.ndarray:
        return measurement_jacobian(full0 + tk @ x, q, branch, p) @ tk

    x = np.zeros(len(keep))
    if keep:
        with np.errstate(all="ignore"):
            try:
                x = least_squares(
                    fun, x, jac=jac, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15
                ).x
            except (ValueError, np.linalg.LinAlgError):
                x = np.full(len(keep), np.nan)
    full = full0 + tk @ x
    _check_fit(design, measurements, full, branch)
    return _result(design, measurements, full, branch, names, keep, jac(x) if keep else None)


def _check_fit(design: Design, m: Measurements, full: np.ndarray, branch: np.ndarray) -> None:
    """Refuse (422 at ``measurements``) a fit that left the sane set: non-finite parameters,
    a length off by more than the design's reach, or a measured posture whose loop does not
    close at the solution (data that fit no design near the nominal one: wrong units,
    swapped fields, another robot); a length below the design's rules is such a fit too
    (L0 may come out a little below 0 for a design with L0 = 0: the answer's design then has
    L0 = 0, its ``parameters`` the value fitted)."""
    reach = design.L1 + design.L2
    lengths = full[:5]
    if (
        not np.all(np.isfinite(full))
        or np.any(np.abs(lengths - _nominal(design, None)[:5]) > reach)
        or np.any(lengths[1:] < MIN_LENGTH)
        or lengths[0] < -1e-3 * reach
    ):
        raise InputError(
            "the measurements fit no design near the nominal one (the least-squares fit "
            "diverged): check their units (m, rad), the order of q and p, and the nominal "
            "design",
            field="measurements",
        )
    ok = loop_state(full, m.q, branch).ok
    if not ok.all():
        i = int(np.flatnonzero(~ok)[0])
        raise InputError(
            f"the best fit of the measurements leaves measurements[{i}]'s loop open (q = "
            f"{m.q[i].tolist()}): the measurements fit no design near the nominal one",
            field=("measurements", i),
        )


def _result(
    design: Design,
    m: Measurements,
    full: np.ndarray,
    branch: np.ndarray,
    names: list[str],
    keep: list[int],
    jac: np.ndarray | None,
) -> CalibrationResult:
    """The answer of :func:`calibrate` at the solution ``full``."""
    res = residuals(full, m.q, branch, m.p)
    dof = 3 * len(m) - len(keep)
    std: dict[str, float] = {}
    cond = 1.0
    if jac is not None:
        with np.errstate(all="ignore"):
            sigma2 = float(np.sum(res**2)) / max(dof, 1)
            scale = np.linalg.norm(jac, axis=0)
            sv = np.linalg.svd(jac / scale, compute_uv=False) if np.isfinite(jac).all() else [0]
            cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf
            if math.isfinite(cond):
                cov = sigma2 * np.linalg.pinv(jac.T @ jac)
                std = {names[j]: float(np.sqrt(max(cov[k, k], 0.0))) for k, j in enumerate(keep)}
        if not (math.isfinite(cond) and all(map(math.isfinite, std.values()))):
            raise InputError(
                "the measurements' best fit is a singular point of the model (its Jacobian "
                "lost rank there): they fit no design near the nominal one",
                field="measurements",
            )
    legs = "L1_A" in names
    l1, l2 = 0.5 * (full[1] + full[2]), 0.5 * (full[3] + full[4])
    identified = Design(
        L0=max(float(full[0]), 0.0),
        L1=float(l1),
        L2=float(l2),
        link_radius=design.link_radius,
        joint_min=design.joint_min,
        joint_max=design.joint_max,
    )
    return CalibrationResult(
        design=identified,
        offsets=full[5:8].copy(),
        frame_position=full[8:11].copy(),
        frame_rotation=full[11:14].copy(),
        residuals=np.linalg.norm(res, axis=1),
        std=std,
        condition_number=cond,
        unidentified=[name for j, name in enumerate(names) if j not in keep],
        parameters={name: float(v) for name, v in zip(FULL_NAMES, full, strict=True)},
        assembly_modes=["+" if b > 0 else "-" for b in branch],
        leg_lengths={k: float(full[i]) for i, k in enumerate(FULL_NAMES[1:5], start=1)}
        if legs
        else None,
    )
