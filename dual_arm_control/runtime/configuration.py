"""Scenario to motion-generator configuration: task, object, targets, speeds, standby."""

from dataclasses import replace

from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.ballistics import release_velocity_minimum_speed
from dual_arm_control.core.motion_generator import MotionGeneratorConfig
import numpy as np

# The place DS aims this far below the box's resting pose [m], so the table, not the release,
# stops the box: it is put down while still held, then released at rest.
PLACE_PRESS_DEPTH = 0.004


def motion_config_for_scenario(scenario, cell, base=None):
    """Return the MotionGeneratorConfig of a scenario: task, object, targets, speeds, standby."""
    base = MotionGeneratorConfig() if base is None else base
    config = replace(
        base, task=scenario.task, object_size=tuple(scenario.object.size),
        standby_positions=tuple(tuple(cell.arm(arm).standby_position) for arm in ARMS),
        standby_rotations=tuple(tuple(map(tuple, cell.arm(arm).R_world_standby))
                                for arm in ARMS),
        impact=replace(base.impact, impact_speed=scenario.speeds.impact),
        speed=replace(base.speed, reach_speed=scenario.speeds.reach))
    toss = replace(base.toss, toss_speed=scenario.speeds.toss)
    if scenario.release is not None:
        velocity = np.asarray(scenario.release.velocity, dtype=float)
        toss = replace(toss, release_position=tuple(scenario.release.position),
                       release_direction=tuple(velocity), toss_speed=float(
                           np.linalg.norm(velocity)))
    elif scenario.landing_target is not None:
        solution = release_velocity_minimum_speed(np.asarray(toss.release_position),
                                                  np.asarray(scenario.landing_target))
        toss = replace(toss, release_direction=tuple(solution.velocity),
                       toss_speed=float(solution.speed))
    config = replace(config, toss=toss)
    if scenario.place is not None:
        pressed = np.asarray(scenario.place, dtype=float) - [0.0, 0.0, PLACE_PRESS_DEPTH]
        config = replace(config, place=replace(base.place, position=tuple(pressed)))
    return config
