"""Scenario to motion-generator configuration: task, object, targets, speeds, standby."""

from dataclasses import replace

from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.ballistics import centre_landing_height, landing_without_drag
from dual_arm_control.core.manipulation import release_velocity, TossConfig
from dual_arm_control.core.motion_config import MotionGeneratorConfig
from dual_arm_control.core.toss_planning import plan_release
from dual_arm_control.scenario import TOSS_TASKS
import numpy as np

# The place DS aims this far below the box's resting pose [m], so the table, not the release,
# stops the box: it is put down while still held, then released at rest.
PLACE_PRESS_DEPTH = 0.004


def motion_config_for_cell(cell, base=None):
    """
    Return base (default MotionGeneratorConfig()) with the cell's facts: standby poses, pallet.

    A motion generator started without a scenario needs them too: without the pallet's top face
    a box lifted off it would not be kept clear of it (core.place.pallet_floor).
    """
    base = MotionGeneratorConfig() if base is None else base
    return replace(
        base, standby_positions=tuple(tuple(cell.arm(arm).standby_position) for arm in ARMS),
        standby_rotations=tuple(tuple(map(tuple, cell.arm(arm).R_world_standby))
                                for arm in ARMS),
        place=replace(base.place, pallet=cell.pallet.top_face()))


def motion_config_for_scenario(scenario, cell, base=None):
    """Return the MotionGeneratorConfig of a scenario: task, object, targets, speeds, standby."""
    base = motion_config_for_cell(cell, base)
    config = replace(
        base, task=scenario.task, object_size=tuple(scenario.object.size),
        impact=replace(base.impact, impact_speed=scenario.speeds.impact),
        speed=replace(base.speed, reach_speed=scenario.speeds.reach))
    toss = base.toss
    if scenario.speeds.toss is not None:
        toss = replace(toss, toss_speed=scenario.speeds.toss)
    if scenario.release is not None:
        velocity = np.asarray(scenario.release.velocity, dtype=float)
        toss = replace(toss, release_position=tuple(scenario.release.position),
                       release_direction=tuple(velocity), toss_speed=float(
                           np.linalg.norm(velocity)))
    if scenario.release_orientation is not None:
        toss = replace(toss, orientation='given',
                       release_rpy_deg=tuple(float(v) for v in scenario.release_orientation))
    config = replace(config, toss=toss)
    if scenario.landing_target is not None:
        config = config_for_landing_target(config, scenario.landing_target)
    if scenario.incoming_belt is not None:
        config = replace(config, moving_grab=replace(config.moving_grab, enabled=True))
    if scenario.conveyor is not None and scenario.task in TOSS_TASKS:
        config = replace(config, conveyor=replace(
            config.conveyor, enabled=True, landing_height=float(
                scenario.conveyor.rim_height + 0.5 * scenario.object.size[2])))
    if scenario.place is not None:
        pressed = np.asarray(scenario.place, dtype=float) - [0.0, 0.0, PLACE_PRESS_DEPTH]
        config = replace(config, place=replace(config.place, position=tuple(pressed)))
    return config


def config_for_landing_target(config, target):
    """
    Return config with the toss release planned for landing target (3,) [m] (object centre).

    The release point, direction and speed come from core.toss_planning.plan_release over the
    config's release region, pulled toward the default release point. Raises
    UnreachableTargetError with the reason when no release state serves the target.
    """
    plan = plan_release(np.asarray(target, dtype=float),
                        np.asarray(TossConfig().release_position), config.release_planning)
    return config_for_release_plan(config, plan)


def config_for_release_plan(config, plan):
    """Return config with its toss release set to a ReleasePlan's point, direction and speed."""
    speed = float(np.linalg.norm(plan.velocity))
    return replace(config, toss=replace(config.toss, release_position=tuple(plan.position),
                                        release_direction=tuple(plan.velocity / speed),
                                        toss_speed=speed))


def planned_release(scenario, cell):
    """
    Return the object's planned (position, velocity) at release [m, m/s], or None.

    The scenario's release state, or for a landing target the one the motion generator plans
    (release position of its toss config, velocity from the ballistic solution).
    """
    if scenario.release is not None:
        return (np.asarray(scenario.release.position, dtype=float),
                np.asarray(scenario.release.velocity, dtype=float))
    if scenario.task not in TOSS_TASKS:
        return None
    toss = motion_config_for_scenario(scenario, cell).toss
    return np.asarray(toss.release_position, dtype=float), release_velocity(toss)


def planned_landing(scenario, cell):
    """
    Return where the scenario's toss lands the box centre (3,) [m], or None without a toss.

    Its landing target when it gives one, else the drag-free landing of its planned release.
    """
    if scenario.landing_target is not None:
        return np.asarray(scenario.landing_target, dtype=float)
    planned = planned_release(scenario, cell)
    if planned is None:
        return None
    return predicted_landing(*planned, scenario.object.size[2], cell)


def predicted_landing(p_release, v_release, object_height, cell):
    """Return the drag-free landing point of the box centre on the cell surface below it."""
    landing = None
    surface = cell.front_table.top_height
    for _ in range(3):
        landing = landing_without_drag(p_release, v_release,
                                       centre_landing_height(surface, object_height))
        below = cell.surface_height(*landing.position[:2])
        if below == surface:
            break
        surface = below
    return landing.position
