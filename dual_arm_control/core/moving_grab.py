"""
Grabbing a box that a belt carries (issue 15): follow its predicted motion, then carry it off.

The paper grabs a box at rest (section III). On a belt the box moves at the belt's velocity, so
three things change, each a small rule here. The impact DS (eqs. 1-6) is written relative to
the grasp points, which the generator recomputes every tick from the tracker's estimate
(predicted to the tick, the mocap latency included); adding the box's velocity to the tool
velocities as feed-forward makes the tools move with the box and hit it at the desired
impact speed *relative* to it (belt_feed_forward). The reach starts only when the box is
predicted to be in the grab range at the contact, a reach duration ahead
(grab_wait_reason), so the contact happens where the arms can reach. After both pads hold the
box, the object DS (eqs. 7-9) starts from the box's belt velocity, which fades out
(decayed_belt_velocity), so the grab does not stop the box on the belt before lift-off.
"""

from dataclasses import dataclass
import math

from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.settings import check_settings, setting
import numpy as np


@dataclass(frozen=True)
class MovingGrabConfig:
    """How the motion generator grabs a box carried by a belt."""

    enabled: bool = setting(
        False, 'Grab the box from the moving incoming belt (set by the scenario).')
    reach_duration: float = setting(
        1.37, 'Predicted time from the start of the reach to the contact; the box is predicted '
        'this far ahead to decide the start (measured on the paper_toss placement).',
        unit='s', low=0.0, high=10.0)
    grab_y_range: tuple = setting(
        (-0.06, 0.02), 'World y range (low, high) where the box may be at the contact: the reach '
        'starts when the box is predicted to be in it a reach duration ahead.',
        unit='m', low=-3.0, high=3.0, size=2)
    velocity_time_constant: float = setting(
        0.1, "Time constant of the low-pass filter on the tracker's box velocity that gives the "
        "belt velocity (the tracker's velocity is noisy and overshoots when the belt starts).",
        unit='s', low=0.0, high=5.0, low_open=True)
    tracking_gain: float = setting(
        1.02, 'Gain on the reach command that moves with the box (the DS velocity relative to '
        "the box plus the box's belt velocity). The torque-controlled arms reach a few % less "
        'than a commanded speed, so at 1 the pad chasing the box (the faster in the world) '
        'closes on it slower than the pad the box comes toward (40 conveyor_grab trials, bases '
        '1.2 m apart: gap up to 10 ms at 1.0, 8 ms at 1.015-1.03; at 1.06 the right pad met the '
        'box up to 17 % fast relative to it, 11 of 40 over the 15 % limit).', low=0.0, high=2.0)
    carry_time_constant: float = setting(
        0.15, "The box's belt velocity, added to the object DS at the grasp, fades out with "
        'this time constant.', unit='s', low=0.0, high=5.0, low_open=True)

    synchronisation_max_speedup: float = setting(
        1.2, 'impact.synchronisation_max_speedup in a moving grab, whose synchroniser works on '
        "the pads' centres: at 1.35 the arm behind struck the belt box up to 19 % fast "
        '(conveyor_grab: 47 of 100 within the 15 % limit, 100 of 100 at 1.2).', low=1.0,
        high=3.0)

    def __post_init__(self):
        check_settings(self)
        low, high = self.grab_y_range
        if low > high:
            raise ConfigError(f'grab_y_range must be (low, high), got {self.grab_y_range}')


def belt_velocity(v_world_object):
    """Return the box's velocity in the belt plane (3,) [m/s]: its horizontal part."""
    velocity = np.array(v_world_object, dtype=float)
    velocity[2] = 0.0
    return velocity


def filtered_belt_velocity(previous, v_world_object, dt, time_constant):
    """Return the belt velocity (3,) [m/s]: first-order low-pass of the box's, one tick dt."""
    weight = 1.0 - math.exp(-dt / time_constant)
    previous = np.asarray(previous, dtype=float)
    return previous + weight * (belt_velocity(v_world_object) - previous)


def predicted_box_position(p_world_object, v_world_object, horizon):
    """Return where the box will be after horizon [s] at its current belt velocity (3,) [m]."""
    return np.asarray(p_world_object, dtype=float) + belt_velocity(v_world_object) * horizon


def grab_wait_reason(p_predicted, config):
    """Return why the reach must wait for a box predicted at p_predicted at contact, else ''."""
    low, high = config.grab_y_range
    y = float(p_predicted[1])
    if low <= y <= high:
        return ''
    return (f'box predicted at y = {y:.3f} m at the contact, outside the grab range '
            f'[{low:.2f}, {high:.2f}] m')


def belt_feed_forward(velocity, v_belt, gain=1.0):
    """
    Return the tools' velocities (2, 3) [m/s]: gain times (velocity + the box's belt velocity).

    The impact DS gives the tools' velocities relative to grasp points that move with the box;
    the feed-forward makes the absolute velocity that plus the box's, so the impact speed
    along the impact direction, relative to the box, is the DS's (eqs. 1-6 in the box's frame).
    A gain above 1 makes up for the arms' tracking shortfall, which is proportional to the
    absolute speed and so differs between the chasing pad and the one the box comes toward.
    """
    return gain * (np.asarray(velocity, dtype=float) + np.asarray(v_belt, dtype=float)[None, :])


def decayed_belt_velocity(v_belt, dt, time_constant):
    """Return the belt velocity carried into the object DS, faded by one tick of dt [s]."""
    return np.asarray(v_belt, dtype=float) * math.exp(-dt / time_constant)
