"""Orientation DS of appendix A: convergence, interaction matrix, coupling eta and R_*."""

from dual_arm_control.core.exceptions import ConfigError, InputError
from dual_arm_control.core.geometry import rotation_exp, rotation_log, skew
from dual_arm_control.core.orientation import (
    intermediate_target_orientation, orientation_coupling, orientation_ds_angular_velocity,
    orientation_error, orientation_error_jacobian, orientation_error_jacobian_inverse,
    OrientationDsConfig, theta_mu_interaction_matrix)
import numpy as np
import pytest


def random_rotation(rng, max_angle=np.pi):
    """Return a rotation with a uniformly random axis and an angle in [0, max_angle)."""
    axis = rng.normal(size=3)
    return rotation_exp(axis / np.linalg.norm(axis) * rng.uniform(0.0, max_angle))


def angle_between(R_a, R_b):
    return float(np.linalg.norm(rotation_log(R_a.T @ R_b)))


def integrate(R_world_current, R_world_target, config, dt, duration):
    """Integrate R <- exp([omega] dt) R; return the final rotation and the angle history."""
    angles = [angle_between(R_world_target, R_world_current)]
    for _ in range(int(round(duration / dt))):
        omega = orientation_ds_angular_velocity(R_world_current, R_world_target, config)
        R_world_current = rotation_exp(omega * dt) @ R_world_current
        angles.append(angle_between(R_world_target, R_world_current))
    return R_world_current, np.array(angles)


def test_converges_from_random_orientations():
    """
    50 random starts/targets (errors up to 179 deg), dt in [1, 5] ms: error < 1e-3 rad.

    Worst case: about 1 s at the 3 rad/s saturation, then exp(-3 t) from 1 rad to 1e-3 rad in
    2.3 s, so 4 s suffices; the angle must also never increase (Lyapunov: d|xi|/dt < 0).
    """
    rng = np.random.default_rng(7)
    config = OrientationDsConfig()
    final_errors = []
    for trial in range(50):
        R_world_target = random_rotation(rng)
        start_angle = rng.uniform(0.05, np.radians(179.0))
        R_world_current = rotation_exp(unit_random(rng) * start_angle) @ R_world_target
        dt = rng.uniform(0.001, 0.005)
        R_final, angles = integrate(R_world_current, R_world_target, config, dt, 4.0)
        assert np.all(np.diff(angles) <= 1e-12), f'trial {trial}: angle increased'
        final_errors.append(angles[-1])
    assert max(final_errors) < 1e-3


def unit_random(rng):
    axis = rng.normal(size=3)
    return axis / np.linalg.norm(axis)


def test_error_follows_linear_ds_exactly_with_anisotropic_gains():
    """Unsaturated, xi(t) = exp(A t) xi(0) with A = -diag(1, 2, 4): the exact L_xi is used."""
    rng = np.random.default_rng(3)
    config = OrientationDsConfig(convergence_rates=(1.0, 2.0, 4.0), max_angular_speed=100.0)
    R_world_target = random_rotation(rng)
    R_world_current = R_world_target @ rotation_exp(np.array([0.9, -1.2, 0.7]))
    xi_start = orientation_error(R_world_target, R_world_current)
    dt, duration = 0.0005, 0.5
    R_final, _ = integrate(R_world_current, R_world_target, config, dt, duration)
    xi_expected = np.exp(-np.array([1.0, 2.0, 4.0]) * duration) * xi_start
    # explicit Euler on the exp map: per-step factor 1 - k dt vs exp(-k dt), relative error
    # about k^2 dt t / 2 = 2e-3 for k = 4.
    np.testing.assert_allclose(orientation_error(R_world_target, R_final), xi_expected,
                               rtol=3e-3, atol=1e-6)


def test_interaction_matrix_matches_finite_difference():
    """
    xi_dot from a central difference of xi(exp(omega h) R_c) equals L_xi omega to 1e-6.

    Angles from 1e-5 rad to 3.1 rad; the appendix's literal L_theta_mu R_c^T is shown to be a
    different map (error of order 1), which is why L_xi uses R_d^T (see orientation.py).
    """
    rng = np.random.default_rng(11)
    step = 1e-6
    for angle in (1e-5, 1e-3, 0.3, 1.0, 2.0, 3.1):
        for _ in range(5):
            R_world_target = random_rotation(rng)
            R_world_current = R_world_target @ rotation_exp(unit_random(rng) * angle)
            omega = rng.normal(size=3)

            def xi_at(time, R_world_current=R_world_current, R_world_target=R_world_target,
                      omega=omega):
                return orientation_error(R_world_target,
                                         rotation_exp(omega * time) @ R_world_current)

            xi_dot = (xi_at(step) - xi_at(-step)) / (2.0 * step)
            L_xi = orientation_error_jacobian(R_world_target, R_world_current)
            assert np.max(np.abs(xi_dot - L_xi @ omega)) < 1e-6
            if angle >= 0.3:
                xi = orientation_error(R_world_target, R_world_current)
                theta = np.linalg.norm(xi)
                literal = theta_mu_interaction_matrix(theta, xi / theta) @ R_world_current.T
                assert np.max(np.abs(xi_dot - literal @ omega)) > 1e-3 * angle


def test_interaction_matrix_well_defined_near_zero():
    """L(0) = I, and the series branch joins the closed form at 1e-3 rad to 1e-12."""
    mu = unit_random(np.random.default_rng(0))
    np.testing.assert_array_equal(theta_mu_interaction_matrix(0.0, mu), np.eye(3))
    below = theta_mu_interaction_matrix(1e-3 * (1 - 1e-9), mu)
    above = theta_mu_interaction_matrix(1e-3 * (1 + 1e-9), mu)
    assert np.max(np.abs(below - above)) < 1e-12
    tiny = theta_mu_interaction_matrix(1e-8, mu)
    assert np.all(np.isfinite(tiny)) and np.max(np.abs(tiny - np.eye(3))) < 1e-8
    # coefficient of [mu]x^2 against its definition 1 - sinc(t) / sinc^2(t / 2) at t = 0.5
    theta = 0.5
    coefficient = 1.0 - np.sinc(theta / np.pi) / np.sinc(theta / 2.0 / np.pi) ** 2
    K = skew(mu)
    expected = np.eye(3) - theta / 2.0 * K + coefficient * K @ K
    np.testing.assert_allclose(theta_mu_interaction_matrix(theta, mu), expected, atol=1e-15)


def test_jacobian_inverse_is_inverse():
    rng = np.random.default_rng(5)
    for angle in (0.0, 1e-6, 5e-4, 0.7, 2.5, np.pi - 1e-3):
        R_world_target = random_rotation(rng)
        R_world_current = R_world_target @ rotation_exp(unit_random(rng) * angle)
        product = (orientation_error_jacobian_inverse(R_world_target, R_world_current)
                   @ orientation_error_jacobian(R_world_target, R_world_current))
        np.testing.assert_allclose(product, np.eye(3), atol=1e-10)


def test_angular_velocity_zero_at_target_and_saturated():
    rng = np.random.default_rng(2)
    config = OrientationDsConfig()
    R_world = random_rotation(rng)
    np.testing.assert_allclose(orientation_ds_angular_velocity(R_world, R_world, config),
                               np.zeros(3), atol=1e-12)
    R_far = R_world @ rotation_exp(np.array([0.0, 0.0, 3.0]))
    omega = orientation_ds_angular_velocity(R_far, R_world, config)
    assert np.linalg.norm(omega) == pytest.approx(3.0, rel=1e-12)
    # unsaturated: omega = -k * (error axis in world) * theta, pointing back to the target
    R_near = rotation_exp(np.array([0.1, 0.0, 0.0])) @ R_world
    omega = orientation_ds_angular_velocity(R_near, R_world, config)
    np.testing.assert_allclose(omega, [-0.3, 0.0, 0.0], atol=1e-12)


def test_coupling_eta_limits_and_monotone():
    """eta(0) = 1, eta -> sigma / d for large d, decreasing in the error; 0.9 at 0.434 m."""
    config = OrientationDsConfig()
    target = np.array([0.5, 0.0, 0.3])
    distances = np.linspace(0.0, 20.0, 2001)
    etas = np.array([orientation_coupling(target + [d, 0.0, 0.0], target, config)
                     for d in distances])
    assert etas[0] > 1.0 - 1e-12
    # strictly decreasing wherever 1 - eta is representable in double precision
    assert np.all(np.diff(etas) <= 0.0)
    assert np.all(np.diff(etas)[etas[:-1] < 1.0 - 1e-12] < 0.0)
    assert etas[-1] == pytest.approx(1.0 - np.exp(-1.0 / (20.0 + 1e-6)), rel=1e-9)
    assert orientation_coupling(target + [0.0, 100.0, 0.0], target, config) < 0.011
    # the reference coupling's tabulated value (sigma = 1 m): eta = 0.9 at 0.434 m
    assert orientation_coupling(target + [0.0, 0.434, 0.0], target, config) == \
        pytest.approx(0.9, abs=1e-3)
    sharper = OrientationDsConfig(coupling_sigma=0.1)
    assert orientation_coupling(target + [0.3, 0, 0], target, sharper) < \
        orientation_coupling(target + [0.3, 0, 0], target, config)


def test_intermediate_target_follows_geodesic():
    rng = np.random.default_rng(9)
    R_world_rest = random_rotation(rng)
    R_world_desired = R_world_rest @ rotation_exp(np.array([0.4, -1.1, 0.8]))
    total = angle_between(R_world_rest, R_world_desired)
    np.testing.assert_allclose(
        intermediate_target_orientation(R_world_rest, R_world_desired, 0.0), R_world_rest,
        atol=1e-12)
    np.testing.assert_allclose(
        intermediate_target_orientation(R_world_rest, R_world_desired, 1.0), R_world_desired,
        atol=1e-12)
    for eta in (0.25, 0.5, 0.8):
        R_star = intermediate_target_orientation(R_world_rest, R_world_desired, eta)
        assert angle_between(R_world_rest, R_star) == pytest.approx(eta * total, rel=1e-9)
        assert angle_between(R_star, R_world_desired) == pytest.approx((1 - eta) * total,
                                                                       rel=1e-9)
    with pytest.raises(InputError):
        intermediate_target_orientation(R_world_rest, R_world_desired, 1.5)


def test_coupled_target_converges_as_position_error_vanishes():
    """With eta from a position error shrinking to zero, R converges to R_desired."""
    rng = np.random.default_rng(4)
    config = OrientationDsConfig(coupling_sigma=0.05)
    R_world_rest = random_rotation(rng)
    R_world_desired = R_world_rest @ rotation_exp(np.array([0.0, 1.5, 0.0]))
    R_world_current = R_world_rest
    p_world_desired = np.zeros(3)
    dt = 0.002
    for step in range(2000):
        p_world_abs = p_world_desired + np.array([0.6, 0.0, 0.0]) * np.exp(-2.0 * step * dt)
        eta = orientation_coupling(p_world_abs, p_world_desired, config)
        R_star = intermediate_target_orientation(R_world_rest, R_world_desired, eta)
        omega = orientation_ds_angular_velocity(R_world_current, R_star, config)
        R_world_current = rotation_exp(omega * dt) @ R_world_current
    assert angle_between(R_world_current, R_world_desired) < 1e-3


@pytest.mark.parametrize('kwargs', [
    {'convergence_rates': (3.0, 0.0, 3.0)}, {'convergence_rates': (1.0, 2.0)},
    {'max_angular_speed': -1.0}, {'coupling_sigma': 0.0}, {'coupling_epsilon': float('nan')},
])
def test_config_rejects_invalid(kwargs):
    with pytest.raises(ConfigError):
        OrientationDsConfig(**kwargs)
