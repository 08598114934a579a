"""
State-dependent modulation of a DS around a transitory attractor (paper eqs. 1-3 and 5).

Per-point quantities are arrays with a leading point axis n: n = 2 for the arms (row 0 left,
row 1 right) or n = 1 for the object. Bases are (n, 3, 3) with columns e1, e2, e3 in the world
frame; positions in metres, velocities in m/s.
"""

from dataclasses import dataclass
from functools import cached_property
import math
from typing import NamedTuple

from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.geometry import orthonormal_basis
from dual_arm_control.core.settings import check_settings, setting
import numpy as np

_MIN_NOMINAL_SPEED_SQUARED = 1e-20
_FULL_ACTIVATION_MARGIN = math.log(99.0)


@dataclass(frozen=True)
class ModulationRegionConfig:
    """
    Geometry of the region where the modulation acts around one target (section II, Fig. 3).

    The defaults are those of the reach with impact. Off-line errors left when the desired velocity
    switches on (about delta_normal) decay along the run as exp(-k rho / v) (k the coordination
    rate, v the impact speed) and end up in the contact point and in the impact direction; rho =
    0.2 m and delta_normal = 0.01 m leave at most 1.5 mm and 0.8 deg at 0.45 m/s (test_impact); the
    reference's rho = 0.075 m, delta_normal = 0.05 m would leave about 5 cm * exp(-4.5 * 0.075 /
    0.45) = 2.4 cm.
    """

    transitory_distance: float = setting(
        0.20, 'rho: the transitory attractor sits at x_t = x_d - rho e1; the DS runs the last '
        'rho along e1 at the desired velocity.', unit='m', low=0, high=1.0, low_open=True)
    radial_distance: float = setting(
        0.25, 'delta_radial, radius of the activation ball around x_t. Must exceed rho with '
        'radial_slope * (delta_radial - rho) >= ln 99 so that phi_radial >= 0.99 at the target.',
        unit='m', low=0, high=2.0, low_open=True)
    normal_distance: float = setting(
        0.02, 'delta_normal, radius of the cylinder around the line through x_t along e1 inside '
        "which the desired velocity is applied. The reach's 0.02 m is wide enough that the "
        'torque-controlled arms (tracking within 1-2 cm at 0.5 m/s) enter the region instead of '
        'dithering around x_t (measured in the MuJoCo twin).',
        unit='m', low=0, high=0.5, low_open=True)
    tangent_distance: float = setting(
        0.015, 'delta_tangent, half-length along e1 around the target x_d inside which the '
        "contact activation kappa is on (the reach's 0.015 m is the reference's).",
        unit='m', low=0, high=0.5, low_open=True)
    radial_slope: float = setting(
        200.0, "a_radial of the logistic radial activation (the reach's 200 is the reference's).",
        unit='1/m', low=0, high=1e4, low_open=True)
    normal_slope: float = setting(
        400.0, "a_normal of the logistic normal activation (the reach's 400 is the reference's "
        "300 in this logistic's units).", unit='1/m', low=0, high=1e4, low_open=True)
    tangent_slope: float = setting(
        400.0, "a_tangent of the logistic tangential activation (the reach's 400 is the "
        "reference's).", unit='1/m', low=0, high=1e4, low_open=True)

    def __post_init__(self):
        check_settings(self)
        margin = self.radial_slope * (self.radial_distance - self.transitory_distance)
        if margin < _FULL_ACTIVATION_MARGIN:
            raise ConfigError(
                f'radial_distance = {self.radial_distance:g} m with radial_slope = '
                f'{self.radial_slope:g} 1/m leaves the target at phi_radial < 0.99 '
                f'(transitory_distance = {self.transitory_distance:g} m); need radial_slope * '
                f'(radial_distance - transitory_distance) >= {_FULL_ACTIVATION_MARGIN:.2f}')

    @cached_property
    def distances(self):
        """Return (delta_radial, delta_normal, delta_tangent) [m], read-only."""
        return _read_only([self.radial_distance, self.normal_distance, self.tangent_distance])

    @cached_property
    def slopes(self):
        """Return (a_radial, a_normal, a_tangent) [1/m], read-only."""
        return _read_only([self.radial_slope, self.normal_slope, self.tangent_slope])


def _read_only(values):
    array = np.array(values, dtype=float)
    array.flags.writeable = False
    return array


class RegionActivation(NamedTuple):
    """Activations per point (n,), each in [0, 1]."""

    alpha: np.ndarray
    """alpha, modulation on (text after eq. 3)."""
    gamma: np.ndarray
    """gamma = phi_radial phi_normal, desired velocity on (eq. 6)."""
    kappa: np.ndarray
    """kappa = gamma phi_tangent, at the target (Proposition 3)."""


def modulation_bases(directions):
    """Return E (n, 3, 3), each basis from geometry.orthonormal_basis with e1 along a row."""
    return np.stack([orthonormal_basis(direction) for direction in np.atleast_2d(directions)])


def transitory_attractor(desired_positions, bases, transitory_distance):
    """Return x_t = x_d - rho e1 (n, 3) [m] (text after eq. 2)."""
    return np.asarray(desired_positions, dtype=float) - transitory_distance * bases[:, :, 0]


def activation_distances(positions, transitory_attractors, bases, transitory_distance):
    """
    Return Gamma (n, 3) [m]: radial, normal and tangent distances (section II).

    Gamma_radial = |x - x_t| (3D) and Gamma_normal = distance to the line through x_t along e1
    (2D, normal to e1), both with origin x_t as in the paper. Gamma_tangent (1D along e1) is
    measured from the target x_d = x_t + rho e1: with origin x_t, phi_tangent would peak rho
    before contact and kappa = gamma phi_tangent could not indicate the contact, which is
    what section III-C uses it for.
    """
    local = np.einsum('nki,nk->ni', bases, np.asarray(positions) - transitory_attractors)
    radial = np.sqrt(np.einsum('ni,ni->n', local, local))
    normal = np.hypot(local[:, 1], local[:, 2])
    tangent = np.abs(local[:, 0] - transitory_distance)
    return np.stack((radial, normal, tangent), axis=1)


def activations(distances, region):
    """Return phi_i = 1 / (1 + exp(-a_i (delta_i - Gamma_i))) (n, 3): radial, normal, tangent."""
    exponent = np.clip(-region.slopes * (region.distances - distances), -500.0, 500.0)
    return 1.0 / (1.0 + np.exp(exponent))


def region_activations(phi, shared=True):
    """
    Return RegionActivation of phi (n, 3): alpha, gamma, kappa per point.

    Per point, gamma = phi_radial phi_normal and kappa = gamma phi_tangent are chained first.
    With shared=True each activation is then averaged over the points, as the paper does for
    alpha (text after eq. 3), and the same value is returned for every point. Shared
    activations keep both arms' fields blended identically, so the relative motion of the
    coordinated DS is never modulated and the arms stay synchronised; chaining before
    averaging avoids the reference's mean(phi_radial) * mean(phi_normal), which is 1/4 when
    each arm satisfies only one of the two conditions. shared=False gives each point its own
    activation (decoupled arms, or the object alone).
    """
    chained = np.cumprod(phi, axis=1)
    if shared:
        chained = np.broadcast_to(chained.sum(axis=0) / len(phi), chained.shape)
    return RegionActivation(chained[:, 0], chained[:, 1], chained[:, 2])


def modulation_gains(bases, nominal, targets):
    """
    Return lambda_ij (n, 3, 3) (eq. 5) for the nominal field f_n (n, 3).

    targets (n, 3, 3): targets[h, i] is the target field f_mi of direction e_i at point h.
    lambda_ij = (e_i^T f_mi)(f_n^T e_j) / (f_n^T f_n). Where f_n = 0 (only at the nominal
    attractor) eq. 5 is undefined; the gains are then zero, which leaves M f_n = 0 there as any
    finite gain would. modulated_velocity avoids this point altogether.
    """
    nominal = np.asarray(nominal, dtype=float)
    along_targets = np.einsum('nki,nik->ni', bases, targets)
    along_nominal = np.einsum('nkj,nk->nj', bases, nominal)
    squared_speed = np.einsum('nk,nk->n', nominal, nominal)
    scale = np.where(squared_speed > _MIN_NOMINAL_SPEED_SQUARED,
                     1.0 / np.maximum(squared_speed, _MIN_NOMINAL_SPEED_SQUARED), 0.0)
    return along_targets[:, :, None] * along_nominal[:, None, :] * scale[:, None, None]


def blended_modulation_gains(gains, alpha):
    """Return Lambda-bar = alpha Lambda + (1 - alpha) I (n, 3, 3) (eq. 3), alpha (n,)."""
    alpha = np.asarray(alpha, dtype=float)[:, None, None]
    return alpha * gains + (1.0 - alpha) * np.eye(3)


def modulation_matrix(bases, blended_gains):
    """Return M = E Lambda-bar E^T (3n, 3n), block diagonal (eq. 2)."""
    count = len(bases)
    blocks = np.einsum('nik,nkl,njl->nij', bases, blended_gains, bases)
    matrix = np.zeros((3 * count, 3 * count))
    for index in range(count):
        matrix[3 * index:3 * index + 3, 3 * index:3 * index + 3] = blocks[index]
    return matrix


def modulated_velocity(bases, nominal, targets, alpha, grasp_velocity=None):
    """
    Return x_dot = M f_n + f_g (n, 3) [m/s] (eq. 1) with M from eqs. 2, 3 and 5.

    Evaluated in closed form: with lambda from eq. 5, E Lambda-bar E^T f_n equals
    alpha sum_i e_i e_i^T f_mi + (1 - alpha) f_n for every f_n != 0 (Proposition 1, appendix
    B). The closed form is also the continuous extension at f_n = 0, where eq. 5 divides by
    zero; the transitory attractor, where that happens, is therefore not a spurious
    equilibrium when the desired velocity is active. grasp_velocity f_g (n, 3) is optional.
    """
    along_targets = np.einsum('nki,nik->ni', bases, targets)
    target_velocity = np.einsum('nki,ni->nk', bases, along_targets)
    alpha = np.asarray(alpha, dtype=float)[:, None]
    velocity = alpha * target_velocity + (1.0 - alpha) * nominal
    if grasp_velocity is not None:
        velocity = velocity + grasp_velocity
    return velocity
