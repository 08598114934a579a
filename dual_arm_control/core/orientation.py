"""
Orientation dynamical system of the paper's appendix A.

The end-effector orientation R_world_current is driven to a target R_world_target through a
linear DS on the axis-angle error xi = theta * mu of R_target^T R_current:

    xi_dot = A_theta xi,   omega = L_xi^-1 A_theta xi,   A_theta = -diag(convergence_rates).

Sign convention (checked against a finite difference in test/test_orientation.py): with xi
taken from R_target^T R_current and omega the angular velocity of the current frame expressed in
the WORLD frame, the exact relation is xi_dot = L_theta_mu(theta, mu) R_target^T omega, where
L_theta_mu is the appendix's matrix (Malis et al. 1999). The appendix pairs L_theta_mu with
R_current^T; that product is the exact map only for the opposite sign of the [mu]x term. Both
give the same omega for an isotropic A_theta, and for any negative definite A_theta the
error norm still decreases, so the appendix's DS converges as written; we use the exact form so
that xi_dot = A_theta xi holds to machine precision.

The position coupling eta(x) moves the target from a resting orientation to the desired one as
the absolute position error shrinks, R_*(eta) = slerp(R_rest, R_desired, eta).
"""

from dataclasses import dataclass
import functools

from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.geometry import rotation_log, skew, slerp_rotation, vector_norm
from dual_arm_control.core.settings import check_settings, setting
from dual_arm_control.core.validation import finite_array
import numpy as np


_SERIES_ANGLE = 1e-3
_IDENTITY = np.eye(3)
_IDENTITY.setflags(write=False)


@dataclass(frozen=True)
class OrientationDsConfig:
    """Parameters of the appendix-A orientation DS."""

    convergence_rates: tuple = setting(
        (3.0, 3.0, 3.0), 'A_theta = -diag(convergence_rates) acting on the error components '
        '(reference: 3 = 3 x unit orientation gain while reaching).',
        unit='rad/s per rad', low=0, low_open=True, size=3)
    max_angular_speed: float = setting(
        3.0, 'The norm of omega is saturated to this (reference 3).',
        unit='rad/s', low=0, low_open=True)
    coupling_sigma: float = setting(
        1.0, 'sigma of eta(x) = 1 - exp(-sigma / (||e_abs|| + epsilon)) (reference 1 m: eta = '
        '0.9 at 0.43 m, 0.5 at 1.44 m).', unit='m', low=0, low_open=True)
    coupling_epsilon: float = setting(
        1e-6, 'Keeps eta defined (= 1) at zero position error.', unit='m', low=0, low_open=True)

    def __post_init__(self):
        check_settings(self)

    @property
    def dynamics_matrix(self):
        """Return A_theta = -diag(convergence_rates), (3, 3), 1/s, negative definite."""
        return _dynamics_matrix(tuple(self.convergence_rates)).copy()


@functools.lru_cache(maxsize=16)
def _dynamics_matrix(convergence_rates):
    """Return A_theta = -diag(convergence_rates) (3, 3), read-only, built once per rates."""
    matrix = -np.diag(convergence_rates)
    matrix.setflags(write=False)
    return matrix


def orientation_error(R_world_target, R_world_current):
    """
    Return xi = theta * mu of R_target^T R_current (appendix A), (3,) rad.

    The axis is expressed in the target frame (equivalently the current frame: the axis of a
    relative rotation is fixed by it). xi = 0 iff the orientations match; theta in [0, pi].
    """
    R_world_target = finite_array('R_world_target', R_world_target, (3, 3))
    R_world_current = finite_array('R_world_current', R_world_current, (3, 3))
    return rotation_log(R_world_target.T @ R_world_current)


def _cot_half_angle_coefficient(theta):
    """Return 1 - sinc(theta) / sinc^2(theta / 2) = 1 - (theta / 2) cot(theta / 2)."""
    if theta < _SERIES_ANGLE:
        half_squared = 0.25 * theta * theta
        return half_squared / 3.0 + half_squared * half_squared / 45.0
    half = 0.5 * theta
    return 1.0 - half / np.tan(half)


def theta_mu_interaction_matrix(theta, mu):
    """
    Return L_theta_mu = I - theta/2 [mu]x + (1 - sinc theta / sinc^2(theta/2)) [mu]x^2.

    Appendix A (from Malis et al. 1999), (3, 3), dimensionless. theta in rad (>= 0, < 2 pi),
    mu a unit axis (3,); any mu is accepted at theta = 0, where L = I. The coefficient of
    [mu]x^2 equals 1 - (theta/2) cot(theta/2) and uses its Taylor series below 1e-3 rad, so the
    matrix is smooth through theta = 0.
    """
    theta = float(theta)
    mu = finite_array('mu', mu, (3,))
    mu_cross = skew(mu)
    return (_IDENTITY - 0.5 * theta * mu_cross
            + _cot_half_angle_coefficient(theta) * mu_cross @ mu_cross)


def _angle_axis(xi):
    """Split a rotation vector into (theta, unit axis); the axis is arbitrary at theta = 0."""
    theta = vector_norm(xi)
    if theta == 0.0:
        return 0.0, np.array([1.0, 0.0, 0.0])
    return theta, xi / theta


def orientation_error_jacobian(R_world_target, R_world_current):
    """
    Return L_xi, (3, 3), such that xi_dot = L_xi omega_world (appendix A).

    omega_world is the angular velocity of the current frame in the world frame (rad/s) with the
    target fixed. L_xi = L_theta_mu R_target^T: the exact form of the appendix's
    L_theta_mu R_current^T (see the module docstring for the sign convention).
    """
    R_world_target = finite_array('R_world_target', R_world_target, (3, 3))
    theta, mu = _angle_axis(orientation_error(R_world_target, R_world_current))
    return theta_mu_interaction_matrix(theta, mu) @ R_world_target.T


def orientation_error_jacobian_inverse(R_world_target, R_world_current):
    """
    Return L_xi^-1, (3, 3), closed form: R_target (I + (1-cos)/theta [mu]x + (1-sinc)[mu]x^2).

    The bracket is the inverse of L_theta_mu (the left Jacobian of SO(3)); it is defined for
    every theta in [0, pi], so the DS has no singularity on its domain.
    """
    R_world_target = finite_array('R_world_target', R_world_target, (3, 3))
    return _error_jacobian_inverse(R_world_target,
                                   orientation_error(R_world_target, R_world_current))


def _error_jacobian_inverse(R_world_target, xi):
    """Return L_xi^-1 (3, 3) (appendix A) from the orientation error xi (3,) it is taken at."""
    theta, mu = _angle_axis(xi)
    mu_cross = skew(mu)
    if theta < _SERIES_ANGLE:
        first = 0.5 * theta - theta ** 3 / 24.0
        second = theta * theta / 6.0
    else:
        first = (1.0 - np.cos(theta)) / theta
        second = 1.0 - np.sin(theta) / theta
    return R_world_target @ (_IDENTITY + first * mu_cross + second * mu_cross @ mu_cross)


def saturated_angular_velocity(omega, max_angular_speed):
    """Return omega (3,) scaled down so that ||omega|| <= max_angular_speed (rad/s)."""
    omega = np.asarray(omega, dtype=float)
    speed = vector_norm(omega)
    if speed > max_angular_speed:
        return omega * (max_angular_speed / speed)
    return omega


def orientation_ds_angular_velocity(R_world_current, R_world_target, config):
    """
    Return omega_world = sat(L_xi^-1 A_theta xi), (3,) rad/s in the world frame (appendix A).

    Integrating R_current <- exp([omega] dt) R_current gives xi_dot = A_theta xi while the norm
    is below config.max_angular_speed, and a uniformly scaled A_theta xi when saturated, so the
    orientation converges to R_world_target from any start with theta < pi.
    """
    R_world_target = finite_array('R_world_target', R_world_target, (3, 3))
    xi = orientation_error(R_world_target, R_world_current)
    omega = (_error_jacobian_inverse(R_world_target, xi)
             @ _dynamics_matrix(tuple(config.convergence_rates)) @ xi)
    return saturated_angular_velocity(omega, config.max_angular_speed)


def orientation_coupling(p_world_abs, p_world_abs_desired, config):
    """
    Return eta(x) = 1 - exp(-sigma / (||x_abs - x_abs_d|| + epsilon)) in [0, 1] (appendix A).

    x_abs is the absolute (midpoint) position of the two tools, (3,) m. eta -> 1 as the error
    vanishes and -> 0 for large errors, strictly decreasing in the error norm.
    """
    p_world_abs = finite_array('p_world_abs', p_world_abs, (3,))
    p_world_abs_desired = finite_array('p_world_abs_desired', p_world_abs_desired, (3,))
    distance = vector_norm(p_world_abs - p_world_abs_desired)
    return 1.0 - np.exp(-config.coupling_sigma / (distance + config.coupling_epsilon))


def intermediate_target_orientation(R_world_rest, R_world_desired, eta):
    """
    Return R_*(eta) = slerp(R_rest, R_desired, eta), (3, 3) (appendix A).

    R_* = R_rest at eta = 0 and R_desired at eta = 1, along the shortest geodesic; the DS
    then uses xi from R_*^T R_current.
    """
    eta = float(eta)
    if not 0.0 <= eta <= 1.0:
        raise InputError(f'eta = {eta:g} is outside [0, 1]')
    R_world_rest = finite_array('R_world_rest', R_world_rest, (3, 3))
    R_world_desired = finite_array('R_world_desired', R_world_desired, (3, 3))
    return slerp_rotation(R_world_rest, R_world_desired, eta)
