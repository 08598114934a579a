"""Cooperative transform, coordinated gain matrix and nominal DS (paper eq. 4)."""

from dual_arm_control.core.cooperative import (
    absolute_relative, cooperative_gain_matrix, cooperative_transform,
    cooperative_transform_inverse, coordinated_gain_matrix, CoordinationConfig,
    impact_frame_gain_matrix, left_right, nominal_coordinated_velocity)
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.geometry import orthonormal_basis
import numpy as np
import pytest


def test_cooperative_transform_matches_the_paper_and_inverts():
    t_b = cooperative_transform()
    i3 = np.eye(3)
    np.testing.assert_array_equal(t_b, np.block([[0.5 * i3, 0.5 * i3], [-i3, i3]]))
    np.testing.assert_allclose(t_b @ cooperative_transform_inverse(), np.eye(6), atol=1e-15)
    np.testing.assert_allclose(np.linalg.inv(t_b), cooperative_transform_inverse(), atol=1e-15)


def test_absolute_relative_and_twist_distribution():
    x_left, x_right = np.array([0.41, 0.1, 0.32]), np.array([0.41, -0.1, 0.32])
    abs_rel = absolute_relative(np.concatenate((x_left, x_right)))
    np.testing.assert_allclose(abs_rel, [0.41, 0.0, 0.32, 0.0, -0.2, 0.0], atol=1e-15)
    v_abs, v_rel = np.array([0.5, 0.0, 0.2]), np.array([0.0, 0.3, -0.1])
    v_arms = left_right(np.concatenate((v_abs, v_rel)))
    np.testing.assert_allclose(v_arms[:3], v_abs - 0.5 * v_rel, atol=1e-15)
    np.testing.assert_allclose(v_arms[3:], v_abs + 0.5 * v_rel, atol=1e-15)


def test_absolute_relative_is_t_b_and_round_trips_in_batches():
    rng = np.random.default_rng(3)
    x = rng.uniform(-1.0, 1.0, (7, 6))
    np.testing.assert_allclose(absolute_relative(x), x @ cooperative_transform().T, atol=1e-14)
    np.testing.assert_allclose(left_right(absolute_relative(x)), x, atol=1e-14)
    np.testing.assert_allclose(absolute_relative(left_right(x)), x, atol=1e-14)


def test_coordinated_gain_matrix_is_eq_4_symmetric_negative_definite():
    config = CoordinationConfig(absolute_gain=4.5, relative_gain=10.0)
    gain = coordinated_gain_matrix(config)
    expected = cooperative_transform_inverse() @ cooperative_gain_matrix(config) \
        @ cooperative_transform()
    np.testing.assert_allclose(gain, expected, atol=1e-14)
    np.testing.assert_allclose(gain, gain.T, atol=1e-14)
    np.testing.assert_allclose(np.linalg.eigvalsh(gain), [-10.0] * 3 + [-4.5] * 3, atol=1e-12)
    error = np.array([0.1, -0.2, 0.3])
    # Equal errors of both arms are an absolute error, opposite ones a relative error.
    np.testing.assert_allclose(gain @ np.concatenate((error, error)),
                               -4.5 * np.concatenate((error, error)), atol=1e-14)
    np.testing.assert_allclose(gain @ np.concatenate((-error, error)),
                               -10.0 * np.concatenate((-error, error)), atol=1e-14)


def test_decoupled_gain_matrix_is_block_diagonal():
    gain = coordinated_gain_matrix(CoordinationConfig(coordinated=False))
    np.testing.assert_array_equal(gain[:3, 3:], np.zeros((3, 3)))
    np.testing.assert_array_equal(gain[3:, :3], np.zeros((3, 3)))
    np.testing.assert_allclose(gain, -7.25 * np.eye(6), atol=1e-14)


def test_impact_frame_gain_matrix_keeps_eigenvalues_and_reduces_to_a_prime():
    config = CoordinationConfig()
    gain = coordinated_gain_matrix(config)
    basis = orthonormal_basis([0.3, -0.8, 0.2])
    np.testing.assert_allclose(impact_frame_gain_matrix(gain, np.stack((basis, basis))), gain,
                               atol=1e-14)
    mirrored = np.stack((basis, orthonormal_basis([0.3, 0.8, 0.2])))
    framed = impact_frame_gain_matrix(gain, mirrored)
    np.testing.assert_allclose(framed, framed.T, atol=1e-14)
    np.testing.assert_allclose(np.linalg.eigvalsh(framed), np.linalg.eigvalsh(gain), atol=1e-12)
    # Equal progress of both arms along their own e1 is an absolute motion in the frames.
    progress = np.concatenate((mirrored[0][:, 0], mirrored[1][:, 0]))
    np.testing.assert_allclose(framed @ progress, -4.5 * progress, atol=1e-14)


def test_nominal_coordinated_velocity_is_zero_at_the_attractor_and_vectorised():
    gain = coordinated_gain_matrix(CoordinationConfig())
    rng = np.random.default_rng(4)
    attractor = rng.uniform(-1.0, 1.0, 6)
    np.testing.assert_array_equal(nominal_coordinated_velocity(attractor, attractor, gain),
                                  np.zeros(6))
    x = rng.uniform(-1.0, 1.0, (5, 6))
    batch = nominal_coordinated_velocity(x, attractor, gain)
    for row, velocity in zip(x, batch):
        np.testing.assert_allclose(velocity, gain @ (row - attractor), atol=1e-14)


@pytest.mark.parametrize('field, value', [
    ('absolute_gain', 0.0), ('absolute_gain', float('nan')), ('relative_gain', -1.0),
    ('relative_gain', 1e3), ('coordinated', 'yes')])
def test_config_rejects_bad_values_naming_the_field(field, value):
    with pytest.raises(ConfigError, match=field):
        CoordinationConfig(**{field: value})
