"""Dynamic identification: measured motions and torques -> the inertial parameters that they
determine (``docs/calibration.md``, *Dynamic identification*).

The torques are linear in the *standard parameters* of each link written about its own pivot
(:data:`STANDARD_NAMES`): mass ``m``, first moment ``X = m com L``, perpendicular inertia
about the pivot ``J = I_perp + m (com L)^2`` (the parallel-axis theorem), ``I_axial``; and in
the payload mass, the base inertia and the rotors. So ``tau = Y(q, qd, qdd) phi``. The
regressor ``Y`` is read off the product's compiled inverse dynamics
(:func:`planner.dynamics.inverse_dynamics`' kernel) by linearity: a link's translational
part is ``m F0 + X F1 + m a^2 F2`` (probed at com = 0, +1, -1), its rotational part
``I_perp Rp + I_axial Ra``, and ``F2 = Rp`` by the parallel-axis theorem (a test checks
``Y phi`` against :func:`~planner.dynamics.inverse_dynamics` for random parameters).

Not every standard parameter is seen by the data: the proximal mass has no effect (its pivot
is fixed on the axis), the distal mass acts as a point mass at C on the proximal links, the
payload as half a point mass at the tip of each distal link, the base inertia and the first
rotor both multiply theta1's acceleration. The *base parameters* are found numerically:
the columns of ``Y`` (scaled to unit norm) are taken in the order of :data:`PRIORITY` while
they raise the rank (:data:`RANK_TOL`); the rest are held at their priors (the request's
inertia, else the defaults) and named in ``unidentified``. The identified inertia is made a
valid :class:`~planner.dynamics.Inertia` by choosing the proximal mass (free: the data do
not see it) so the proximal centre of mass and ``I_perp`` are physical; anything still out
of the physical set is clipped and said in ``notes``.

Optional friction per actuator: ``tau_f = viscous qd + coulomb sign(qd)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from planner.design import Design
from planner.dynamics import _kernels
from planner.dynamics.inertia import Inertia, LinkInertia, check_gravity
from planner.dynamics.inverse import _inputs, _kinematics, _rates, inverse_dynamics
from planner.exceptions import InputError

__all__ = [
    "FRICTION_NAMES",
    "PRIORITY",
    "RANK_TOL",
    "STANDARD_NAMES",
    "IdentificationResult",
    "identify_inertia",
    "regressor",
    "standard_parameters",
]

#: How far below zero a physical-set constraint may end in the optimisers' answer.
_FEASIBLE_TOL = 1e-7

#: The standard parameters, the regressor's columns in this order (kg, kg m, kg m^2).
STANDARD_NAMES: tuple[str, ...] = (
    "proximal.mass",
    "proximal.first_moment",
    "proximal.I_pivot",
    "proximal.I_axial",
    "distal.mass",
    "distal.first_moment",
    "distal.I_pivot",
    "distal.I_axial",
    "payload.mass",
    "base.inertia",
    "rotor[0]",
    "rotor[1]",
    "rotor[2]",
)
#: The friction parameters (N m s/rad, N m), appended with ``friction``.
FRICTION_NAMES: tuple[str, ...] = (
    "friction.viscous[0]",
    "friction.viscous[1]",
    "friction.viscous[2]",
    "friction.coulomb[0]",
    "friction.coulomb[1]",
    "friction.coulomb[2]",
)
#: The order in which columns are taken for the base parameters: what a user can act on
#: first; the dependent ones (proximal and distal mass, payload, rotor[0]) come last so that
#: they are the ones held.
PRIORITY: tuple[str, ...] = (
    "base.inertia",
    "proximal.first_moment",
    "proximal.I_pivot",
    "proximal.I_axial",
    "distal.first_moment",
    "distal.I_pivot",
    "distal.I_axial",
    "rotor[1]",
    "rotor[2]",
    *FRICTION_NAMES,
    "distal.mass",
    "payload.mass",
    "rotor[0]",
    "proximal.mass",
)
#: A column that leaves the smallest singular value of the scaled columns taken before it
#: below this is a dependent (unidentified) direction.
RANK_TOL = 1e-7


def standard_parameters(design: Design, inertia: Inertia) -> np.ndarray:
    """The standard parameters (:data:`STANDARD_NAMES`) of ``inertia``, shape (13,)."""
    out = []
    for link, length in ((inertia.proximal, design.L1), (inertia.distal, design.L2)):
        a = link.com * length
        out += [link.mass, link.mass * a, link.I_perp + link.mass * a * a, link.I_axial]
    return np.array([*out, inertia.payload_mass, inertia.base_inertia, *inertia.rotor])


def _probe(design: Design, kin, qd, qdd, g, params: np.ndarray) -> np.ndarray:
    out = np.empty_like(kin.q)
    prm, q, passive, ok, qd1, qdd1, g1 = _inputs(params, kin, qd, qdd, g)
    _kernels.inverse_kernel(design.L1, design.L2, prm, q, passive, ok, qd1, qdd1, g1, out)
    return out


def regressor(
    design: Design,
    q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    *,
    assembly_mode: object = "+",
    gravity: object = (0.0, 0.0, -9.81),
    friction: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """``(Y, ok)``: Y of shape (N, 3, 13) (or 19 with friction) such that ``tau = Y phi``
    (module docstring), and ``ok`` (N,) where the posture assembles and is not singular."""
    g = check_gravity(gravity)
    kin = _kinematics(design, q, assembly_mode)
    n = kin.q.shape[0]
    qd2 = np.ascontiguousarray(_rates("qd", qd, n))
    qdd2 = np.ascontiguousarray(_rates("qdd", qdd, n))
    zero = np.zeros(len(_kernels.PARAMS))

    def run(values: dict[int, float]) -> np.ndarray:
        """The kernel's torques with the parameters ``values`` (index: value), others 0."""
        params = zero.copy()
        for index, v in values.items():
            params[index] = v
        return _probe(design, kin, qd2, qdd2, g, params)

    cols = []
    for k, length in enumerate((design.L1, design.L2)):
        base = 4 * k  # mass, com, I_perp, I_axial of this link in the kernel's order
        # translational part m F0 + X F1 + m a^2 F2 with a = com L: probed at com 0, +-1
        t0, tp, tm = (run({base: 1.0, base + 1: com}) for com in (0.0, 1.0, -1.0))
        cols += [t0, (tp - tm) / (2 * length), run({base + 2: 1.0}), run({base + 3: 1.0})]
    for index in range(8, 13):  # payload, base, rotors
        cols.append(run({index: 1.0}))
    if friction:
        for kind in (qd2, np.sign(qd2)):
            for j in range(3):
                col = np.zeros_like(qd2)
                col[:, j] = kind[:, j]
                cols.append(col)
    y = np.stack(cols, axis=2)
    y[~kin.ok] = np.nan
    return y, kin.ok


@dataclass(frozen=True, eq=False)
class IdentificationResult:
    """The answer of :func:`identify_inertia`.

    ``inertia``: a valid :class:`~planner.dynamics.Inertia`; ``friction``: (viscous (3,),
    coulomb (3,)) or None; ``base_parameters``: the identified parameters by name (standard
    parameters with the held ones' contributions at their priors); ``residual_rms``: N m, of
    ``tau`` against the identified model; ``unidentified``: the names held; ``notes``: any
    clipping to the physical set."""

    inertia: Inertia
    friction: tuple[np.ndarray, np.ndarray] | None
    base_parameters: dict[str, float]
    residual_rms: float
    unidentified: list[str]
    condition_number: float
    notes: list[str] = field(default_factory=list)


def _check_tau(tau: object, n: int) -> np.ndarray:
    return _rates("tau", tau, n)


def identify_inertia(
    design: Design,
    q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    tau: np.ndarray,
    *,
    assembly_mode: object = "+",
    gravity: object = (0.0, 0.0, -9.81),
    prior: Inertia | None = None,
    friction: bool = False,
) -> IdentificationResult:
    """Identify the inertial parameters (and friction) that the data determine.

    Raises
    ------
    InputError
        A posture that does not assemble or is singular (named ``q`` with its index), fewer
        torque samples than identifiable parameters (at ``tau``), a non-finite number.
    """
    prior = prior if prior is not None else Inertia.default(design)
    y, ok = regressor(
        design, q, qd, qdd, assembly_mode=assembly_mode, gravity=gravity, friction=friction
    )
    n = y.shape[0]
    t = _check_tau(tau, n)
    bad = np.flatnonzero(~ok)
    if bad.size:
        i = int(bad[0])
        raise InputError(
            f"q[{i}] does not assemble in assembly mode {assembly_mode!r} or is "
            "parallel-singular (the torques are undefined there)",
            field=("q", i),
        )
    names = list(STANDARD_NAMES) + (list(FRICTION_NAMES) if friction else [])
    phi0 = np.concatenate([standard_parameters(design, prior), np.zeros(6 if friction else 0)])
    ymat = y.reshape(3 * n, -1)
    order = [names.index(k) for k in PRIORITY if k in names]
    keep = _select(ymat, order)
    if 3 * n < len(keep) + 1:
        raise InputError(
            f"{n} samples give {3 * n} torque equations; the data's {len(keep)} identifiable "
            f"parameters need at least {(len(keep) + 1 + 2) // 3} samples",
            field="tau",
        )
    held = [j for j in range(len(names)) if j not in keep]
    rhs = t.ravel() - ymat[:, held] @ phi0[held]
    sub = ymat[:, keep]
    scale = np.linalg.norm(sub, axis=0)
    phi = phi0.copy()
    cond = 1.0
    if keep:  # data that see nothing (no motion, no gravity) identify nothing
        sol, *_ = np.linalg.lstsq(sub / scale, rhs, rcond=None)
        phi[keep] = sol / scale
        sv = np.linalg.svd(sub / scale, compute_uv=False)
        cond = float(sv[0] / sv[-1])
    inertia, notes = _physical(design, _realise(design, phi, phi0, keep, held, ymat), prior)
    fr = (phi[13:16].copy(), phi[16:19].copy()) if friction else None
    model = inverse_dynamics(
        design, inertia, q, qd, qdd, assembly_mode=assembly_mode, gravity=gravity
    ).tau
    if fr is not None:
        model = model + fr[0] * np.asarray(qd) + fr[1] * np.sign(np.asarray(qd))
    return IdentificationResult(
        inertia=inertia,
        friction=fr,
        base_parameters={names[j]: float(phi[j]) for j in sorted(keep)},
        residual_rms=float(np.sqrt(np.mean((model - t) ** 2))),
        unidentified=[names[j] for j in held],
        condition_number=cond,
        notes=notes,
    )


def _select(ymat: np.ndarray, order: list[int]) -> list[int]:
    norms = np.linalg.norm(ymat, axis=0)
    taken: list[int] = []
    for j in order:
        if norms[j] == 0:
            continue
        trial = ymat[:, [*taken, j]] / norms[[*taken, j]]
        if np.linalg.svd(trial, compute_uv=False)[-1] > RANK_TOL:
            taken.append(j)
    return taken


def _constraints(design: Design, phi: np.ndarray) -> np.ndarray:
    """The physical rules of standard parameters (13 first entries of ``phi``), each >= 0
    when kept: per link m (above a microgram), X, m L - X, I_axial, J - I_axial / 2 and
    ``m (J - I_axial / 2) - X^2`` (so that ``I_perp = J - X^2 / m >= I_axial / 2``); the
    payload, base and rotors >= 0."""
    out = []
    for k, length in enumerate((design.L1, design.L2)):
        m, x, j, ia = phi[4 * k : 4 * k + 4]
        out += [m - 1e-6, x, m * length - x, ia, j - ia / 2, m * (j - ia / 2) - x * x]
    return np.array([*out, *phi[8:13]])


def _realise(
    design: Design,
    phi: np.ndarray,
    phi0: np.ndarray,
    keep: list[int],
    held: list[int],
    ymat: np.ndarray,
) -> np.ndarray:
    """The member of the data's family of parameters nearest the prior that is physical.

    The held parameters whose columns lie in the span of the identified ones (an exact
    dependency: the data cannot see them) are free; every choice ``z`` of them, with the
    identified ones moved by ``-pinv(Y_id) Y_held (z - z0)``, gives the same torques. Among
    them, the one nearest the prior (relative to each prior's size) within
    :func:`_constraints` (SLSQP); ``phi`` itself when that fails or it is already physical."""
    from scipy.optimize import NonlinearConstraint, minimize

    if np.all(_constraints(design, phi) >= -1e-12):
        return phi
    sub, others = ymat[:, keep], ymat[:, held]
    comp, *_ = np.linalg.lstsq(sub, -others, rcond=None)
    miss = np.linalg.norm(sub @ comp + others, axis=0)
    norms = np.linalg.norm(others, axis=0)
    free = [k for k in range(len(held)) if miss[k] <= 1e-6 * norms[k]]  # a zero column too
    if not free:
        return phi
    idx = np.array([held[k] for k in free])
    scale = np.maximum(np.abs(phi0[idx]), 1e-6)

    def member(u: np.ndarray) -> np.ndarray:
        """The family's member with the free held parameters at ``phi0 + u scale``."""
        out = phi.copy()
        out[idx] = phi0[idx] + u * scale
        out[keep] += comp[:, free] @ (u * scale)
        return out

    def size(u: np.ndarray) -> float:
        return float(u @ u)

    physical = NonlinearConstraint(lambda u: _constraints(design, member(u)), 0.0, np.inf)
    fit = minimize(
        size, np.zeros(len(idx)), method="SLSQP", constraints=physical, options={"maxiter": 500}
    )
    best = member(fit.x)
    if fit.success:
        return best
    # SLSQP's line search can stop short on rounding alone (seen with BLAS summing in another
    # order on one core): the same problem by the interior-point method, from where it stopped
    fit = minimize(
        size, fit.x, method="trust-constr", constraints=physical, options={"maxiter": 2000}
    )
    best = member(fit.x)
    # feasible to the optimisers' own tolerance (SLSQP's successful answers end within ~4e-8)
    return best if np.all(_constraints(design, best) >= -_FEASIBLE_TOL) else phi


def _physical(design: Design, phi: np.ndarray, prior: Inertia) -> tuple[Inertia, list[str]]:
    """An :class:`Inertia` of the standard parameters ``phi`` (after :func:`_realise`):
    ``com = X / (m L)``, ``I_perp = J - m (com L)^2``; a value outside the physical set by
    more than the optimiser's tolerance (1e-6 relative) is clipped and said in the notes."""
    notes: list[str] = []
    links = []
    for k, (name, length) in enumerate((("proximal", design.L1), ("distal", design.L2))):
        m, x, j, ia = (float(v) for v in phi[4 * k : 4 * k + 4])
        if m <= 0:
            notes.append(f"{name}.mass identified as {m:.3g} <= 0: the prior's")
            m = getattr(prior, name).mass
        ia = _clip(ia, 0.0, j, f"{name}.I_axial", notes)
        com = _clip(x / (m * length), 1.0, 1.0, f"{name}.com", notes, upper=True)
        com = _clip(com, 0.0, 1.0, f"{name}.com", notes)
        perp = _clip(j - m * (com * length) ** 2, ia / 2, j, f"{name}.I_perp", notes)
        links.append(LinkInertia(m, com, max(perp, ia / 2), ia, name))
    rest = [_clip(float(phi[i]), 0.0, float(phi[i]), STANDARD_NAMES[i], notes) for i in (8, 9)]
    size = float(np.max(np.abs(phi[9:13])))  # the rotors' and base's scale
    rotor = [_clip(float(phi[10 + i]), 0.0, size, f"rotor[{i}]", notes) for i in range(3)]
    return (
        Inertia(
            proximal=links[0],
            distal=links[1],
            payload_mass=rest[0],
            base_inertia=rest[1],
            rotor=(rotor[0], rotor[1], rotor[2]),
        ),
        notes,
    )


def _clip(
    value: float, bound: float, size: float, label: str, notes: list[str], *, upper: bool = False
) -> float:
    """``value`` kept on the right side of ``bound`` (below it with ``upper``): silently
    within 1e-6 of ``size`` (the optimiser's tolerance), else clipped with a note."""
    beyond = value - bound if upper else bound - value
    if beyond <= 0:
        return value
    if beyond > 1e-6 * max(abs(size), abs(bound), 1e-12):
        side = "above" if upper else "below"
        notes.append(f"{label} identified as {value:.4g}, {side} {bound:.4g}: clipped")
    return bound
