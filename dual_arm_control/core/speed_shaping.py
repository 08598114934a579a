"""
"Boosted" DS fields: keep the direction of a DS output, impose its speed (paper section IV-A).

Far from the object the arms move at the reach speed, near it at the impact speed; during a
toss the object moves at the toss speed. Speeds are functions of the state, so no filter is
needed; SpeedFilter smooths a speed target that jumps (phase switches) with a time constant.
"""

from dataclasses import dataclass
import math

from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.geometry import last_axis_norms
from dual_arm_control.core.settings import check_settings, setting
from dual_arm_control.core.validation import check_range
import numpy as np

_MIN_SPEED = 1e-9


@dataclass(frozen=True)
class SpeedProfileConfig:
    """Speed profile of the reach with impact."""

    reach_speed: float = setting(
        0.85, "Speed of the faster arm far from the object. Default 0.85, the reference's "
        'desVreach.', unit='m/s', low=0, high=2.0, low_open=True)
    near_distance: float = setting(
        0.25, 'Distance to the grasp point below which the impact speed applies; must cover the '
        'run from the transitory attractor (its rho, 0.2 m) with some margin.',
        unit='m', low=0, high=2.0)
    far_distance: float = setting(
        0.50, 'Distance above which the reach speed applies; more than near_distance.',
        unit='m', low=0, high=5.0, low_open=True)
    time_constant: float = setting(
        0.05, 'Time constant of SpeedFilter.', unit='s', low=0, high=10.0, low_open=True)

    def __post_init__(self):
        check_settings(self)
        check_range('far_distance', self.far_distance, self.near_distance, 5.0, 'm',
                    low_open=True)


def speed_blend_weight(distance, near_distance, far_distance):
    """
    Return w in [0, 1]: 0 at or below near_distance, 1 at or above far_distance.

    Cubic smoothstep in between (continuous with continuous slope).
    """
    ratio = np.clip((np.asarray(distance, dtype=float) - near_distance)
                    / (far_distance - near_distance), 0.0, 1.0)
    return ratio * ratio * (3.0 - 2.0 * ratio)


def profile_speed(distance, near_speed, far_speed, near_distance, far_distance):
    """Return near_speed + (far_speed - near_speed) w(distance) [m/s]."""
    weight = speed_blend_weight(distance, near_distance, far_distance)
    return near_speed + (far_speed - near_speed) * weight


def reach_speed(distance, impact_speed, config):
    """Return the reach-with-impact speed [m/s] at a distance [m] from the grasp points."""
    return profile_speed(distance, impact_speed, config.reach_speed, config.near_distance,
                         config.far_distance)


def boosted_velocity(velocity, speed):
    """
    Return speed * velocity / |velocity| (..., 3) [m/s]: one point's DS direction at a speed.

    For one arm or the object. Where the DS output vanishes, zero is returned.
    """
    velocity = np.asarray(velocity, dtype=float)
    norm = last_axis_norms(velocity)
    return np.where(norm > _MIN_SPEED, velocity * (np.asarray(speed)[..., None]
                                                   / np.maximum(norm, _MIN_SPEED)), 0.0)


def boosted_coordinated_velocity(velocity, speed):
    """
    Return the coordinated field (6,) scaled so that the faster arm moves at speed [m/s].

    Both arms are scaled by the same factor: a positive scaling of the whole 6D field is a
    change of time along the same trajectories, so the coordination (simultaneous contact)
    is preserved. Normalising each arm to its own speed would erase the relative motion that
    lets one arm wait for the other. Where both arms' outputs vanish, zero is returned.
    """
    velocity = np.asarray(velocity, dtype=float)
    fastest = max(math.sqrt(velocity[:3] @ velocity[:3]), math.sqrt(velocity[3:] @ velocity[3:]))
    if fastest <= _MIN_SPEED:
        return np.zeros(6)
    return velocity * (speed / fastest)


def arm_velocities_near_object(velocity, speed, distance, config):
    """
    Return the two arms' reach velocities (2, 3) [m/s] from the coordinated field (6,).

    Beyond far_distance [m] of the grasp points both arms keep the coordinated field's ratio
    (boosted_coordinated_velocity), so eq. 4's coordination brings them in together; within
    near_distance each arm moves at speed along its own DS direction, so both pads strike at
    the impact speed (eq. 5) and the arrival synchroniser does the timing. The coordinated
    field alone slowed the nearer arm to 0.37 m/s of 0.5 at 25 deg of yaw. Smoothstep blend
    in between.
    """
    coordinated = boosted_coordinated_velocity(velocity, speed).reshape(2, 3)
    weight = float(speed_blend_weight(distance, config.near_distance, config.far_distance))
    return (weight * coordinated
            + (1.0 - weight) * boosted_velocity(coordinated, np.full(2, speed)))


def saturated_velocity(velocity, max_speed):
    """
    Return velocity (..., 3) rescaled per point to at most max_speed [m/s].

    A single point is scaled in Python floats: the same operations as the array form (summed
    squares in order, correctly rounded square root) without NumPy's dispatch.
    """
    velocity = np.asarray(velocity, dtype=float)
    if velocity.shape == (3,):
        x, y, z = velocity.tolist()
        norm = math.sqrt(x * x + y * y + z * z)
        return velocity * min(max_speed / max(norm, _MIN_SPEED), 1.0)
    norm = last_axis_norms(velocity)
    return velocity * np.minimum(1.0, max_speed / np.maximum(norm, _MIN_SPEED))


def _check_step(dt):
    """Raise InputError unless the time step dt [s] is finite and >= 0."""
    if not (math.isfinite(dt) and dt >= 0.0):
        raise InputError(f'dt must be finite and >= 0 s, got {dt!r}')


class SpeedFilter:
    """
    First-order low-pass of a speed [m/s]: ds/dt = (target - s) / time_constant.

    Discretised exactly for a constant target over each step, so the response does not
    depend on the call rate.
    """

    def __init__(self, time_constant, initial_speed=0.0):
        """Create the filter; time_constant [s] > 0, initial_speed [m/s]."""
        self.time_constant = check_range('time_constant', time_constant, 0.0, math.inf, 's',
                                         low_open=True)
        self.speed = float(initial_speed)

    def reset(self, speed=0.0):
        """Set the filtered speed [m/s]."""
        self.speed = float(speed)

    def update(self, target_speed, dt):
        """Advance by dt [s] toward target_speed [m/s]; return the filtered speed."""
        _check_step(dt)
        self.speed += (1.0 - math.exp(-dt / self.time_constant)) * (target_speed - self.speed)
        return self.speed


class SpeedErrorIntegrator:
    """
    Outer speed loop on a DS output: v_cmd = v_d (1 + k_i int(|v_d| - v . v_d/|v_d|) dt / |v_d|).

    The passive controller follows the desired velocity with a lag that grows with the load
    (the object's weight and inertia), so a carried object leaves the hands slower than
    planned. Integrating the tracked object's speed shortfall along the DS direction and adding
    it to the DS speed removes that lag without turning the DS direction. The correction is
    capped to +-limit_ratio |v_d| so a bad estimate cannot run away.
    """

    def __init__(self, integral_gain, limit_ratio):
        """Create the loop: integral_gain [1/s], limit_ratio [-] of the desired speed."""
        self.integral_gain = check_range('integral_gain', integral_gain, 0.0, 200.0, '1/s')
        self.limit_ratio = check_range('limit_ratio', limit_ratio, 0.0, 1.0)
        self.correction = 0.0

    def reset(self):
        """Forget the integrated shortfall."""
        self.correction = 0.0

    def update(self, desired, measured, dt):
        """Return the corrected velocity (3,) [m/s] after integrating the shortfall over dt [s]."""
        _check_step(dt)
        desired = np.asarray(desired, dtype=float)
        speed = math.sqrt(desired @ desired)
        if speed <= _MIN_SPEED:
            return desired
        shortfall = speed - float(np.asarray(measured, dtype=float) @ desired) / speed
        limit = self.limit_ratio * speed
        self.correction = min(max(self.correction + self.integral_gain * dt * shortfall, -limit),
                              limit)
        return desired * (1.0 + self.correction / speed)


def released_velocity(field_velocity, corrected_velocity, correction_share):
    """
    Return the object velocity (3,) [m/s] the pads keep while they open at a toss's release.

    field_velocity is the toss field's, corrected_velocity the speed loop's command
    (SpeedErrorIntegrator); correction_share [0, 1] of the correction is kept. The arms carry
    the box until the pads let go of it, so dropping the correction slows a heavy box as it
    leaves; keeping all of it pushes a light one fast (toss.release_correction_share).
    """
    field_velocity = np.asarray(field_velocity, dtype=float)
    return field_velocity + correction_share * (np.asarray(corrected_velocity) - field_velocity)
