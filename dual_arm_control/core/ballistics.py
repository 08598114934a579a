"""
Projectile computations for tossing: release velocity for a landing target, landing prediction.

World frame, z up, SI units. Gravity acts along -z. A toss is reduced to the vertical plane
through the release and landing points: horizontal distance r = ||(p_land - p_release)_xy||,
height difference z = (p_land - p_release)_z (usually negative), heading
phi = atan2(dy, dx) and elevation theta of the release velocity above the horizontal.

Landing height: the tracked point (the object centre) lands when it reaches the height it has
while resting on the landing surface, not the surface height. For a box landing flat, that is
the surface height plus half the box height (centre_landing_height). Every landing function
takes that height, never the surface height.
"""

from dataclasses import dataclass
import math

from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.validation import check_range, finite_array
import numpy as np

STANDARD_GRAVITY = 9.81
"""Gravitational acceleration used throughout the project [m/s^2]."""

_MIN_HORIZONTAL_DISTANCE = 1e-9
_ROUNDING = 1e-12


class UnreachableTargetError(InputError):
    """No release velocity (within the given limits) lands the object on the target."""


@dataclass(frozen=True)
class FlightModel:
    """Point-mass flight model for numerical landing prediction."""

    gravity: float = STANDARD_GRAVITY
    """Gravitational acceleration along -z [m/s^2]."""
    drag_coefficient: float = 0.0
    """Quadratic drag per unit mass k = rho_air C_d A / (2 m) [1/m]: a_drag = -k ||v|| v."""
    integration_step: float = 0.01
    """RK4 step [s]; error ~ step^4 (0.01 s: < 1e-7 m/s on a 1.5 m fall with k = 0.4/m)."""
    max_flight_time: float = 10.0
    """Give up (UnreachableTargetError) if the landing height is not reached by then [s]."""

    def __post_init__(self):
        check_range('gravity', self.gravity, 0.0, 100.0, 'm/s^2', low_open=True)
        check_range('drag_coefficient', self.drag_coefficient, 0.0, 100.0, '1/m')
        check_range('integration_step', self.integration_step, 0.0, 0.1, 's', low_open=True)
        check_range('max_flight_time', self.max_flight_time, 0.0, 1e3, 's', low_open=True)


@dataclass(frozen=True)
class ReleaseSolution:
    """
    A release velocity that lands on the target.

    velocity (3,) world [m/s], speed [m/s], elevation above the horizontal and heading
    atan2(dy, dx) [rad], flight_time from release to landing [s].
    """

    velocity: np.ndarray
    speed: float
    elevation: float
    heading: float
    flight_time: float


@dataclass(frozen=True)
class Landing:
    """Where (3,) [m], with which velocity (3,) [m/s] and after how long [s] the object lands."""

    position: np.ndarray
    velocity: np.ndarray
    flight_time: float


def centre_landing_height(surface_height, object_height):
    """
    Return the height [m] of a box centre when the box rests flat on a surface.

    surface_height: height of the landing surface (table, conveyor) [m]; object_height: box
    edge length along the vertical at landing [m]. The centre lands half a box height above the
    surface, which is the landing_height the landing functions expect.
    """
    check_range('object_height', object_height, 0.0, math.inf, 'm')
    return float(surface_height) + 0.5 * float(object_height)


def minimum_speed_elevation(horizontal_distance, height_difference):
    """
    Return the release elevation [rad] that reaches (r, z) with the least speed.

    theta* = pi/4 + atan2(z, r)/2: the bisector between the vertical and the line of sight.
    """
    return 0.25 * math.pi + 0.5 * math.atan2(height_difference, horizontal_distance)


def release_speed(horizontal_distance, height_difference, elevation, gravity=STANDARD_GRAVITY):
    """
    Return the release speed [m/s] that reaches (r, z) [m] when launched at `elevation` [rad].

    v^2 = g r^2 / (2 cos^2(theta) (r tan(theta) - z)). Raises UnreachableTargetError when the
    elevation does not aim above the line of sight (r tan(theta) <= z) or is vertical.
    """
    r, z, theta = float(horizontal_distance), float(height_difference), float(elevation)
    if not -0.5 * math.pi < theta < 0.5 * math.pi:
        raise UnreachableTargetError(
            f'elevation {math.degrees(theta):.2f} deg must lie strictly between -90 and 90 deg '
            f'to reach a horizontal distance of {r:.4f} m')
    clearance = r * math.tan(theta) - z
    if clearance <= 0.0:
        raise UnreachableTargetError(
            f'elevation {math.degrees(theta):.2f} deg is not above the line of sight '
            f'{math.degrees(math.atan2(z, r)):.2f} deg to the target (r = {r:.4f} m, '
            f'z = {z:.4f} m): no speed reaches it')
    return math.sqrt(gravity * r ** 2 / (2.0 * math.cos(theta) ** 2 * clearance))


def flight_time(speed, elevation, height_difference, gravity=STANDARD_GRAVITY):
    """
    Return the time [s] to come down to height_difference z [m] after release.

    t = (v sin(theta) + sqrt(v^2 sin^2(theta) - 2 g z)) / g: the later (descending) root of
    z = v sin(theta) t - g t^2 / 2. Raises UnreachableTargetError if the apex is below z.
    """
    vertical_speed = float(speed) * math.sin(float(elevation))
    discriminant = vertical_speed ** 2 - 2.0 * gravity * float(height_difference)
    if discriminant < -_ROUNDING * (vertical_speed ** 2 + 1.0):
        apex = vertical_speed ** 2 / (2.0 * gravity)
        raise UnreachableTargetError(
            f'the flight apex is {apex:.4f} m above release, below the landing height '
            f'difference {float(height_difference):.4f} m')
    return (vertical_speed + math.sqrt(max(discriminant, 0.0))) / gravity


def release_velocity_minimum_speed(p_release, p_land, gravity=STANDARD_GRAVITY,
                                   max_speed=math.inf):
    """
    Return the ReleaseSolution of least speed from p_release (3,) to p_land (3,) [m], world.

    v_min^2 = g (sqrt(r^2 + z^2) + z) at theta* = pi/4 + atan2(z, r)/2; its apex lies at
    r (1 + z / sqrt(r^2 + z^2)) / 2 <= r, so the object always comes down onto the target. A
    target straight above needs a vertical throw, one straight below a release at rest. Raises
    UnreachableTargetError if the speed exceeds max_speed [m/s], InputError if the points
    coincide.
    """
    r, z, heading = _planar_geometry(p_release, p_land)
    if r < _MIN_HORIZONTAL_DISTANCE and abs(z) < _MIN_HORIZONTAL_DISTANCE:
        raise InputError('release and landing points coincide: no toss to compute')
    elevation = minimum_speed_elevation(r, z)
    if r < _MIN_HORIZONTAL_DISTANCE:
        speed = math.sqrt(2.0 * gravity * z) if z > 0.0 else 0.0
    else:
        speed = release_speed(r, z, elevation, gravity)
    return _solution(speed, elevation, heading, z, gravity, max_speed)


def release_velocity_at_elevation(p_release, p_land, elevation, gravity=STANDARD_GRAVITY,
                                  max_speed=math.inf):
    """
    Return the ReleaseSolution from p_release (3,) to p_land (3,) [m] at a fixed elevation [rad].

    The object must come down onto the target, not pass it while rising: for a target above
    the release (z > 0) that needs tan(theta) >= 2 z / r (the apex, at horizontal distance
    v^2 sin(theta) cos(theta) / g, must not lie beyond r). Raises UnreachableTargetError when
    the elevation is at or below the line of sight or too flat to descend onto the target,
    when the target is (almost) straight above or below the release (heading undefined), or
    when the speed exceeds max_speed [m/s].
    """
    r, z, heading = _planar_geometry(p_release, p_land)
    if r < _MIN_HORIZONTAL_DISTANCE:
        raise UnreachableTargetError(
            f'target is {r:.2e} m from the release horizontally: a fixed-elevation toss is '
            f'undefined; use release_velocity_minimum_speed')
    speed = release_speed(r, z, elevation, gravity)
    if r * math.tan(elevation) < 2.0 * z:
        raise UnreachableTargetError(
            f'at elevation {math.degrees(elevation):.2f} deg the object passes the target '
            f'(r = {r:.4f} m, z = {z:.4f} m) while still rising; it lands on it only from '
            f'{math.degrees(math.atan2(2.0 * z, r)):.2f} deg up')
    return _solution(speed, float(elevation), heading, z, gravity, max_speed)


def landing_without_drag(p_release, v_release, landing_height, gravity=STANDARD_GRAVITY):
    """
    Return the Landing of a point released at p_release (3,) [m] with v_release (3,) [m/s].

    Closed form of the drag-free parabola, landing when z comes down to landing_height [m]
    (see the module docstring for a box). Raises UnreachableTargetError if it never does.
    """
    p_release = finite_array('p_release', p_release, (3,))
    v_release = finite_array('v_release', v_release, (3,))
    height_difference = float(landing_height) - p_release[2]
    vertical_speed = v_release[2]
    discriminant = vertical_speed ** 2 - 2.0 * gravity * height_difference
    if discriminant < 0.0:
        raise UnreachableTargetError(
            f'apex {p_release[2] + vertical_speed ** 2 / (2.0 * gravity):.4f} m is below the '
            f'landing height {float(landing_height):.4f} m')
    t = (vertical_speed + math.sqrt(discriminant)) / gravity
    position, velocity = drag_free_state(p_release, v_release, t, gravity)
    return Landing(position=position, velocity=velocity, flight_time=t)


def drag_free_state(position, velocity, time, gravity=STANDARD_GRAVITY):
    """Return (position (3,) [m], velocity (3,) [m/s]) of a drag-free flight time [s] later."""
    acceleration = np.array([0.0, 0.0, -gravity])
    return (position + velocity * time + 0.5 * acceleration * time ** 2,
            velocity + acceleration * time)


def flight_derivative(velocity, model):
    """
    Return the acceleration (3,) [m/s^2] of a point in flight: -g z_hat - k ||v|| v.

    velocity (3,) [m/s]; model: FlightModel (gravity, quadratic drag per unit mass k).
    """
    acceleration = -model.drag_coefficient * np.linalg.norm(velocity) * velocity
    acceleration[2] -= model.gravity
    return acceleration


def landing_by_integration(p_release, v_release, landing_height, model=None):
    """
    Return the Landing predicted by integrating the flight with RK4, drag included.

    Classical RK4 on (p, v) with the derivative re-evaluated at every stage, until the point
    comes down through landing_height [m] (an ascending crossing is not a landing). The step
    that crosses is then shortened by Newton's method on its length (dz/dh = v_z) so the
    landing instant is found to integration accuracy rather than to one step. Raises
    UnreachableTargetError if the point is still above the landing height after
    model.max_flight_time, or falls below it while already descending below it.
    """
    model = model or FlightModel()
    position = finite_array('p_release', p_release, (3,)).copy()
    velocity = finite_array('v_release', v_release, (3,)).copy()
    landing_height = float(landing_height)
    if position[2] < landing_height and velocity[2] <= 0.0:
        raise UnreachableTargetError(
            f'released at {position[2]:.4f} m, below the landing height {landing_height:.4f} m, '
            f'without upward speed')
    step = model.integration_step
    elapsed = 0.0
    while elapsed < model.max_flight_time:
        next_position, next_velocity = _rk4_step(position, velocity, step, model)
        if next_position[2] <= landing_height and next_velocity[2] < 0.0 \
                and position[2] >= landing_height:
            h = _crossing_step(position, velocity, landing_height, step, model)
            position, velocity = _rk4_step(position, velocity, h, model)
            return Landing(position=position, velocity=velocity, flight_time=elapsed + h)
        if next_position[2] < landing_height and next_velocity[2] < 0.0:
            raise UnreachableTargetError(
                f'the apex stays below the landing height {landing_height:.4f} m')
        position, velocity = next_position, next_velocity
        elapsed += step
    raise UnreachableTargetError(
        f'the object is still above the landing height {landing_height:.4f} m after '
        f'{model.max_flight_time:g} s of flight')


def _rk4_step(position, velocity, h, model):
    k1_p, k1_v = velocity, flight_derivative(velocity, model)
    k2_p = velocity + 0.5 * h * k1_v
    k2_v = flight_derivative(k2_p, model)
    k3_p = velocity + 0.5 * h * k2_v
    k3_v = flight_derivative(k3_p, model)
    k4_p = velocity + h * k3_v
    k4_v = flight_derivative(k4_p, model)
    return (position + h / 6.0 * (k1_p + 2.0 * k2_p + 2.0 * k3_p + k4_p),
            velocity + h / 6.0 * (k1_v + 2.0 * k2_v + 2.0 * k3_v + k4_v))


def _crossing_step(position, velocity, landing_height, step, model):
    """Return h in (0, step] with z(h) = landing_height for the RK4 step from (p, v)."""
    h = step
    for _ in range(50):
        p, v = _rk4_step(position, velocity, h, model)
        correction = (p[2] - landing_height) / v[2]
        h = min(max(h - correction, 0.0), step)
        if abs(correction) < 1e-14:
            break
    return h


def _planar_geometry(p_release, p_land):
    p_release = finite_array('p_release', p_release, (3,))
    p_land = finite_array('p_land', p_land, (3,))
    delta = p_land - p_release
    return float(math.hypot(delta[0], delta[1])), float(delta[2]), math.atan2(delta[1],
                                                                              delta[0])


def _solution(speed, elevation, heading, height_difference, gravity, max_speed):
    if speed > max_speed:
        raise UnreachableTargetError(
            f'the target needs a release speed of {speed:.3f} m/s at elevation '
            f'{math.degrees(elevation):.2f} deg, above the limit {max_speed:.3f} m/s')
    direction = np.array([math.cos(elevation) * math.cos(heading),
                          math.cos(elevation) * math.sin(heading), math.sin(elevation)])
    return ReleaseSolution(velocity=speed * direction, speed=speed, elevation=elevation,
                           heading=heading,
                           flight_time=flight_time(speed, elevation, height_difference, gravity))
