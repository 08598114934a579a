"""
Where and how the pads approach the box: impact directions, the support's clearance, yielding.

The per-tick geometry of the reach with impact around eqs. 1-6: each pad's impact direction (its
face normal tilted toward the object's task motion, its rise limited so the run-in clears the
surface the box rests on), and the yield of a pad that touches its face before the other.
"""

from dataclasses import replace

from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.elbow_reach import elbow_clear_direction
from dual_arm_control.core.grasp import rolled_pad_half_extents
from dual_arm_control.core.impact import (clearance_limited_direction, impact_direction,
                                          max_impact_tilt)
from dual_arm_control.core.manipulation import lift_velocity, toss_geometry, toss_velocity
from dual_arm_control.core.phases import Task
from dual_arm_control.core.place import place_velocity
import numpy as np

TOSS_TASKS = (Task.PICK_AND_TOSS, Task.TOSS_TO_TARGET, Task.PLACE_TOSS)


def first_touch_gaps(faces, p_tools, R_tools, pad_half_length, pad_half_width):
    """
    Return each pad's gap (2,) [m] to its face from the point of the pad that touches first.

    faces: the two FaceRectangle; p_tools (2, 3) [m]; R_tools: the two tool rotations (pad
    normal = tool z, pad length along tool x). A pad tilted against its face touches with its
    nearest corner: synchronising the pads' centres let a pad 5-8 deg off its face (the face
    turned toward its arm's base, box yawed 20 deg) touch 10-15 ms before the other. Only the
    part of the pad over the face can touch it: a pad overhanging the face's edge touches with
    its nearest point above the face, found by clipping the pad's outline to the face
    (pad_overlap_gap). Zero half extents give the gaps of the pads' centres.
    """
    outline = np.array([[-pad_half_length, -pad_half_width, 0.0],
                        [pad_half_length, -pad_half_width, 0.0],
                        [pad_half_length, pad_half_width, 0.0],
                        [-pad_half_length, pad_half_width, 0.0]])
    gaps = np.empty(2)
    for index, face in enumerate(faces):
        corners = p_tools[index] + outline @ np.asarray(R_tools[index]).T
        corner_gaps = (face.centre - corners) @ face.normal
        in_face = (corners - face.centre) @ face.axes.T
        over_face = bool(np.all(np.abs(in_face) <= face.half_extents))
        gap = None if over_face else pad_overlap_gap(in_face.tolist(), corner_gaps.tolist(),
                                                     face.half_extents.tolist())
        gaps[index] = float(np.min(corner_gaps)) if gap is None else gap
    return gaps


def pad_overlap_gap(outline, gaps, half_extents):
    """
    Return the smallest gap [m] over the part of a pad's outline above its face, or None.

    outline: the pad's corners (u, v) in order [m], in the face's axes from its centre; gaps:
    each corner's gap to the face plane [m], which varies linearly over the flat pad. The
    outline is clipped to the face rectangle |u| <= half_extents (Sutherland-Hodgman, the gap
    carried along) and the smallest gap of the clipped polygon's vertices returned; None when
    the pad lies wholly beside the face. Plain floats: this runs on every reach tick.
    """
    polygon = [(u, v, gap) for (u, v), gap in zip(outline, gaps)]
    for axis, sign in ((0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0)):
        limit = half_extents[axis]
        clipped = []
        start = polygon[-1]
        inside_start = limit - sign * start[axis]
        for end in polygon:
            inside_end = limit - sign * end[axis]
            if (inside_start >= 0.0) != (inside_end >= 0.0):
                fraction = inside_start / (inside_start - inside_end)
                clipped.append(tuple(a + fraction * (b - a) for a, b in zip(start, end)))
            if inside_end >= 0.0:
                clipped.append(end)
            start, inside_start = end, inside_end
        polygon = clipped
        if not polygon:
            return None
    return min(vertex[2] for vertex in polygon)


def synchronised_arrival(velocity, gaps, normals, schedule, measured_velocity=None):
    """
    Return velocity (2, 3) [m/s] rescaled per arm so that both pads reach their faces together.

    The coordinated DS (eq. 4) synchronises the commanded motions, but the arms track them with
    different lags and a yawed box puts their faces at different angles, so each pad's time to
    contact T is measured: its gap (2,) [m] to the face plane along the inward normal (2, 3)
    over its commanded closing speed. The arm behind speeds up and the arm ahead slows down by
    schedule.gain (T_behind - T_ahead) / (T_behind + T_ahead), within [schedule.slowest,
    schedule.fastest]. With gain k > 1 the time difference shrinks like T^k and the speed
    change with it, so both pads strike at the impact speed (eq. 5); a one-sided catch-up
    (later arm times the ratio of the times) keeps that ratio to the end and strikes fast. The
    schedule blends in over the outer half of schedule.horizon [m] and out over the last
    schedule.final_gap [m] of the nearer pad, where the gaps are within the mocap's noise.
    With the tools' measured velocity (2, 3) [m/s], each time also counts the tracking lag:
    an arm regains the commanded closing speed with the time constant schedule.lag [s] as the
    schedule fades, so one slower than commanded loses lag (commanded - measured) of gap (one
    faster gains it), and the arm slowed ahead is not left behind at contact.
    """
    velocity = np.asarray(velocity, dtype=float)
    gaps = np.asarray(gaps, dtype=float)
    closing = np.einsum('ij,ij->i', velocity, normals)
    if np.any(closing <= 1e-6) or np.any(gaps <= 0.0) or np.max(gaps) >= schedule.horizon:
        return velocity
    lost_gap = 0.0
    if measured_velocity is not None:
        measured = np.einsum('ij,ij->i', np.asarray(measured_velocity, dtype=float), normals)
        lost_gap = schedule.lag * (closing - measured)
    times = np.maximum(gaps + lost_gap, 0.0) / closing
    lead = schedule.gain * (times - times[::-1]) / times.sum()
    weight = min(1.0, 2.0 * (1.0 - float(np.max(gaps)) / schedule.horizon))
    if schedule.final_gap > 0.0:
        weight *= min(1.0, max(0.0, float(np.min(gaps)) / schedule.final_gap - 1.0))
    scale = np.clip(1.0 + weight * lead, schedule.slowest, schedule.fastest)
    return velocity * scale[:, None]


def yield_to_single_contact(commands, contacts, frames):
    """
    Return commands where a pad that touches its face alone stops pushing into it.

    While only one pad is in contact during the reach, that arm's velocity loses its component
    along the contact normal (into the box), so it waits at the face for the other pad instead
    of pushing the box away from it; its tangential motion and orientation are kept.
    """
    touching = [arm for arm in ARMS if contacts[arm].in_contact]
    if len(touching) != 1:
        return commands
    arm = touching[0]
    command = commands[arm]
    normal = frames[arm].normal
    into_face = float(command.v_world @ normal)
    if into_face <= 0.0:
        return commands
    yielded = dict(commands)
    yielded[arm] = replace(command, v_world=command.v_world - into_face * normal)
    return yielded


def object_motion_direction(config, p_world_object):
    """Return the direction (3,) the task's object DS would move the object from p_world_object."""
    if config.task in TOSS_TASKS:
        return toss_velocity(p_world_object, toss_geometry(config.toss,
                                                           config.coordination)).velocity
    if config.task is Task.PICK_AND_PLACE:
        return place_velocity(p_world_object, config.place, config.coordination)
    return lift_velocity(p_world_object, config.lift, config.coordination)


def rolled_impact_config(config, pad_roll):
    """
    Return config.impact with pad_half_height of the pads rolled by pad_roll [rad].

    impact.pad_half_height is the unrolled pad's half extent across the impact plane (its
    half width); rolled about the face normal, the pad reaches |sin| pad_half_length +
    |cos| pad_half_height below its centre (core.grasp.rolled_pad_half_extents).
    """
    if pad_roll == 0.0:
        return config.impact
    _, half_height = rolled_pad_half_extents(pad_roll, config.reachability.pad_half_length,
                                             config.impact.pad_half_height)
    return replace(config.impact, pad_half_height=half_height)


def impact_directions(config, frames, object_velocity, support_height=None, pad_roll=0.0,
                      elbow_reaches=None):
    """
    Return {arm: (3,)} unit impact directions: each face normal tilted toward the motion.

    elbow_reaches {arm: ElbowReach}: when given, a direction whose run-in the arm could only
    follow with its elbow folded past its limit turns away from the shoulder
    (elbow_clear_direction). support_height [m]: height of the surface the box rests on; when
    given, a direction's rise is limited so the run-in of the pad (rolled by pad_roll [rad]
    about the face normal) clears it (clearance_limited_direction).
    """
    max_tilt = max_impact_tilt(config.impact)
    impact = rolled_impact_config(config, pad_roll)
    directions = {}
    for arm in ARMS:
        direction = impact_direction(frames[arm].normal, object_velocity, max_tilt)
        if elbow_reaches is not None:
            direction = elbow_clear_direction(
                direction, frames[arm].normal, max_tilt, elbow_reaches[arm],
                frames[arm].p_world_grasp, frames[arm].R_world_grasp,
                impact.region.transitory_distance, impact.elbow_clearance)
        if support_height is not None:
            direction = clearance_limited_direction(
                direction, frames[arm].p_world_grasp[2] - support_height, impact)
        directions[arm] = direction
    return directions


def support_height_below(config, p_world_object):
    """Return the height [m] of the surface a resting, upright box centred at p rests on."""
    return float(p_world_object[2]) - 0.5 * config.object_size[2]
