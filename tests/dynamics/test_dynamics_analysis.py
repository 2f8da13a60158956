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
