"""
Desired net wrench on the grasped object, the f_o^d of eq. 10 (paper section II-E).

Two ways, both in the world frame with the moment about the object's centre of mass:

- passive DS on the object (section II-E, after Kronander and Billard 2016):
  f_o^d = -D_o (xdot_o - f(x_o)) + b_o, with the ESTIMATED object twist xdot_o (the reference
  code left it at zero, which turned the law into a pure feed-forward);
- inverse dynamics (footnote 3): f_o^d = M_o xddot_o^d + b_o + f_env.

b_o = [-m g; w x (I w)] is the wrench the hands must supply against gravity and the gyroscopic
term, i.e. what cancels the object's Coriolis and gravity forces.
"""

import dataclasses

from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.geometry import cross3
from dual_arm_control.core.settings import check_settings, setting
from dual_arm_control.core.validation import check_range, finite_array
import numpy as np


@dataclasses.dataclass(frozen=True)
class ObjectWrenchConfig:
    """
    Gains of the object-level passive DS; defaults are the reference setup's numbers.

    The damping is isotropic (D_o = diag(d_lin I, d_ang I)), the constant special case of the
    paper's state-varying D_o(x_o).
    """

    linear_damping: float = setting(
        12.64, "d_lin, damping on the object's linear velocity error.",
        unit='N s/m', low=0, high=1e4)
    angular_damping: float = setting(
        2.0, "d_ang, damping on the object's angular velocity error. The reference's 25 only "
        'worked because it never estimated omega; with a real estimate (noise ~0.2 rad/s) 25 '
        'asks the pads for 5 N m of pitch moment they cannot give, which saturates the QP.',
        unit='N m s/rad', low=0, high=1e4)
    include_moment: bool = setting(
        True, 'If false the moment part of f_o^d is zero (force-only distribution).')
    gravity: float = setting(
        9.81, 'Magnitude of gravity, acting along -z of the world.',
        unit='m/s^2', low=0, high=100.0)

    def __post_init__(self):
        """Validate every field; raise ConfigError naming the field, value and range."""
        check_settings(self)


def box_inertia(mass, size):
    """Return the (3, 3) inertia [kg m^2] of a solid box of mass [kg] and edge lengths (3,) [m]."""
    check_range('mass', mass, 0.0, 1e3, 'kg', low_open=True)
    size = finite_array('size', size, (3,))
    squares = size ** 2
    return mass / 12.0 * np.diag([squares[1] + squares[2], squares[0] + squares[2],
                                  squares[0] + squares[1]])


def object_bias_wrench(mass, inertia_world, w_world_object, gravity=9.81):
    """
    Return b_o (6,): the wrench [N, N m] that balances gravity and the gyroscopic moment.

    mass [kg]; inertia_world (3, 3) about the centre of mass in world axes [kg m^2];
    w_world_object (3,) object angular velocity [rad/s]; gravity magnitude along -z [m/s^2].
    """
    if not (np.isfinite(mass) and mass > 0.0):
        raise InputError(f'object mass must be finite and > 0 kg, got {mass!r}')
    w_world_object = np.asarray(w_world_object, dtype=float)
    return np.concatenate(([0.0, 0.0, mass * gravity],
                           cross3(w_world_object, inertia_world @ w_world_object)))


def desired_object_wrench(v_world_object, w_world_object, v_world_desired, w_world_desired,
                          mass, inertia_world, config=None):
    """
    Return f_o^d (6,) [N, N m] from the passive DS on the object (section II-E).

    f_o^d = -D_o ([v; w] - [v_d; w_d]) + b_o, world frame, moment about the centre of mass.
    v/w_world_object: (3,) estimated object twist [m/s, rad/s]; v/w_world_desired: (3,) the
    object DS f(x_o) [m/s, rad/s]; mass [kg]; inertia_world (3, 3) [kg m^2].
    """
    config = ObjectWrenchConfig() if config is None else config
    v_error = (finite_array('v_world_object', v_world_object, (3,))
               - finite_array('v_world_desired', v_world_desired, (3,)))
    w_world_object = finite_array('w_world_object', w_world_object, (3,))
    w_error = w_world_object - finite_array('w_world_desired', w_world_desired, (3,))
    wrench = object_bias_wrench(mass, finite_array('inertia_world', inertia_world, (3, 3)),
                                w_world_object, config.gravity)
    wrench[:3] -= config.linear_damping * v_error
    wrench[3:] -= config.angular_damping * w_error
    if not config.include_moment:
        wrench[3:] = 0.0
    return wrench


def inertial_wrench(mass, inertia_world, a_world_desired, alpha_world_desired):
    """
    Return M_o [a_d; alpha_d] (6,) [N, N m]: the inertial part of the object's inverse dynamics.

    Added to the passive DS's f_o^d it is the feed-forward of footnote 3, so the hands push a
    heavy box along its desired motion instead of waiting for the velocity error to grow.
    """
    return np.concatenate((mass * finite_array('a_world_desired', a_world_desired, (3,)),
                           finite_array('inertia_world', inertia_world, (3, 3))
                           @ finite_array('alpha_world_desired', alpha_world_desired, (3,))))


def inverse_dynamics_object_wrench(a_world_desired, alpha_world_desired, w_world_object, mass,
                                   inertia_world, environment_wrench=None, gravity=9.81):
    """
    Return f_o^d (6,) [N, N m] from the object's inverse dynamics (footnote 3 of the paper).

    f_o^d = M_o [a_d; alpha_d] + b_o + f_env, M_o = diag(m I, I_world). a/alpha_world_desired:
    (3,) desired linear [m/s^2] and angular [rad/s^2] acceleration; w_world_object (3,)
    [rad/s]; environment_wrench: the paper's f_env (6,), the wrench the hands must add to
    counter environment loads, i.e. minus the wrench the environment applies [N, N m].
    """
    inertia_world = finite_array('inertia_world', inertia_world, (3, 3))
    wrench = object_bias_wrench(mass, inertia_world,
                                finite_array('w_world_object', w_world_object, (3,)), gravity)
    wrench += inertial_wrench(mass, inertia_world, a_world_desired, alpha_world_desired)
    if environment_wrench is not None:
        wrench += finite_array('environment_wrench', environment_wrench, (6,))
    return wrench
