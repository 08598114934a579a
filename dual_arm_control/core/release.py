"""
When a toss lets go of the box: the release plane, reached a lead time early (section IV-A).

The paper releases within 0.03 m of the release point; releasing on entering that sphere lets
go 2-3 cm early and the box lands short. TossRelease releases where the box reaches the plane
through the release point across the release velocity (close to the release path), so the
release state is the planned one, and keeps the sphere only as a fallback for a box that
passes near the point without crossing the plane there. Whether the box moves away from the
point is read from its estimated velocity, not from two successive distances: at 0.8 m/s the
box covers 4 mm per 5 ms tick, and mocap noise of 2 mm made the distance grow while the box
still approached, letting go 1-2 cm before the plane.
"""

from dataclasses import replace

from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.speed_shaping import saturated_velocity
import numpy as np


class TossRelease:
    """The toss release rule, with the previous update's distances it needs to see a crossing."""

    def __init__(self):
        """Start with no previous update."""
        self.reset()

    def reset(self):
        """Forget the previous update (a new grasp)."""
        self._previous_along = None

    def reason(self, p_world_object, v_world_object, p_world_release, v_world_release, config,
               command_latency=0.0):
        """
        Return why the box must be released now, or None.

        config: PhaseConfig (release_tolerance, release_plane_radius, release_lead_time). The
        box's signed distance along the release velocity from the release plane, advanced by
        its own velocity times release_lead_time (the pads take that long to come off) plus
        command_latency [s] (the release command takes that long to reach the arms), turning
        non-negative within release_plane_radius of the release path releases it; so does the
        box moving away from the release point (its velocity along the offset from the point
        positive) inside release_tolerance.
        """
        p_world_offset = p_world_object - p_world_release
        distance = float(np.linalg.norm(p_world_offset))
        release_speed = np.linalg.norm(v_world_release)
        if release_speed < 1e-6:
            return None
        direction = v_world_release / release_speed
        offset_along = float(p_world_offset @ direction)
        lead_time = config.release_lead_time + command_latency
        along = offset_along + lead_time * float(v_world_object @ direction)
        lateral = float(np.linalg.norm(p_world_offset - offset_along * direction))
        previous_along, self._previous_along = self._previous_along, along
        if (previous_along is not None and previous_along < 0.0 <= along
                and lateral <= config.release_plane_radius):
            early = f', {command_latency * 1e3:.1f} ms early' if command_latency > 0.0 else ''
            return (f'object reaches the release plane {lateral:.3f} m off the release path'
                    f'{early}')
        if distance <= config.release_tolerance and float(v_world_object @ p_world_offset) > 0.0:
            return f'object passed {distance:.3f} m from the release position'
        return None


class PlaceRelease:
    """The place release rule, with how long the box has stalled next to the place."""

    def __init__(self):
        """Start with no stall."""
        self.reset()

    def reset(self):
        """Forget the stall (a new grasp)."""
        self._stalled_time = 0.0

    def reason(self, p_world_object, v_world_object, p_world_place, config, dt):
        """
        Return why the box must be put down now, or None.

        config: PhaseConfig (place_tolerance, place_speed, place_stall_distance,
        place_stall_height, place_stall_speed, place_stall_time). Within place_tolerance of the
        place and slower than place_speed, the box is on the table. A box the arms bring no
        closer (slower than place_stall_speed, within place_stall_distance horizontally and
        place_stall_height vertically, for place_stall_time) is let go where it is: at the
        arms' reach a heavy box hovered 7-17 mm above the table at x = 0.75 m, and a box
        grasped forward of its centre rested on the table 3 cm short of the place, held
        until the end of the run.
        """
        offset = np.asarray(p_world_object, dtype=float) - p_world_place
        distance = float(np.linalg.norm(offset))
        speed = float(np.linalg.norm(v_world_object))
        if distance <= config.place_tolerance and speed < config.place_speed:
            return f'object {distance:.3f} m from the place position at {speed:.3f} m/s'
        stalled = (float(np.linalg.norm(offset[:2])) <= config.place_stall_distance
                   and abs(float(offset[2])) <= config.place_stall_height
                   and speed < config.place_stall_speed)
        self._stalled_time = self._stalled_time + dt if stalled else 0.0
        if self._stalled_time >= config.place_stall_time - 1e-9:
            return (f'object stalled {distance:.3f} m from the place position for '
                    f'{self._stalled_time:.3f} s')
        return None


def clear_of_the_box(v_world_tool, p_world_tool, p_world_object, v_world_object, clearance,
                     separation_speed):
    """
    Return the tool velocity (3,) [m/s] that keeps a retracting pad from being struck by the box.

    A toss whose heading leaves the arms' plane throws the box along the squeeze axis, toward
    one pad: the pads open at release, but the retract toward standby then lets the flying
    box catch up with that pad (in the twin 140 ms after a release at 0.65 m/s across, turning
    a 4 mm landing into 18 cm). While the box's centre is within clearance [m] of the tool and
    comes toward it, the tool's velocity away from the box is raised to the box's closing
    speed plus separation_speed [m/s]; its other components are kept. Away is horizontal: the
    pads hold vertical faces, so the pad a box flies toward is beside it. (Along the full
    offset, a falling box read as receding from a pad above its centre while its face ran
    into the pad: a box thrown at 0.79 m/s along -y landed 6.6 cm off, test_toss_planning.)
    """
    offset = np.asarray(p_world_tool, dtype=float) - np.asarray(p_world_object, dtype=float)
    distance = float(np.linalg.norm(offset))
    beside = float(np.hypot(offset[0], offset[1]))
    if distance >= clearance or beside < 1e-9:
        return v_world_tool
    away = np.array([offset[0], offset[1], 0.0]) / beside
    closing = float(np.asarray(v_world_object, dtype=float) @ away)
    if closing <= 0.0:
        return v_world_tool
    shortfall = closing + separation_speed - float(v_world_tool @ away)
    return v_world_tool + max(shortfall, 0.0) * away


def commands_clear_of_the_box(commands, p_tools, p_world_object, v_world_object, clearance,
                              separation_speed, max_speed):
    """Return {arm: ArmCommand} with each pad out of the flying box's way, at most max_speed."""
    return {arm: replace(commands[arm], v_world=saturated_velocity(clear_of_the_box(
                commands[arm].v_world, p_tools[index], p_world_object, v_world_object, clearance,
                separation_speed), max_speed))
            for index, arm in enumerate(ARMS)}
