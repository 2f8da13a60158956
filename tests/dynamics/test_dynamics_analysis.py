"""The design side: the inertia map over (theta2, theta3) and the torque statistics."""

from __future__ import annotations

import numpy as np
from dynamics_reference import mass_matrix_by_polarisation

from planner import Design
from planner.dynamics import Inertia
from planner.dynamics.analysis import inertia_map, torque_stats


def test_inertia_map_holds_for_every_theta1() -> None:
    """The map is computed at theta1 = 0; M from the kinetic energy's finite differences
    (independent of the product's M) at random theta1 gives the same eigenvalues."""
    design = Design.default()
    inertia = Inertia.default(design)
    imap = inertia_map(design, inertia, resolution=9)
    rng = np.random.default_rng(0)
    checked = 0
    for i in range(9):
        for j in range(9):
            if not np.all(np.isfinite(imap.eigenvalues[i, j])):
                continue
            q = np.array([[rng.uniform(-3, 3), imap.theta2[i], imap.theta3[j]]])
            ref = np.linalg.eigvalsh(mass_matrix_by_polarisation(design, inertia, "+", q))[0]
            np.testing.assert_allclose(imap.eigenvalues[i, j], ref, rtol=1e-6)
            checked += 1
    assert checked > 20
    assert imap.largest == np.nanmax(imap.eigenvalues)


def test_torque_stats_of_a_sine() -> None:
    """Peak A and RMS A / sqrt(2) of A sin over whole periods, unevenly sampled."""
    t = np.sort(np.concatenate([[0.0, 2.0], np.random.default_rng(1).uniform(0, 2, 20000)]))
    amp = np.array([1.0, 2.5, 0.3])
    tau = amp * np.sin(2 * np.pi * t)[:, None]
    stats = torque_stats(t, tau)
    np.testing.assert_allclose(stats.peak, amp, rtol=1e-6)
    np.testing.assert_allclose(stats.rms, amp / np.sqrt(2), rtol=1e-4)


def test_serial_comparison_cells_and_values() -> None:
    """Each compared cell's working mode is its posture's sign triple, its values are the
    largest eigenvalues of the two robots' M there (the five-bar's from the kinetic energy's
    finite differences), the cells keep the margins, and on the default design the five-bar's
    reflected inertia is below the serial arm's in the median of every working mode."""
    from planner import conditioning, forward_batch
    from planner.dynamics.analysis import serial_comparison
    from planner.dynamics.serial import SerialArm, serial_coordinates
    from planner.kinematics import WORKING_MODES

    design = Design.default()
    inertia = Inertia.default(design)
    cmp = serial_comparison(design, inertia, resolution=12)
    arm = SerialArm(design, inertia)
    cells = np.argwhere(cmp.working_mode >= 0)
    assert len(cells) > 30
    for i, j in cells[::5]:
        q = np.array([[0.0, cmp.theta2[i], cmp.theta3[j]]])
        fb = forward_batch(design, q, "+")
        signs = "".join("+" if s > 0 else "-" for s in fb.working_mode_signs[0])
        assert WORKING_MODES[cmp.working_mode[i, j]] == signs
        c = conditioning(design, fb.q, fb.passive, fb.w)
        assert c.kappa_A[0] <= 10 and c.min_serial[0] >= 0.05
        m = mass_matrix_by_polarisation(design, inertia, "+", q)[0]
        np.testing.assert_allclose(cmp.parallel[i, j], np.linalg.eigvalsh(m)[-1], rtol=1e-6)
        np.testing.assert_allclose(
            cmp.parallel_planar[i, j], np.linalg.eigvalsh(m[1:, 1:])[-1], rtol=1e-6
        )
        ms = arm.mass_matrix(serial_coordinates(fb.q, fb.passive))[0]
        np.testing.assert_allclose(cmp.serial[i, j], np.linalg.eigvalsh(ms)[-1], rtol=1e-12)
    assert np.all(np.isnan(cmp.parallel[cmp.working_mode < 0]))
    stats = cmp.by_mode()
    assert sum(int(r["cells"]) for r in stats.values()) == len(cells)
    assert all(r["ratio_median"] < 1 for r in stats.values())


def test_cycle_torques_of_both_robots() -> None:
    """cycle_torques: the five-bar's statistics are those of its inverse dynamics; the
    serial arm's of its own torques along the same motion of P (serial_motion)."""
    from planner.dynamics import inverse_dynamics
    from planner.dynamics.analysis import cycle_torques
    from planner.dynamics.serial import SerialArm, serial_motion

    design = Design.default()
    inertia = Inertia.default(design)
    t = np.linspace(0.0, 2.0, 401)
    q = np.array([0.1, 2.0, 1.0]) + np.array([0.3, 0.2, -0.2]) * np.sin(np.pi * t)[:, None]
    qd = np.array([0.3, 0.2, -0.2]) * np.pi * np.cos(np.pi * t)[:, None]
    qdd = -np.array([0.3, 0.2, -0.2]) * np.pi**2 * np.sin(np.pi * t)[:, None]
    par, ser = cycle_torques(design, inertia, t, q, qd, qdd)
    tau = inverse_dynamics(design, inertia, q, qd, qdd).tau
    np.testing.assert_allclose(par.peak, np.max(np.abs(tau), axis=0))
    arm = SerialArm(design, inertia)
    tau_s = arm.inverse_dynamics(*serial_motion(design, q, qd, qdd), gravity=(0, 0, -9.81))
    np.testing.assert_allclose(ser.rms, torque_stats(t, tau_s).rms)
    assert not np.allclose(par.rms, ser.rms, rtol=0.05)  # two robots, two answers


def test_inertia_map_figure_and_report_command() -> None:
    """The named figure renders; planner inertia-report prints both tables for both designs
    (small grid and few samples to stay fast)."""
    from typer.testing import CliRunner

    from planner.plotting import render_figure
    from planner_cli import app

    png = render_figure("inertia_map", Design.default(), n=24)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    r = CliRunner().invoke(app, ["inertia-report", "--resolution", "16", "--samples", "200"])
    assert r.exit_code == 0, r.output
    rows = [line for line in r.output.splitlines() if line.startswith("| default")]
    assert any("| five-bar |" in line for line in rows)
    assert any("| serial |" in line for line in rows)
    assert "| paper-optimum | +-+ |" in r.output
