"""
Cooperative task space and the coordinated linear DS of the dual-arm system (paper eq. 4).

The state of the two arms is stacked as x = [x_L; x_R] in R^6 (world frame, metres). The
cooperative coordinates are the absolute position x_abs = (x_L + x_R) / 2 and the relative
position x_rel = x_R - x_L. Every function accepts leading batch dimensions (..., 6).
"""

from dataclasses import dataclass

from dual_arm_control.core.settings import check_settings, setting
import numpy as np

_I3 = np.eye(3)
_COOPERATIVE_TRANSFORM = np.block([[0.5 * _I3, 0.5 * _I3], [-_I3, _I3]])
_COOPERATIVE_TRANSFORM_INVERSE = np.block([[_I3, -0.5 * _I3], [_I3, 0.5 * _I3]])


@dataclass(frozen=True)
class CoordinationConfig:
    """
    Gain matrix A = diag(-absolute_gain I3, -relative_gain I3) of the coordinated DS (eq. 4).

    One A serves every coordinated field (reach, impact, manipulation), unlike the reference code,
    which used -4.5/-10 in its nominal DS but -6/-8 in the impact attractor.
    """

    absolute_gain: float = setting(
        4.5, 'Convergence rate of the absolute (midpoint) position. Default 4.5, the rate the '
        "reference's nominal DS applied (3 x 1.5).", unit='1/s', low=0, high=100.0, low_open=True)
    relative_gain: float = setting(
        10.0, "Convergence rate of the relative position x_R - x_L. Default 10, the reference's "
        'nominal relative rate (5 x 2). A relative rate above the absolute one makes the arms '
        'agree with each other faster than they reach the target: this is what synchronises '
        'them.', unit='1/s', low=0, high=100.0, low_open=True)
    coordinated: bool = setting(
        True, "True couples the arms through A' = T_b^-1 A T_b. False keeps only the "
        "block-diagonal part of A' (paper section V): each arm converges to its own attractor at "
        'the rate (absolute_gain + relative_gain) / 2, independently of the other arm.')

    def __post_init__(self):
        check_settings(self)


def cooperative_transform():
    """Return T_b (6, 6) with [x_abs; x_rel] = T_b [x_L; x_R] (text after eq. 4)."""
    return _COOPERATIVE_TRANSFORM.copy()


def cooperative_transform_inverse():
    """Return T_b^-1 (6, 6): x_L = x_abs - x_rel / 2, x_R = x_abs + x_rel / 2."""
    return _COOPERATIVE_TRANSFORM_INVERSE.copy()


def absolute_relative(x):
    """
    Return [x_abs; x_rel] = T_b x (..., 6) of stacked arm vectors x = [x_L; x_R] (..., 6).

    Valid for positions [m] and linear velocities [m/s] alike (T_b is constant).
    """
    x = np.asarray(x, dtype=float)
    left, right = x[..., :3], x[..., 3:]
    return np.concatenate((0.5 * (left + right), right - left), axis=-1)


def left_right(abs_rel):
    """
    Return [x_L; x_R] = T_b^-1 [x_abs; x_rel] (..., 6), the inverse of absolute_relative.

    For velocities this is the twist distribution v_L = v_abs - v_rel / 2,
    v_R = v_abs + v_rel / 2.
    """
    abs_rel = np.asarray(abs_rel, dtype=float)
    absolute, half_relative = abs_rel[..., :3], 0.5 * abs_rel[..., 3:]
    return np.concatenate((absolute - half_relative, absolute + half_relative), axis=-1)


def cooperative_gain_matrix(config):
    """Return A = diag(-absolute_gain I3, -relative_gain I3) (6, 6) [1/s] (eq. 4)."""
    return np.diag(np.repeat([-config.absolute_gain, -config.relative_gain], 3))


def coordinated_gain_matrix(config):
    """
    Return A' = T_b^-1 A T_b (6, 6) [1/s] (eq. 4), or its block diagonal if not coordinated.

    A' = [[a I3, b I3], [b I3, a I3]] with a = -(k_abs + k_rel) / 2, b = (k_rel - k_abs) / 2:
    symmetric, negative definite, eigenvalues -k_abs and -k_rel. The decoupled variant keeps
    a I3 on the diagonal and zeroes b.
    """
    gain = _COOPERATIVE_TRANSFORM_INVERSE @ cooperative_gain_matrix(config) \
        @ _COOPERATIVE_TRANSFORM
    if not config.coordinated:
        gain[:3, 3:] = 0.0
        gain[3:, :3] = 0.0
    return gain


def impact_frame_gain_matrix(gain_matrix, bases):
    """
    Return E A' E^T (6, 6) [1/s]: eq. 4's coordination applied in the arms' modulation bases.

    bases (2, 3, 3) holds E^L and E^R (columns e1, e2, e3, world frame); E = diag(E^L, E^R).
    A' couples the arms through world-frame differences x_R - x_L. When the two impact
    directions are mirror images (tilted grasp), equal progress of the arms along their own
    e1 is not a world-frame relative quantity, and the world coupling pushes each arm off its
    impact line as the other one advances on its own. Expressed in the bases, the relative
    coordinate compares the arms' progress along e1^L and e1^R instead. E is orthogonal, so
    the result keeps A's eigenvalues; for E^L = E^R it equals A'.
    """
    rotation = np.zeros((6, 6))
    rotation[:3, :3] = bases[0]
    rotation[3:, 3:] = bases[1]
    return rotation @ gain_matrix @ rotation.T


def nominal_coordinated_velocity(x, attractor, gain_matrix):
    """
    Return f_n = A'(x - x_*) (..., 6) [m/s] (eq. 4).

    x, attractor: stacked positions [x_L; x_R] (..., 6) [m], world frame.
    gain_matrix: A' (6, 6) [1/s] from coordinated_gain_matrix or impact_frame_gain_matrix.
    """
    error = np.asarray(x, dtype=float) - attractor
    return error @ np.asarray(gain_matrix).T
