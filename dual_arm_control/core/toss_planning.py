"""
Release state for a landing target: inverse ballistics over the release states the arms can hold.

A landing target alone does not fix the release: any point of a region in front of the robots
can be the release point, and from each a family of throws lands on the target. For every point
of a grid over the release region plan_release takes the throw at the speed the task prefers
(min_release_speed), or the least speed that reaches the target if that is more, on the
flatter of the two parabolas; it keeps the points within the speed, heading and elevation
limits and returns the one of least cost (speed, distance from the nominal release point and
from the preferred elevation), with the landing it predicts. A target no point serves is
refused with the limits missed by the candidate that misses fewest.
"""

from dataclasses import dataclass
from typing import NamedTuple

from dual_arm_control.core.ballistics import (landing_without_drag, STANDARD_GRAVITY,
                                              UnreachableTargetError)
from dual_arm_control.core.validation import check_range, check_vector, finite_array
import numpy as np


@dataclass(frozen=True)
class ReleasePlanningConfig:
    """
    Where and how fast the object may be released (world frame, SI units).

    x_range, y_range, z_range: the release region [m] (low, high): the arms hold the paper
        cube anywhere in it within their joint limits (checked by test_toss_planning with
        core.reachability). Defaults (0.60, 0.72), (-0.12, 0.12), (0.40, 0.55).
    grid_step: spacing of the candidate release points [m], > 0. Default 0.02.
    min_release_speed: m/s, > 0; the release speed of a near target (the toss DS needs to
        carry the box at a speed, not drop it). Default 0.6.
    max_release_speed: m/s, > min_release_speed; the fastest release planned. Default 1.3: the
        paper cube is then released within 2 % of its speed and 2 deg of its direction, though
        its pads slip ~1 cm on it (measured in the twin, toss_to_target).
    min_elevation_deg: flattest throw [deg]. Default 0.
    max_heading_deg: largest |heading| of the throw from world +x [deg]. Default 60.
    max_elevation_deg: steepest throw [deg]. Default 55.
    position_weight: m/s per m; cost of moving the release away from the nominal point against
        the speed it saves. Default 1.
    preferred_elevation_deg, elevation_weight (m/s per rad): the elevation the toss DS tracks
        best (that of the paper's release, 27 deg) and the cost of leaving it. Defaults 25, 1.
    """

    x_range: tuple = (0.60, 0.72)
    y_range: tuple = (-0.12, 0.12)
    z_range: tuple = (0.40, 0.55)
    grid_step: float = 0.02
    min_release_speed: float = 0.6
    max_release_speed: float = 1.3
    min_elevation_deg: float = 0.0
    max_heading_deg: float = 60.0
    max_elevation_deg: float = 55.0
    position_weight: float = 1.0
    preferred_elevation_deg: float = 25.0
    elevation_weight: float = 1.0

    def __post_init__(self):
        for name in ('x_range', 'y_range', 'z_range'):
            low, high = check_vector(name, getattr(self, name), 2, 'm')
            check_range(f'{name}[1]', high, low, 3.0, 'm')
        check_range('grid_step', self.grid_step, 0.0, 1.0, 'm', low_open=True)
        check_range('min_release_speed', self.min_release_speed, 0.0, 3.0, 'm/s',
                    low_open=True)
        check_range('max_release_speed', self.max_release_speed, self.min_release_speed, 3.0,
                    'm/s')
        check_range('min_elevation_deg', self.min_elevation_deg, -90.0, 90.0, 'deg')
        check_range('max_heading_deg', self.max_heading_deg, 0.0, 180.0, 'deg')
        check_range('max_elevation_deg', self.max_elevation_deg, self.min_elevation_deg, 90.0,
                    'deg')
        check_range('position_weight', self.position_weight, 0.0, 100.0, 'm/s per m')
        check_range('preferred_elevation_deg', self.preferred_elevation_deg,
                    self.min_elevation_deg, self.max_elevation_deg, 'deg')
        check_range('elevation_weight', self.elevation_weight, 0.0, 100.0, 'm/s per rad')


class ReleasePlan(NamedTuple):
    """A release state for a target: position (3,) [m], velocity (3,) [m/s], predicted landing."""

    position: np.ndarray
    velocity: np.ndarray
    predicted_landing: np.ndarray


def release_candidates(config):
    """Return the grid (n, 3) [m] over the release region: edges included, <= grid_step apart."""
    axes = [np.linspace(low, high, int(np.ceil((high - low) / config.grid_step - 1e-9)) + 1)
            for low, high in (config.x_range, config.y_range, config.z_range)]
    return np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1).reshape(-1, 3)


def plan_release(target, nominal_position, config, gravity=STANDARD_GRAVITY):
    """
    Return the ReleasePlan that lands the object centre on target (3,) [m].

    target is the object centre at rest on the landing surface; nominal_position (3,) [m] is
    the release point preferred when speeds tie. Raises UnreachableTargetError naming the
    limit that the best candidate misses.
    """
    target = finite_array('target', target, (3,))
    nominal_position = finite_array('nominal_position', nominal_position, (3,))
    positions = release_candidates(config)
    delta = target - positions
    r = np.hypot(delta[:, 0], delta[:, 1])
    z = delta[:, 2]
    least_speed = np.sqrt(gravity * (np.hypot(r, z) + z))
    speed = np.maximum(least_speed, config.min_release_speed)
    elevation = _elevations(r, z, speed, gravity, config)
    heading = np.degrees(np.arctan2(delta[:, 1], delta[:, 0]))
    misses = ((speed > config.max_release_speed, 'it needs {speed:.2f} m/s, above '
               f'max_release_speed {config.max_release_speed:g} m/s'),
              (np.abs(heading) > config.max_heading_deg, 'it needs a heading of {heading:.0f} '
               f'deg, beyond max_heading_deg {config.max_heading_deg:g}'),
              (np.isnan(elevation), 'no throw between min_elevation_deg '
               f'{config.min_elevation_deg:g} and max_elevation_deg '
               f'{config.max_elevation_deg:g} reaches it'),
              (r < 1e-3, 'it lies straight below a release point'))
    missed_count = np.sum([missed for missed, _ in misses], axis=0)
    usable = missed_count == 0
    if not usable.any():
        nearest = int(np.lexsort((speed, missed_count))[0])
        reason = '; '.join(text.format(speed=speed[nearest], heading=heading[nearest])
                           for missed, text in misses if missed[nearest])
        raise UnreachableTargetError(
            f'landing target {np.round(target, 3).tolist()} m cannot be reached from the '
            f'release region: {reason}')
    cost = (speed + config.position_weight * np.linalg.norm(positions - nominal_position, axis=1)
            + config.elevation_weight * np.abs(elevation
                                               - np.radians(config.preferred_elevation_deg)))
    best = int(np.argmin(np.where(usable, cost, np.inf)))
    direction = np.array([np.cos(elevation[best]) * delta[best, 0] / r[best],
                          np.cos(elevation[best]) * delta[best, 1] / r[best],
                          np.sin(elevation[best])])
    velocity = speed[best] * direction
    landing = landing_without_drag(positions[best], velocity, target[2], gravity).position
    return ReleasePlan(positions[best].copy(), velocity, landing)


def _elevations(r, z, speed, gravity, config):
    """
    Return the elevation [rad] (n,) of the flatter throw at speed within the limits, else NaN.

    tan(theta) solves a T^2 - r T + (z + a) = 0 with a = g r^2 / (2 v^2); the steeper root is
    used where the flatter one is below min_elevation_deg.
    """
    a = gravity * r ** 2 / (2.0 * speed ** 2)
    root = np.sqrt(np.maximum(r ** 2 - 4.0 * a * (z + a), 0.0))
    low = np.degrees(np.arctan((r - root) / (2.0 * a)))
    high = np.degrees(np.arctan((r + root) / (2.0 * a)))
    chosen = np.where(low >= config.min_elevation_deg, low, high)
    valid = (chosen >= config.min_elevation_deg) & (chosen <= config.max_elevation_deg)
    return np.where(valid, np.radians(chosen), np.nan)
