"""The calibration model against the product's kinematics and its Jacobian against finite
differences."""

from __future__ import annotations

import numpy as np
from calibration_factories import NOMINAL, random_valid, true_parameters

from planner import Manipulator, forward_batch
from planner.calibration.model import (
    FULL_NAMES,
    loop_state,
    measurement_jacobian,
    residuals,
    rotation_matrix,
)


def test_equal_legs_are_the_products_kinematics() -> None:
    q, modes = random_valid(40, seed=3)
    full = np.zeros(len(FULL_NAMES))
    full[:5] = (NOMINAL.L0, NOMINAL.L1, NOMINAL.L1, NOMINAL.L2, NOMINAL.L2)
    branch = np.where(np.asarray(modes) == "+", 1.0, -1.0)
    state = loop_state(full, q, branch)
    ref = forward_batch(NOMINAL, q, branch)
    assert state.ok.all() and ref.ok.all()
    np.testing.assert_allclose(state.p3, ref.p, atol=1e-12)
    np.testing.assert_allclose(state.passive, ref.passive, atol=1e-10)
    assert np.array_equal(state.working_mode_signs, ref.working_mode_signs)


def test_the_q_columns_are_the_products_a_inverse_b() -> None:
    """dP/dq of the model = A^-1 B of planner.kinematics (an independent derivation)."""
    q, modes = random_valid(10, seed=5)
    full = np.zeros(len(FULL_NAMES))
    full[:5] = (NOMINAL.L0, NOMINAL.L1, NOMINAL.L1, NOMINAL.L2, NOMINAL.L2)
    branch = np.where(np.asarray(modes) == "+", 1.0, -1.0)
    p = loop_state(full, q, branch).p3  # identity frame: residual = p - P
    jac = measurement_jacobian(full, q, branch, p).reshape(len(q), 3, -1)
    robot = Manipulator(NOMINAL)
    for i in range(len(q)):
        a, b = robot.jacobians(robot.posture(q[i], modes[i]))
        np.testing.assert_allclose(-jac[i, :, 5:8], np.linalg.solve(a, b), atol=1e-10)


def test_jacobian_against_finite_differences() -> None:
    full = true_parameters(seed=7, legs=True)
    full[11:14] = [0.3, -0.2, 0.5]  # a rotation well away from identity
    q, modes = random_valid(12, seed=8)
    branch = np.where(np.asarray(modes) == "+", 1.0, -1.0)
    p = np.random.default_rng(0).normal(0.0, 0.3, size=(len(q), 3))
    jac = measurement_jacobian(full, q, branch, p)
    h = 1e-6
    for k in range(len(FULL_NAMES)):
        step = np.zeros(len(FULL_NAMES))
        step[k] = h
        fd = (residuals(full + step, q, branch, p) - residuals(full - step, q, branch, p)) / (2 * h)
        np.testing.assert_allclose(jac[:, k], fd.ravel(), atol=1e-8, err_msg=FULL_NAMES[k])


def test_rotation_matrix_is_rodrigues() -> None:
    from scipy.spatial.transform import Rotation

    for phi in ([0.0, 0.0, 0.0], [1e-9, 0, 2e-9], [0.3, -0.2, 0.5], [2.0, 1.0, -1.0]):
        np.testing.assert_allclose(
            rotation_matrix(np.array(phi)), Rotation.from_rotvec(phi).as_matrix(), atol=1e-14
        )
