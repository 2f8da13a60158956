"""Actuator torques along a timed path: what the torque limits of the timing need.

Along a path q(s) timed by s(t), ``qd = q' sd`` and ``qdd = q' sdd + q'' sd^2``, and since
the velocity-product terms of the inverse dynamics are quadratic in qd,

    tau = a(s) sdd + b(s) sd^2 + c(s),   a = M q',  b = M q'' + h_v(q, q'),  c = gravity,

the form toppra's second-order constraints take (:func:`TorqueModel.path_coefficients`).
Slowing a motion uniformly in time by a factor c scales the dynamic part ``a sdd + b sd^2``
by c^2 and leaves gravity as it is, so the largest c that keeps every ``|tau_j| <= limit_j``
has a closed form (:func:`torque_time_scale`). No toppra here: this module serves the toppra
constraint, the fits, the ruckig check and the dense re-check alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.design import Design
from planner.dynamics import DEFAULT_GRAVITY, Inertia, check_gravity, inverse_dynamics
from planner.dynamics.inverse import inverse_dynamics_terms
from planner.exceptions import TimingInfeasibleError

__all__ = [
    "MIN_TIME_SCALE",
    "TorqueModel",
    "gravity_at_start",
    "gravity_excess",
    "torque_time_scale",
]

#: Smallest uniform slow-down :func:`torque_time_scale` answers: where gravity alone takes a
#: joint's whole torque somewhere, only an infinitely slow motion would hold it; the dense
#: re-check then fails (and names the torque rule) instead of a motion 1000 times slower.
MIN_TIME_SCALE = 1e-3


@dataclass(frozen=True, eq=False)
class TorqueModel:
    """The robot's inverse dynamics in one assembly mode under one gravity.

    Parameters
    ----------
    design, inertia : the robot (``inertia`` None: :meth:`Inertia.default` of the design)
    gravity : shape (3,), m/s^2
    assembly_mode : '+' or '-'
    """

    design: Design
    inertia: Inertia | None = None
    gravity: tuple[float, float, float] = DEFAULT_GRAVITY
    assembly_mode: str = "+"

    def __post_init__(self) -> None:
        if self.inertia is None:
            object.__setattr__(self, "inertia", Inertia.default(self.design))
        object.__setattr__(self, "gravity", tuple(check_gravity(self.gravity).tolist()))

    def _id(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, g: object) -> np.ndarray:
        assert self.inertia is not None
        return inverse_dynamics(
            self.design, self.inertia, q, qd, qdd, assembly_mode=self.assembly_mode, gravity=g
        ).tau

    def torques(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """tau (M, 3), N m, of samples (M, 3) each (NaN where a posture is singular)."""
        return self._id(q, qd, qdd, self.gravity)

    def split(
        self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(dynamic part, gravity part) of tau, each (M, 3): tau = dynamic + gravity."""
        zero = np.zeros_like(np.atleast_2d(q))
        dyn, grav = self._terms(q, [(qd, qdd, (0.0, 0.0, 0.0)), (zero, zero, self.gravity)])
        return dyn, grav

    def _terms(self, q: np.ndarray, terms: list) -> list[np.ndarray]:
        assert self.inertia is not None
        return inverse_dynamics_terms(
            self.design, self.inertia, q, terms, assembly_mode=self.assembly_mode
        )

    def path_coefficients(
        self, q: np.ndarray, d1: np.ndarray, d2: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(a, b, c), each (G, 3), of ``tau = a sdd + b sd^2 + c`` at path points with
        q, q', q'' (G, 3)."""
        zero = np.zeros_like(q)
        g0 = (0.0, 0.0, 0.0)
        a, b, c = self._terms(q, [(zero, d1, g0), (d1, d2, g0), (zero, zero, self.gravity)])
        return a, b, c


def torque_time_scale(
    dynamic: np.ndarray, gravity: np.ndarray, limit: np.ndarray, target: float = 1.0
) -> float:
    """The largest c in (0, 1] with ``|c^2 target dynamic + gravity| <= limit`` at every
    sample (rows of (M, 3) arrays; NaN rows are ignored): the exact uniform slow-down with
    ``c^2`` a further ``target`` of it, so that a margin is kept on the *dynamic* part of the
    torque, the part the slow-down scales. (A margin taken off the limit instead would eat
    most of a joint's room where gravity alone takes nearly all of it: 1e-3 of the limit cost
    up to 1 % in time where gravity held 95 % of it, issue 36.)

    Raises
    ------
    TimingInfeasibleError
        Gravity alone breaks a limit somewhere: no slowing down helps.
    """
    limit = np.asarray(limit, dtype=float)
    good = np.all(np.isfinite(dynamic) & np.isfinite(gravity), axis=1)
    d, g = dynamic[good], gravity[good]
    over = np.abs(g) > limit
    if np.any(over):
        i, j = np.argwhere(over)[0]
        raise TimingInfeasibleError(
            f"gravity alone needs |tau{j + 1}| = {abs(g[i, j]):.6g} N m on the path, above "
            f"the torque limit {limit[j]:.6g} N m: no timing can hold it"
        )
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(d > 0, (limit - g) / d, np.where(d < 0, (limit + g) / -d, np.inf))
    c2 = float(np.min(room, initial=np.inf)) * target
    return float(np.sqrt(min(max(c2, MIN_TIME_SCALE**2), 1.0)))


def gravity_excess(
    model: TorqueModel, q: np.ndarray, limit: np.ndarray
) -> tuple[int, float] | None:
    """(joint index, |tau_j|) of the first joint whose gravity torque at rest at posture q
    (3,) exceeds its limit, or None."""
    _, g = model.split(q[None], np.zeros((1, 3)), np.zeros((1, 3)))
    over = np.abs(g[0]) > np.asarray(limit)
    if not np.any(over):
        return None
    j = int(np.argmax(over))
    return j, float(abs(g[0, j]))


def gravity_at_start(
    design: Design,
    q_start: np.ndarray,
    assembly_mode: str,
    limits: object | None,
    inertia: Inertia | None,
    gravity: object,
) -> str | None:
    """The ``invalid_start`` message when gravity alone, at rest at ``q_start`` (3,), needs
    more torque than a joint's limit (no motion can leave that posture), else None (also
    without ``limits.torque``). The one rule of :func:`planner.solve`,
    :func:`planner.planning.plan_cartesian` and the sequences, so that they name the joint and
    the value alike."""
    torque = getattr(limits, "torque", None)
    if torque is None:
        return None
    model = TorqueModel(design, inertia, gravity, assembly_mode)  # type: ignore[arg-type]
    excess = gravity_excess(model, np.asarray(q_start, dtype=float), np.asarray(torque, float))
    if excess is None:
        return None
    j, value = excess
    return (
        f"invalid start: gravity alone needs |tau{j + 1}| = {value:.6g} N m at rest there, "
        f"above limits.torque[{j}] = {float(torque[j]):.6g} N m"
    )
