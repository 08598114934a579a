"""
Release state for a landing target: inverse ballistics over the release states the arms can hold.

A landing target alone does not fix the release: any point of a region in front of the robots
can be the release point, and from each a family of throws lands on the target. For every point
of a grid over the release region plan_release takes the throw at the speed the task prefers
(min_release_speed), or the least speed that reaches the target if that is more, on the
flatter of the two parabolas; it keeps the points within the speed, heading, sideways speed
and elevation limits and returns the one of least cost (speed, distance from the nominal
release point and from the preferred elevation), with the landing it predicts. A target no
point serves is refused with the limits missed by the candidate that misses fewest.
"""

from dataclasses import dataclass
from typing import NamedTuple

from dual_arm_control.core.ballistics import (landing_without_drag, STANDARD_GRAVITY,
                                              UnreachableTargetError)
from dual_arm_control.core.settings import check_settings, setting
from dual_arm_control.core.validation import check_range, finite_array
import numpy as np


@dataclass(frozen=True)
class ReleasePlanningConfig:
    """Where and how fast the object may be released (world frame, SI units)."""

    x_range: tuple = setting(
        (0.60, 0.68), 'Release region along world x (low, high): the arms hold the paper cube '
        'anywhere in the region within their joint limits (checked by test_toss_planning with '
        'core.reachability).', unit='m', low=-3.0, high=3.0, size=2)
    y_range: tuple = setting(
        (-0.08, 0.12), 'Release region along world y (low, high): with the bases 1.3 m apart '
        'the left arm (iiwa7, the shorter) misses the far right corner (0.68, -0.12) by 6-20 mm, '
        'the right arm (iiwa14) holds the left one (0.68, 0.12).',
        unit='m', low=-3.0, high=3.0, size=2)
    z_range: tuple = setting(
        (0.40, 0.50), 'Release region along world z (low, high).',
        unit='m', low=-3.0, high=3.0, size=2)
    grid_step: float = setting(
        0.02, 'Spacing of the candidate release points.', unit='m', low=0, high=1.0, low_open=True)
    min_release_speed: float = setting(
        0.6, 'The release speed of a near target (the toss DS needs to carry the box at a speed, '
        'not drop it).', unit='m/s', low=0, high=3.0, low_open=True)
    max_release_speed: float = setting(
        1.8, 'The fastest release planned, at least min_release_speed. Default 1.8: the far '
        'corners of the 0.4 x 0.6 m landing region (x 1.15 m, y +-0.3 m) need 1.66-1.79 m/s '
        'from the release region; the twin releases the paper cube at 1.8 m/s within 2 % of '
        'its speed and 2 deg of its direction, pads slipping <= 6 mm (toss_to_target), but its '
        "joints then run up to 7x the iiwa's speed limits (see README, known limits).",
        unit='m/s', low=0, high=3.0, low_open=True)
    max_lateral_speed: float = setting(
        1.0, 'Largest release speed along world y (sideways): the bases lie on the y axis, so '
        "the pads' normals point near y and that part of the release velocity is pushed by one "
        'pad against the other. toss_workspace with max_release_speed 1.8: all 38 tosses up to '
        '1.0 m/s sideways held (slip <= 6.7 mm), 9 of the 13 at 1.04-1.25 m/s slipped 13-38 '
        'mm.',
        unit='m/s', low=0, high=3.0, low_open=True)
    min_elevation_deg: float = setting(0.0, 'Flattest throw.', unit='deg', low=-90.0, high=90.0)
    max_heading_deg: float = setting(
        60.0, 'Largest |heading| of the throw from world +x.', unit='deg', low=0, high=180.0)
    max_elevation_deg: float = setting(
        55.0, 'Steepest throw, at least min_elevation_deg.', unit='deg', low=-90.0, high=90.0)
    position_weight: float = setting(
        1.0, 'Cost of moving the release away from the nominal point against the speed it saves.',
        unit='m/s per m', low=0, high=100.0)
    preferred_elevation_deg: float = setting(
        25.0, "The elevation the toss DS tracks best (that of the paper's release, 27 deg), "
        'between min_elevation_deg and max_elevation_deg.', unit='deg', low=-90.0, high=90.0)
    elevation_weight: float = setting(
        1.0, 'Cost of leaving preferred_elevation_deg.', unit='m/s per rad', low=0, high=100.0)

    def __post_init__(self):
        check_settings(self)
        for name in ('x_range', 'y_range', 'z_range'):
            low, high = getattr(self, name)
            check_range(f'{name}[1]', high, low, 3.0, 'm')
        check_range('max_release_speed', self.max_release_speed, self.min_release_speed, 3.0,
                    'm/s')
        check_range('max_elevation_deg', self.max_elevation_deg, self.min_elevation_deg, 90.0,
                    'deg')
        check_range('preferred_elevation_deg', self.preferred_elevation_deg,
                    self.min_elevation_deg, self.max_elevation_deg, 'deg')


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
    lateral = speed * np.cos(elevation) * np.abs(np.sin(np.radians(heading)))
    misses = ((speed > config.max_release_speed, 'it needs {speed:.2f} m/s, above '
               f'max_release_speed {config.max_release_speed:g} m/s'),
              (np.abs(heading) > config.max_heading_deg, 'it needs a heading of {heading:.0f} '
               f'deg, beyond max_heading_deg {config.max_heading_deg:g}'),
              (lateral > config.max_lateral_speed, 'it needs {lateral:.2f} m/s along world y, '
               f'above max_lateral_speed {config.max_lateral_speed:g} m/s'),
              (np.isnan(elevation), 'no throw between min_elevation_deg '
               f'{config.min_elevation_deg:g} and max_elevation_deg '
               f'{config.max_elevation_deg:g} reaches it'),
              (r < 1e-3, 'it lies straight below a release point'))
    missed_count = np.sum([missed for missed, _ in misses], axis=0)
    usable = missed_count == 0
    if not usable.any():
        nearest = int(np.lexsort((speed, missed_count))[0])
        reason = '; '.join(text.format(speed=speed[nearest], heading=heading[nearest],
                                       lateral=lateral[nearest])
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
    used where the flatter one is below min_elevation_deg. A candidate right above the target
    (r = 0) has no elevation: NaN, not a division warning.
    """
    a = gravity * r ** 2 / (2.0 * speed ** 2)
    root = np.sqrt(np.maximum(r ** 2 - 4.0 * a * (z + a), 0.0))
    with np.errstate(divide='ignore', invalid='ignore'):
        low = np.degrees(np.arctan((r - root) / (2.0 * a)))
        high = np.degrees(np.arctan((r + root) / (2.0 * a)))
    chosen = np.where(low >= config.min_elevation_deg, low, high)
    valid = (chosen >= config.min_elevation_deg) & (chosen <= config.max_elevation_deg)
    return np.where(valid, np.radians(chosen), np.nan)
