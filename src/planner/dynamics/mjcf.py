"""The robot as MuJoCo sees it: an MJCF model of the closed chain (``planner mjcf``,
``GET /v1/design/mjcf``), so that a user can simulate a planned trajectory.

MuJoCo simulates trees: the chain is cut at P into two legs hanging from the turning base,
and the loop is closed again by an equality ``connect`` between two **sites** at the distal
tips (a body-based ``connect`` would fix its second anchor from the model's initial pose,
where the tips are apart, and keep that offset). Joints, in MuJoCo's order of degrees of
freedom: ``theta1`` (the base, about +y), ``theta2``, ``theta4_rel`` (= theta4 - theta2),
``theta3``, ``theta5_rel`` (= theta5 - theta3), every planar hinge about -z of the base body
so that a positive angle turns the link from A->B towards e(theta1) as in
``docs/conventions.md``. The rotor inertias are the actuated joints' ``armature``; the three
motors are ``motor`` actuators (``ctrl`` = torque, N m). Nothing in MuJoCo picks the assembly
mode: the keyframe ``home`` holds an assembled posture of the requested one (start a
simulation from it, or from any qpos whose passive angles come from the product's forward
kinematics).

This module writes text only; it does not import mujoco.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planner.design import Design
from planner.dynamics.inertia import DEFAULT_GRAVITY, Inertia, LinkInertia, check_gravity
from planner.exceptions import InputError
from planner.kinematics import forward_batch

__all__ = ["DEFAULT_HOME", "JOINT_NAMES", "MIN_BODY_INERTIA", "mjcf_qpos", "to_mjcf"]

#: MuJoCo's joint names in the order of its degrees of freedom (and of ``qpos``).
JOINT_NAMES = ("theta1", "theta2", "theta4_rel", "theta3", "theta5_rel")
#: The keyframe posture when none is given, rad (assembled for the reference designs).
DEFAULT_HOME = (0.0, 2.0, 1.0)
#: MuJoCo refuses moving bodies without mass or inertia: a zero of the inertial model is
#: written as this (kg, kg m^2), far below anything that shows in a torque.
MIN_BODY_INERTIA = 1e-10


def _f(x: float) -> str:
    """A number as MJCF text: the shortest form that reads back as the same double (MuJoCo's
    checks are exact: 12 digits once broke ``A + B >= C`` at ``I_axial = 2 I_perp``)."""
    return repr(float(x))


def _vec(*xs: float) -> str:
    return " ".join(_f(x) for x in xs)


def mjcf_qpos(design: Design, q: np.ndarray, assembly_mode: str = "+") -> np.ndarray:
    """MuJoCo ``qpos`` (N, 5) of actuated joints q (N, 3) in one assembly mode, in the order
    of :data:`JOINT_NAMES` (the passive angles from the product's forward kinematics); NaN
    rows where q does not assemble."""
    batch = forward_batch(design, q, assembly_mode)
    t = batch.q
    out = np.stack(
        [t[:, 0], t[:, 1], batch.passive[:, 0] - t[:, 1], t[:, 2], batch.passive[:, 1] - t[:, 2]],
        axis=1,
    )
    out[~batch.ok] = np.nan
    return out


def _inertial(link: LinkInertia, length: float) -> str:
    m = max(link.mass, MIN_BODY_INERTIA)
    ip = max(link.I_perp, MIN_BODY_INERTIA)
    # the model accepts I_axial up to 2 I_perp (1 + 1e-12); MuJoCo's check of the triangle
    # inequality (two moments sum to at least the third) is exact, so the axial moment is
    # written at most 2 I_perp (a change of at most 1e-12 of it)
    ia = min(max(link.I_axial, MIN_BODY_INERTIA), 2.0 * ip)
    # along the body's local +y: the axial moment is the y one
    return (
        f'<inertial pos="{_vec(0, link.com * length, 0)}" mass="{_f(m)}" '
        f'diaginertia="{_vec(ip, ia, ip)}"/>'
    )


#: Cells per axis of the (theta2, theta3) grid searched for a keyframe when
#: :data:`DEFAULT_HOME` does not assemble.
_HOME_GRID = 64


def _default_home(design: Design, assembly_mode: str) -> tuple[np.ndarray, np.ndarray]:
    """The keyframe of a model given no ``home``: :data:`DEFAULT_HOME` when it assembles,
    else the posture of a (theta2, theta3) grid nearest to it that does (theta1 = 0), so that
    every design with an assembled posture has a model (a design of short distal links does
    not assemble at the default). InputError (no field: the design's) when none does."""
    q = np.asarray(DEFAULT_HOME, dtype=float)
    qpos = mjcf_qpos(design, q.reshape(1, 3), assembly_mode)[0]
    if np.all(np.isfinite(qpos)):
        return q, qpos
    t = np.linspace(-np.pi, np.pi, _HOME_GRID, endpoint=False)
    t2, t3 = (a.ravel() for a in np.meshgrid(t, t, indexing="ij"))
    grid = np.column_stack([np.zeros_like(t2), t2, t3])
    rows = mjcf_qpos(design, grid, assembly_mode)
    ok = np.flatnonzero(np.all(np.isfinite(rows), axis=1))
    if not len(ok):
        raise InputError(
            f"the design assembles in no posture of assembly mode {assembly_mode!r}: no "
            "keyframe 'home' can be written (check L0, L1, L2)"
        )
    best = ok[np.argmin(np.linalg.norm(grid[ok] - q, axis=1))]
    return grid[best], rows[best]


def to_mjcf(
    design: Design,
    inertia: Inertia | None = None,
    *,
    gravity: Sequence[float] = DEFAULT_GRAVITY,
    home: Sequence[float] | None = None,
    assembly_mode: str = "+",
    torque_limits: Sequence[float] | None = None,
    timestep: float = 1e-4,
    loop_solref: float | None = None,
) -> str:
    """The MJCF text of ``design`` with ``inertia`` (default :meth:`Inertia.default`).

    Parameters
    ----------
    gravity : m/s^2, base frame (MuJoCo's ``option gravity``)
    home : actuated joints of the keyframe ``home``, rad (default :data:`DEFAULT_HOME`, or
        when it does not assemble the nearest posture of a grid that does)
    assembly_mode : the keyframe's assembly mode, '+' or '-'
    torque_limits : 3 N m, optional: the motors' ``ctrlrange``
    timestep : s; RK4 at 1e-4 s follows the product's trajectories to ~1e-8 rad over short
        horizons (``docs/dynamics.md``), with the loop's ``solref`` at 20 timesteps
    loop_solref : s, the loop's ``solref`` time constant when given (MuJoCo wants at least
        2 timesteps); the simulator (:mod:`planner.simulation`) keeps it at 2 ms whatever its
        step

    Raises
    ------
    InputError
        ``home`` does not assemble in ``assembly_mode`` (field ``home``), or bad gravity.
    """
    inertia = inertia if inertia is not None else Inertia.default(design)
    g = check_gravity(gravity)
    if home is None:
        home_q, qpos = _default_home(design, assembly_mode)
    else:
        home_q = np.asarray(home, dtype=float)
        qpos = mjcf_qpos(design, home_q.reshape(1, 3), assembly_mode)[0]
    if not np.all(np.isfinite(qpos)):
        raise InputError(
            f"home = {home_q.tolist()} does not assemble in assembly mode {assembly_mode!r}",
            field="home",
        )
    l0, l1, l2 = design.L0, design.L1, design.L2
    radius = max(design.link_radius, 0.005)
    rotor = [max(r, 0.0) for r in inertia.rotor]
    ib = max(inertia.base_inertia, MIN_BODY_INERTIA)
    mp = max(inertia.payload_mass, MIN_BODY_INERTIA)
    tiny = _vec(MIN_BODY_INERTIA, MIN_BODY_INERTIA, MIN_BODY_INERTIA)
    geom = 'contype="0" conaffinity="0" group="1"'

    def leg(side: str, y: float, joint: str, arm: float, passive: str, tip: str) -> list[str]:
        lines = [
            f'      <body name="proximal_{side}" pos="{_vec(0, y, 0)}">',
            f'        <joint name="{joint}" type="hinge" axis="0 0 -1" armature="{_f(arm)}"/>',
            f"        {_inertial(inertia.proximal, l1)}",
            f'        <geom type="capsule" fromto="0 0 0 0 {_f(l1)} 0" size="{_f(radius)}" '
            f'rgba="0.3 0.5 0.8 1" {geom}/>',
            f'        <body name="distal_{side}" pos="{_vec(0, l1, 0)}">',
            f'          <joint name="{passive}" type="hinge" axis="0 0 -1"/>',
            f"          {_inertial(inertia.distal, l2)}",
            f'          <geom type="capsule" fromto="0 0 0 0 {_f(l2)} 0" '
            f'size="{_f(radius)}" rgba="0.8 0.5 0.3 1" {geom}/>',
            f'          <site name="{tip}" pos="{_vec(0, l2, 0)}" size="{_f(radius)}"/>',
        ]
        if side == "C":
            lines += [
                f'          <body name="payload" pos="{_vec(0, l2, 0)}">',
                f'            <inertial pos="0 0 0" mass="{_f(mp)}" diaginertia="{tiny}"/>',
                "          </body>",
            ]
        return [*lines, "        </body>", "      </body>"]

    ctrl = ""
    actuators = []
    for j, name in enumerate(("theta1", "theta2", "theta3")):
        if torque_limits is not None:
            lim = float(torque_limits[j])
            ctrl = f' ctrllimited="true" ctrlrange="{_vec(-lim, lim)}"'
        actuators.append(f'    <motor name="{name}" joint="{name}" gear="1"{ctrl}/>')
    solref = _vec(20 * timestep if loop_solref is None else loop_solref, 1)
    lines = [
        '<mujoco model="hybrid-manipulator">',
        "  <!-- the 3-DOF hybrid manipulator (a five-bar A-C-P-D-B turning about AB), written",
        "       by the planner: the loop is cut at P and closed by the connect 'loop_P' -->",
        '  <compiler angle="radian" autolimits="true"/>',
        f'  <option gravity="{_vec(*g)}" timestep="{_f(timestep)}" integrator="RK4"/>',
        "  <worldbody>",
        '    <body name="base" pos="0 0 0">',
        f'      <joint name="theta1" type="hinge" axis="0 1 0" armature="{_f(rotor[0])}"/>',
        f'      <inertial pos="0 0 0" mass="1" diaginertia="{_vec(ib, ib, ib)}"/>',
        f'      <geom type="capsule" fromto="{_vec(0, -l0 / 2 - radius, 0)} '
        f'{_vec(0, l0 / 2 + radius, 0)}" size="{_f(radius * 1.5)}" rgba="0.4 0.4 0.4 1" '
        f"{geom}/>",
        *leg("C", -l0 / 2, "theta2", rotor[1], "theta4_rel", "tip_C"),
        *leg("D", l0 / 2, "theta3", rotor[2], "theta5_rel", "tip_D"),
        "    </body>",
        "  </worldbody>",
        "  <equality>",
        f'    <connect name="loop_P" site1="tip_C" site2="tip_D" solref="{solref}" '
        'solimp="0.9999 0.9999 0.001"/>',
        "  </equality>",
        "  <actuator>",
        *actuators,
        "  </actuator>",
        "  <keyframe>",
        f'    <key name="home" qpos="{_vec(*qpos)}"/>',
        "  </keyframe>",
        "</mujoco>",
    ]
    return "\n".join(lines) + "\n"
