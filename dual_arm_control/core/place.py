"""
The pick-and-place object DS: carry the box high, descend onto the place, clear of the pallet.

A function of the object's position (eq. 7's x_d^o for the place task), capped in speed; the
box keeps clear of the pallet it was picked from while it comes down near it.
"""

from dataclasses import dataclass
import math

from dual_arm_control.core.geometry import rpy_to_matrix, turned_rectangle_half_extents
from dual_arm_control.core.settings import check_settings, setting
from dual_arm_control.core.speed_shaping import saturated_velocity, speed_blend_weight
from dual_arm_control.core.validation import check_range, finite_array
import numpy as np


@dataclass(frozen=True)
class PlaceConfig:
    """
    Pick-and-place DS: approach the place from above, then descend and stop on it.

    pallet: ((x_min, x_max), (y_min, y_max), top height) [m] of the pallet's top face, set from
    the cell (not tunable, like the standby poses; empty: none), which the carried box clears
    by pallet_clearance.
    """

    position: tuple = setting(
        (0.70, -0.12, 0.25), 'Place position of the object, world frame. Default (0.70, -0.12, '
        '0.25) (reference placing pose).', unit='m', size=3)
    approach_height: float = setting(
        0.05, 'Height above the place at which the object travels. Default 0.05 (reference '
        'height_via_point).', unit='m', low=0, high=1.0, low_open=True)
    descent_start_distance: float = setting(
        0.10, 'Horizontal distance to the place below which the descent begins. Default 0.10 '
        '(reference).', unit='m', low=0, high=1.0, low_open=True)
    descent_end_distance: float = setting(
        0.02, 'Horizontal distance below which the target is the place itself; less than '
        'descent_start_distance.', unit='m', low=0, high=1.0, high_open=True)
    max_speed: float = setting(
        0.5, 'Speed cap of the object. The pads slide most while the carry gets up to speed '
        'and the box turns square: at 0.85 (the toss speed) the boxes of '
        'catalogue_random_place (seed 12, 300 trials) slipped p95 5.4 mm, max 10.2 (heavy '
        'boxes yawed 14-24 deg), at 0.5 p95 4.1, max 8.5, the median cycle 0.14 s longer '
        '(287 and 288 succeed).', unit='m/s', low=0, high=3.0, low_open=True)
    lift_height: float = setting(
        0.03, 'The object travels at least this far above the height it was picked up at, so '
        "it leaves its support before crossing the support's edge (a box carried straight "
        'toward a lower place dragged along the pallet).', unit='m', low=0, high=0.5)
    descent_speed: float = setting(
        0.15, "Cap of the object's downward speed: carried above its pick height, the box "
        "drops up to 0.1 m onto the place, which the DS's rate alone took at up to 0.37 m/s.",
        unit='m/s', low=0, high=3.0, low_open=True)
    yaw_deg: float = setting(
        0.0, 'Yaw of the object when put down, world frame: the carry turns it upright to this '
        "yaw (the carried object's orientation DS), so a box picked up to 25 deg "
        'off is placed square, where the arms also reach it best (catalogue_random_place, '
        'seed 12, 60 trials: slip p95 1.1 cm against 2.6 cm left free).',
        unit='deg', low=-180.0, high=180.0)
    max_angular_speed: float = setting(
        1.0, "Cap of the carried box's angular speed while it turns to yaw_deg (at most the "
        "orientation DS's max_angular_speed). At that 3 rad/s a box picked up 17-25 deg off "
        'turned within about 0.15 s of the grasp, faster than the arms turn their pads: they '
        'rocked on the faces by up to 21 deg and slid (catalogue_random_place, seed 12, 60 '
        'trials: slip p95 8.9 mm, max 13.2; 5.6 and 6.6 mm at 1 rad/s, which turns 25 deg in '
        'under 0.5 s of a carry of 1.15-2.1 s; on the 13 worst-slip trials 0.5 and 0.7 rad/s '
        'slipped as much as 1).',
        unit='rad/s', low=0, high=10.0, low_open=True)
    pallet_clearance: float = setting(
        0.005, "Kept between the carried box and the pallet: the box's bottom stays this far "
        "above the pallet's top while its footprint comes within this distance of the pallet "
        '(a box lowered onto a place near the pallet caught its edge and hung on it).',
        unit='m', low=0, high=0.1)
    pallet: tuple = ()

    def __post_init__(self):
        check_settings(self)
        check_range('descent_end_distance', self.descent_end_distance, 0.0,
                    self.descent_start_distance, 'm', high_open=True)


def place_rotation(config):
    """Return the object's orientation R (3, 3) at a PlaceConfig's place: upright, at yaw_deg."""
    return rpy_to_matrix((0.0, 0.0, np.radians(config.yaw_deg)))


def place_target(x_object, config, pick_height=None, object_size=None):
    """
    Return the moving target (3,) [m] of the place DS.

    The place position raised by w times the travel height, w = 1 beyond
    descent_start_distance (horizontal) and 0 inside descent_end_distance (smoothstep between):
    the object travels high, then descends onto the place once above it. The travel height is
    approach_height above the place, and at least lift_height above pick_height [m] (world z
    of the object where it was picked up), when given. Given the box's object_size (3,) [m],
    the target stays above pallet_floor.
    """
    place = np.asarray(config.position, dtype=float)
    travel = config.approach_height
    if pick_height is not None:
        travel = max(travel, pick_height + config.lift_height - place[2])
    horizontal = np.hypot(x_object[0] - place[0], x_object[1] - place[1])
    weight = speed_blend_weight(horizontal, config.descent_end_distance,
                                config.descent_start_distance)
    target = place + np.array([0.0, 0.0, travel * weight])
    if object_size is not None and config.pallet:
        target[2] = max(target[2], pallet_floor(x_object, config, object_size))
    return target


def pallet_floor(x_object, config, object_size):
    """
    Return the lowest centre height [m] of a box at x_object (3,) [m], -inf if clear of the pallet.

    The box's footprint (object_size (3,) [m] turned by the place yaw; its bounding rectangle)
    closer to the pallet (config.pallet) than pallet_clearance keeps its bottom that far above
    the pallet's top.
    """
    (x_min, x_max), (y_min, y_max), top = config.pallet
    half_x, half_y = turned_rectangle_half_extents(
        math.radians(config.yaw_deg), 0.5 * object_size[0], 0.5 * object_size[1])
    reach_x = half_x + config.pallet_clearance
    reach_y = half_y + config.pallet_clearance
    if (x_object[0] + reach_x <= x_min or x_object[0] - reach_x >= x_max
            or x_object[1] + reach_y <= y_min or x_object[1] - reach_y >= y_max):
        return -math.inf
    return top + 0.5 * object_size[2] + config.pallet_clearance


def place_velocity(x_object, config, coordination, pick_height=None, object_size=None):
    """
    Return the object velocity (3,) [m/s] of the pick-and-place DS, capped at max_speed.

    -k_abs (x^o - place_target(x^o)): linear near the place, so the object slows to zero on it;
    its downward component no faster than descent_speed.
    """
    x_object = finite_array('x_object', x_object, (3,))
    velocity = -coordination.absolute_gain * (x_object - place_target(
        x_object, config, pick_height, object_size))
    velocity[2] = max(velocity[2], -config.descent_speed)
    return saturated_velocity(velocity, config.max_speed)
