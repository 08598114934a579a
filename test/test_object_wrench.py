"""Desired object wrench f_o^d: passive DS on the object (section II-E) and footnote 3."""

from dual_arm_control.core.exceptions import ConfigError, InputError
from dual_arm_control.core.geometry import rotation_exp
from dual_arm_control.core.object_wrench import (
    box_inertia, desired_object_wrench, inverse_dynamics_object_wrench, object_bias_wrench,
    ObjectWrenchConfig)
import numpy as np
import pytest

MASS = 0.7
SIZE = np.array([0.2, 0.2, 0.2])
GRAVITY = 9.81


def test_box_inertia_of_a_cube_and_of_a_slab():
    np.testing.assert_allclose(box_inertia(MASS, SIZE), MASS * 0.04 / 6.0 * np.eye(3))
    np.testing.assert_allclose(
        np.diag(box_inertia(6.0, [0.25, 0.19, 0.20])),
        0.5 * np.array([0.19 ** 2 + 0.2 ** 2, 0.25 ** 2 + 0.2 ** 2, 0.25 ** 2 + 0.19 ** 2]))


def test_tracking_object_needs_only_its_weight():
    twist = np.array([0.3, -0.1, 0.4])
    wrench = desired_object_wrench(twist, np.zeros(3), twist, np.zeros(3), MASS,
                                   box_inertia(MASS, SIZE))
    np.testing.assert_allclose(wrench, [0.0, 0.0, MASS * GRAVITY, 0.0, 0.0, 0.0], atol=1e-12)


def test_estimated_twist_enters_the_damping():
    # With the object at rest the wrench is the reference's feed-forward 12.64 v_d + m g; a
    # measured velocity error must change it (an object velocity stuck at zero would not).
    config = ObjectWrenchConfig()
    inertia = box_inertia(MASS, SIZE)
    v_desired = np.array([0.5, 0.0, 0.5])
    v_object = np.array([0.2, 0.1, 0.6])
    w_desired = np.array([0.0, 0.0, 1.0])
    w_object = np.array([0.3, 0.0, 0.2])
    wrench = desired_object_wrench(v_object, w_object, v_desired, w_desired, MASS, inertia,
                                   config)
    np.testing.assert_allclose(
        wrench[:3], -config.linear_damping * (v_object - v_desired)
        + [0.0, 0.0, MASS * GRAVITY], atol=1e-12)
    np.testing.assert_allclose(
        wrench[3:], -config.angular_damping * (w_object - w_desired)
        + np.cross(w_object, inertia @ w_object), atol=1e-12)
    no_moment = desired_object_wrench(v_object, w_object, v_desired, w_desired, MASS, inertia,
                                      ObjectWrenchConfig(include_moment=False))
    np.testing.assert_allclose(no_moment[3:], 0.0)
    np.testing.assert_allclose(no_moment[:3], wrench[:3])


def test_damping_part_dissipates_object_energy():
    rng = np.random.default_rng(0)
    inertia = box_inertia(MASS, SIZE)
    for _ in range(20):
        v, w = rng.normal(size=3), rng.normal(size=3)
        wrench = desired_object_wrench(v, w, np.zeros(3), np.zeros(3), MASS, inertia)
        active = wrench - object_bias_wrench(MASS, inertia, w)
        assert active[:3] @ v + active[3:] @ w <= 0.0


def test_inverse_dynamics_is_newton_euler():
    rng = np.random.default_rng(1)
    R_world_object = rotation_exp([0.3, -0.2, 0.5])
    inertia_world = R_world_object @ box_inertia(2.0, [0.3, 0.2, 0.1]) @ R_world_object.T
    acceleration, angular_acceleration, w = rng.normal(size=(3, 3))
    wrench = inverse_dynamics_object_wrench(acceleration, angular_acceleration, w, 2.0,
                                            inertia_world)
    # Newton-Euler for the object with the hands' wrench plus gravity acting on it:
    np.testing.assert_allclose(wrench[:3] + 2.0 * np.array([0.0, 0.0, -GRAVITY]),
                               2.0 * acceleration, atol=1e-12)
    np.testing.assert_allclose(wrench[3:], inertia_world @ angular_acceleration
                               + np.cross(w, inertia_world @ w), atol=1e-12)
    free_fall = inverse_dynamics_object_wrench([0.0, 0.0, -GRAVITY], np.zeros(3), np.zeros(3),
                                               2.0, inertia_world)
    np.testing.assert_allclose(free_fall, 0.0, atol=1e-12)
    environment = np.arange(6.0)
    shifted = inverse_dynamics_object_wrench(acceleration, angular_acceleration, w, 2.0,
                                             inertia_world, environment_wrench=environment)
    np.testing.assert_allclose(shifted - wrench, environment, atol=1e-12)


def test_gyroscopic_term_vanishes_about_a_principal_axis_only():
    inertia = box_inertia(2.0, [0.3, 0.2, 0.1])
    assert np.allclose(object_bias_wrench(2.0, inertia, [0.0, 0.0, 3.0])[3:], 0.0)
    assert not np.allclose(object_bias_wrench(2.0, inertia, [1.0, 0.0, 3.0])[3:], 0.0)


def test_invalid_inputs_are_refused():
    inertia = box_inertia(MASS, SIZE)
    with pytest.raises(InputError, match='v_world_object'):
        desired_object_wrench([np.nan, 0, 0], np.zeros(3), np.zeros(3), np.zeros(3), MASS,
                              inertia)
    with pytest.raises(InputError, match='mass'):
        desired_object_wrench(np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), 0.0,
                              inertia)
    with pytest.raises(ConfigError, match='linear_damping'):
        ObjectWrenchConfig(linear_damping=-1.0)
