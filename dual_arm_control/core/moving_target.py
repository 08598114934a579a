"""
Toss into a moving container: where to aim so that the box lands where the container will be.

The landing target is the container's predicted position at the predicted landing time, and
that time depends on the target: the release plan for a target (core.toss_planning) fixes the
release point, hence how long the arms still need to get there (time_to_release, from the DS
state), and the flight time of its parabola. aim_at_moving_container solves
target = container(now + time_to_release(plan(target)) + flight(plan(target))) by fixed-point
iteration, started from the container's position at the landing time of the current plan. The
map is a contraction when the landing time changes slowly with the target (release point held,
belt at 0.1-0.4 m/s): in the tests six iterations leave a residual below a millimetre, four
left 2.4 mm at 0.4 m/s.
"""

from dataclasses import dataclass
from typing import NamedTuple

from dual_arm_control.core.ballistics import landing_without_drag
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.phases import Phase
from dual_arm_control.core.settings import check_settings, setting
import numpy as np


@dataclass(frozen=True)
class ConveyorTossConfig:
    """When and how the toss aims into a container carried by a belt."""

    enabled: bool = setting(
        False, 'Aim the toss into the moving container of the scenario (set by the scenario).')
    landing_height: float = setting(
        0.32, "World z of the box centre when the box's bottom passes the container's rim: the "
        'plane the toss aims in (set by the scenario).', unit='m', low=-1.0, high=3.0)
    belt_axis: tuple = setting(
        (0.0, 1.0, 0.0), 'Direction the belt carries the container along (world): the '
        "container's estimated velocity is taken along it only.", low=-1.0, high=1.0, size=3)
    landing_y_range: tuple = setting(
        (-0.30, 0.15), 'Belt positions (world y, low, high) where a toss may land: the throw '
        'starts when the container is predicted to be in this range at the landing.',
        unit='m', low=-3.0, high=3.0, size=2)
    fixed_point_iterations: int = setting(
        6, 'Iterations of target -> release plan -> landing time -> container position.',
        low=1, high=50)
    reach_duration: float = setting(
        1.37, 'Time from the start of the reach to the contact (measured in the twin on the '
        'paper_toss placement at reach speed 0.85 m/s).', unit='s', low=0.0, high=10.0)
    run_in_speed: float = setting(
        0.45, 'Tool speed over the last part of the reach: the remaining reach takes at least '
        "the tools' distance to their grasp points at this speed.",
        unit='m/s', low=0.0, high=3.0, low_open=True)
    carry_lag: float = setting(
        0.02, 'Time the box needs beyond distance / toss speed to reach the release plane (its '
        'speed ramps up from the impact speed).', unit='s', low=0.0, high=2.0)

    def __post_init__(self):
        check_settings(self)
        low, high = self.landing_y_range
        if low > high:
            raise ConfigError(f'landing_y_range must be (low, high), got {self.landing_y_range}')
        if np.linalg.norm(self.belt_axis) < 0.5:
            raise ConfigError(f'belt_axis must be a unit vector, got {self.belt_axis}')


class MovingTargetAim(NamedTuple):
    """
    The solution of the fixed point.

    target (3,) [m]: landing target (box centre at rest); plan: its ReleasePlan; landing_time
    [s]: predicted landing (absolute); release_in, flight_time [s]; residual [m]: how far the
    last iteration moved the target.
    """

    target: np.ndarray
    plan: object
    landing_time: float
    release_in: float
    flight_time: float
    residual: float


def carry_time(object_position, release_position, release_velocity, config):
    """
    Return the time [s] the carried box needs to reach the release plane.

    The distance to the plane through the release point across the release velocity, at the
    release speed, plus carry_lag (the speed ramps up from the impact speed after contact).
    """
    speed = float(np.linalg.norm(release_velocity))
    direction = np.asarray(release_velocity, dtype=float) / speed
    distance = max(float(np.dot(np.asarray(release_position) - object_position, direction)), 0.0)
    return config.carry_lag + distance / speed


def time_to_release(phase, time_in_phase, reach_distance, object_position, release_position,
                    release_velocity, config):
    """
    Return the predicted time [s] until the box is released, from the DS state.

    STANDBY (before the start): the whole reach and carry; REACH: what is left of the nominal
    reach, but at least the tools' largest distance to their grasp points (reach_distance [m])
    at run_in_speed; CONTACT, MANIPULATE: the carry only. None after the release.
    """
    if phase in (Phase.RELEASE, Phase.RETRACT):
        return None
    carry = carry_time(object_position, release_position, release_velocity, config)
    if phase is Phase.STANDBY:
        return config.reach_duration + carry
    if phase is Phase.REACH:
        return max(config.reach_duration - time_in_phase,
                   reach_distance / config.run_in_speed) + carry
    return carry


def aim_at_moving_container(now, container_position_at, plan_for, release_in_for, first_target,
                            config):
    """
    Return the MovingTargetAim whose landing meets the container (fixed-point iteration).

    now [s]; container_position_at(t): the container's predicted landing point (3,) at time t
    (its centre, z = the box's landing height); plan_for(target): the ReleasePlan of a target
    (raises UnreachableTargetError); release_in_for(plan): time to release [s] with that plan;
    first_target (3,): the starting guess. Raises UnreachableTargetError when an iterate has no
    release (the target is out of the region the planner serves at that instant).
    """
    target = np.asarray(first_target, dtype=float)
    residual = np.inf
    for _ in range(config.fixed_point_iterations):
        plan = plan_for(target)
        release_in = release_in_for(plan)
        flight = landing_without_drag(plan.position, plan.velocity, target[2]).flight_time
        landing_time = now + release_in + flight
        new_target = np.asarray(container_position_at(landing_time), dtype=float)
        residual = float(np.linalg.norm(new_target - target))
        target = new_target
    plan = plan_for(target)
    release_in = release_in_for(plan)
    flight = landing_without_drag(plan.position, plan.velocity, target[2]).flight_time
    return MovingTargetAim(target, plan, now + release_in + flight, release_in, flight, residual)


def along_belt(velocity, config):
    """Return velocity (3,) [m/s] projected on the belt axis (the container moves only so)."""
    axis = np.asarray(config.belt_axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    return float(np.dot(velocity, axis)) * axis


def in_landing_range(target, config):
    """Return True if target (3,) lies in the belt range where a toss may land."""
    low, high = config.landing_y_range
    return low <= float(target[1]) <= high
