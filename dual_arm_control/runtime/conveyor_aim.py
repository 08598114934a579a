"""
Aiming the toss at the conveyor's container, once per DS tick (core.moving_target).

container_aim() takes the tick's DS state (phase, time in phase, tool and object positions),
the tracker's container estimate and the current configuration, solves the landing fixed
point and returns the configuration whose release lands the box in the container, or the
reason it cannot: no container track yet, the container out of the region the release planner
serves at the predicted landing, or (before the start) predicted outside landing_y_range. The
motion generator role waits at standby while there is a reason, and keeps its last aim when a
later tick has one.
"""

from dataclasses import replace
from typing import NamedTuple

from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.ballistics import landing_without_drag, UnreachableTargetError
from dual_arm_control.core.grasp import grasp_frame
from dual_arm_control.core.manipulation import release_velocity, TossConfig
from dual_arm_control.core.moving_target import (aim_at_moving_container, along_belt,
                                                 in_landing_range, time_to_release)
from dual_arm_control.core.phases import Phase
from dual_arm_control.core.toss_planning import plan_release
from dual_arm_control.runtime.configuration import config_for_release_plan
from dual_arm_control.runtime.timing import estimate_at, NANOSECONDS_PER_SECOND
import numpy as np


class ContainerAim(NamedTuple):
    """config: the configuration to toss with (None when reason); aim: the MovingTargetAim."""

    config: object
    aim: object
    reason: str


def container_landing_point(container, conveyor):
    """
    Return f(t) -> the container's predicted centre (3,) at t [s], z at the landing height.

    Constant velocity along the belt axis (conveyor: ConveyorTossConfig): the velocity
    estimate's noise across the belt would otherwise grow with the horizon into the aim.
    """
    stamp = container.stamp_ns / NANOSECONDS_PER_SECOND
    position = np.array(container.position, dtype=float)
    velocity = along_belt(container.linear_velocity, conveyor)
    landing_height = conveyor.landing_height

    def position_at(t):
        point = position + velocity * (t - stamp)
        point[2] = landing_height
        return point
    return position_at


def reach_distance(p_tools, p_object, R_object, size, grasp_offset):
    """Return the largest distance [m] from a tool to its grasp point on the box."""
    return max(float(np.linalg.norm(
        p_tools[arm] - grasp_frame(arm, p_object, R_object, size, grasp_offset).p_world_grasp))
        for arm in ARMS)


def container_aim(stamp_ns, config, phase, time_in_phase, p_tools, estimate, container,
                  grasp_offset=(0.0, 0.0, 0.0), release_point=None):
    """
    Return the ContainerAim of a DS tick.

    config: MotionGeneratorConfig (its conveyor, toss and release_planning); phase (core
    Phase) and time_in_phase [s] of the last tick; p_tools {arm: (3,)}; estimate, container:
    ObjectStates of the box and of the container; release_point (3,) [m]: plan only the
    release velocity, from this point (None: the point the planner picks, over the whole
    release region, for the container's position at the landing of the current plan). The
    fixed point is iterated with the release point held: letting the planner pick it anew in
    every iteration makes it hop between grid points, the release time with it, and the
    iteration need not converge (1 cm apart in a test). Once the box is held, the role keeps
    the release point of the contact for the same reason across ticks.
    """
    conveyor = config.conveyor
    if container is None or not container.valid:
        return ContainerAim(None, None, 'no container track yet')
    if estimate is None or not estimate.valid:
        return ContainerAim(None, None, 'no object track yet')
    now = stamp_ns / NANOSECONDS_PER_SECOND
    p_object, R_object, _, _ = estimate_at(estimate, stamp_ns)
    distance = reach_distance(p_tools, p_object, R_object, config.object_size, grasp_offset)
    nominal = np.asarray(TossConfig().release_position)
    position_at = container_landing_point(container, conveyor)
    current_position = np.asarray(config.toss.release_position, dtype=float)
    current_velocity = release_velocity(config.toss)
    flight = landing_without_drag(current_position, current_velocity,
                                  conveyor.landing_height).flight_time
    first = position_at(now + time_to_release(phase, time_in_phase, distance, p_object,
                                              current_position, current_velocity, conveyor)
                        + flight)
    try:
        if release_point is None:
            release_point = plan_release(first, nominal, config.release_planning).position
        planning = replace(config.release_planning, **{
            name: (float(value), float(value))
            for name, value in zip(('x_range', 'y_range', 'z_range'), release_point)})

        def plan_for(target):
            return plan_release(target, nominal, planning)

        def release_in_for(plan):
            return time_to_release(phase, time_in_phase, distance, p_object, plan.position,
                                   plan.velocity, conveyor)

        aim = aim_at_moving_container(now, position_at, plan_for, release_in_for, first,
                                      conveyor)
    except UnreachableTargetError as error:
        return ContainerAim(None, None, f'container out of the served region at the landing: '
                                        f'{error}')
    if phase is Phase.STANDBY and not in_landing_range(aim.target, conveyor):
        low, high = conveyor.landing_y_range
        return ContainerAim(None, aim, f'container predicted at y = {aim.target[1]:.3f} m at '
                                       f'the landing, outside landing_y_range [{low:g}, '
                                       f'{high:g}] m')
    return ContainerAim(config_for_release_plan(config, aim.plan), aim, '')
