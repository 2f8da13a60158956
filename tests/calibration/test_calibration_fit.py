"""Kinematic calibration: exact recovery without noise, accuracy with noise, identifiability
and bad input."""

from __future__ import annotations

import numpy as np
import pytest
from calibration_factories import NOMINAL, measure, random_valid, true_parameters

from planner import Design, forward_batch
from planner.calibration import Measurements, calibrate, suggest_poses
from planner.calibration.model import FULL_NAMES, rotation_matrix
from planner.exceptions import InputError


def _expected(full: np.ndarray) -> np.ndarray:
    """The true parameters as the calibration must report them with offsets[0] held at 0:
    theta1's zero turns P about y, which the frame absorbs (R' = Ry(-o) R, t' = Ry(-o) t)."""
    from scipy.spatial.transform import Rotation

    out = full.copy()
    ry = rotation_matrix(np.array([0.0, -full[5], 0.0]))
    out[5] = 0.0
    out[8:11] = ry @ full[8:11]
    out[11:14] = Rotation.from_matrix(ry @ rotation_matrix(full[11:14])).as_rotvec()
    return out


def test_noise_free_recovers_every_parameter() -> None:
    full = true_parameters(seed=11)
    q, modes = random_valid(30, seed=12)
    result = calibrate(NOMINAL, measure(full, q, modes, with_modes=False))
    assert result.unidentified == ["offsets[0]"]
    got = np.array([result.parameters[n] for n in FULL_NAMES])
    np.testing.assert_allclose(got, _expected(full), atol=1e-9)
    assert result.residual_max < 1e-12
    assert result.assembly_modes == modes  # the nearest branch is the true one
    assert np.isfinite(result.condition_number) and result.condition_number > 1


def test_known_frame_identifies_theta1_offset() -> None:
    full = true_parameters(seed=13)
    q, modes = random_valid(30, seed=14)
    frame = (full[8:11], full[11:14])
    result = calibrate(
        NOMINAL, measure(full, q, modes), identify=["lengths", "offsets"], frame=frame
    )
    assert result.unidentified == []
    np.testing.assert_allclose(result.offsets, full[5:8], atol=1e-11)


def test_leg_lengths_apart() -> None:
    full = true_parameters(seed=15, legs=True)
    q, modes = random_valid(30, seed=16)
    result = calibrate(
        NOMINAL, measure(full, q, modes), identify=["leg_lengths", "offsets", "frame"]
    )
    assert result.leg_lengths is not None
    got = np.array([result.parameters[n] for n in FULL_NAMES])
    np.testing.assert_allclose(got, _expected(full), atol=1e-9)
    assert result.design.L1 == pytest.approx(0.5 * (full[1] + full[2]), abs=1e-9)


def test_noisy_suggested_poses_predict_held_out_points() -> None:
    full = true_parameters(seed=17)
    poses = suggest_poses(NOMINAL, 50, seed=1)
    assert len(set(poses.working_mode)) >= 4  # spread over the working modes
    m = measure(full, poses.q, poses.assembly_mode, noise=5e-5, seed=2)
    result = calibrate(NOMINAL, m)
    q_out, modes_out = random_valid(200, seed=18)
    truth = measure(full, q_out, modes_out).p
    pred = result.predict(q_out, np.where(np.asarray(modes_out) == "+", 1.0, -1.0))
    rms = float(np.sqrt(np.mean(np.sum((pred - truth) ** 2, axis=1))))
    assert rms <= 1e-4
    # the standard deviations are of the size of the errors (a factor of a few)
    for name in ("L0", "offsets[1]", "frame.position[0]"):
        assert 0 < result.std[name] < 1e-3
    assert 0.03e-3 < result.residual_rms < 0.15e-3


def test_rank_deficiency_is_named_not_guessed() -> None:
    """One in-plane posture turned about AB (theta1 varies, theta2 and theta3 fixed): P runs
    on one circle, which fixes only two in-plane numbers of the five lengths and offsets; the
    answer names what it holds, with finite numbers."""
    full = true_parameters(seed=19)
    q, modes = random_valid(30, seed=20)
    q[:, 1:] = q[0, 1:]
    modes = [modes[0]] * 30
    result = calibrate(NOMINAL, measure(full, q, modes))
    assert "offsets[0]" in result.unidentified
    assert len(result.unidentified) >= 4  # 5 - 2 in-plane numbers, and offsets[0]
    assert all(np.isfinite(v) for v in result.std.values())
    assert np.isfinite(result.condition_number)
    assert result.residual_max < 1e-9  # still fits: the held directions change nothing


def test_too_few_measurements() -> None:
    full = true_parameters(seed=21)
    q, modes = random_valid(4, seed=22)
    with pytest.raises(InputError) as err:
        calibrate(NOMINAL, measure(full, q, modes))
    assert err.value.field_path == ("measurements",)


def test_unreachable_measurement_is_named() -> None:
    full = true_parameters(seed=23)
    q, modes = random_valid(20, seed=24)
    m = measure(full, q, modes)
    qbad = m.q.copy()
    qbad[7] = [0.0, np.pi, 0.0]  # |CD| = L0 + 2 L1 = 0.9 m, the most there is
    # a design whose distal links (2 L2 < 0.9 m) close every other measured posture's loop
    c = np.stack([-0.25 + 0.2 * np.cos(qbad[:, 1]), 0.2 * np.sin(qbad[:, 1])], axis=1)
    d = np.stack([0.25 + 0.2 * np.cos(qbad[:, 2]), 0.2 * np.sin(qbad[:, 2])], axis=1)
    cd = np.linalg.norm(d - c, axis=1)
    others = np.delete(cd, 7).max()
    assert others < 0.899
    short = Design(L0=0.5, L1=0.2, L2=0.25 * (others + 0.9))
    with pytest.raises(InputError) as err:
        calibrate(short, Measurements(qbad, m.p))
    assert err.value.field_path == ("measurements", 7, "q")


def test_nan_is_named() -> None:
    q = np.zeros((10, 3))
    p = np.zeros((10, 3))
    p[3, 1] = np.nan
    with pytest.raises(InputError) as err:
        Measurements(q, p)
    assert err.value.field_path == ("measurements", 3, "p")


def test_wrong_measured_mode_is_named() -> None:
    full = true_parameters(seed=25)
    q, modes = random_valid(20, seed=26)
    m = measure(full, q, modes)
    wm: list[str | None] = [None] * 20
    actual = forward_batch(NOMINAL, q[5], modes[5]).working_mode_signs[0]
    wrong = "".join("-" if s > 0 else "+" for s in actual)
    wm[5] = wrong
    with pytest.raises(InputError) as err:
        calibrate(NOMINAL, Measurements(m.q, m.p, working_mode=wm))
    assert err.value.field_path == ("measurements", 5, "working_mode")


def test_garbage_measurements_are_refused_by_name_never_crash() -> None:
    """Random points for random postures of random designs: every answer is finite or an
    InputError naming ``measurements`` (never another exception, never an unbounded
    number)."""
    rng = np.random.default_rng(0)
    for k in range(20):
        n = int(rng.integers(5, 30))
        design = Design(
            L0=float(rng.uniform(0, 0.6)),
            L1=float(rng.uniform(0.1, 0.4)),
            L2=float(rng.uniform(0.2, 0.7)),
        )
        m = Measurements(rng.uniform(-3, 3, (n, 3)), rng.uniform(-1, 1, (n, 3)))
        identify = (["lengths", "offsets", "frame"], ["leg_lengths", "offsets", "frame"])[k % 2]
        try:
            result = calibrate(design, m, identify=identify)
        except InputError as err:
            assert err.field_path[0] == "measurements"
            continue
        values = [result.residual_rms, result.condition_number, *result.std.values()]
        assert np.all(np.isfinite(values))
