"""
Episode metrics from simulator ground truth (never from the controller's beliefs).

Times are sim time from the episode start [s], SI units throughout. Each function computes one
quantity from arrays of a trajectory log (see trajectory.py) so it can be tested on synthetic
trajectories.
"""

from dataclasses import dataclass

from dual_arm_control.core.ballistics import drag_free_state
from dual_arm_control.core.geometry import quat_xyzw_to_matrix, rotation_log
from dual_arm_control.core.validation import check_range
import numpy as np


@dataclass(frozen=True)
class EventCriteria:
    """
    Thresholds that turn contact flags and motion into events.

    grasp_hold_time: both pads continuously in contact this long [s] = grasp established.
    release_hold_time: both pads out of contact this long [s] = the object was released.
    landing_clearance: object bottom within this height of the surface below [m] = landed.
    home_tolerance: tool within this distance of its start position [m] = back home.
    """

    grasp_hold_time: float = 0.05
    release_hold_time: float = 0.02
    landing_clearance: float = 0.005
    home_tolerance: float = 0.03

    def __post_init__(self):
        check_range('grasp_hold_time', self.grasp_hold_time, 0.0, 1.0, 's')
        check_range('release_hold_time', self.release_hold_time, 0.0, 1.0, 's')
        check_range('landing_clearance', self.landing_clearance, 0.0, 0.1, 'm')
        check_range('home_tolerance', self.home_tolerance, 0.0, 0.5, 'm')


def joint_power(tau, dq):
    """Return the mechanical power tau . dq [W] of the drives at every sample (N,)."""
    return np.einsum('ij,ij->i', np.asarray(tau), np.asarray(dq))


def time_integral(t, values):
    """Return the integral of values over t (trapezoidal rule); 0 for fewer than two samples."""
    return float(np.trapezoid(values, np.asarray(t))) if len(values) > 1 else 0.0


def mechanical_energy(t, tau, dq):
    """Return the time integral of |tau . dq| [J] over the log (trapezoidal rule)."""
    return time_integral(t, np.abs(joint_power(tau, dq)))


def joint_speed_ratio(t, dq, velocity_limits):
    """
    Return (largest |dq| / limit over the log, time [s] above the limit, joint index 0-6).

    t (N,) [s], dq (N, 7) [rad/s], velocity_limits (7,) [rad/s]. The KUKA controller stops an
    arm whose joint exceeds its speed limit, so a motion with a ratio above 1 would not run
    on the robot; the time counts every sample interval that starts above the limit.
    """
    ratio = np.abs(np.asarray(dq)) / np.asarray(velocity_limits)
    above = ratio[:-1].max(axis=1) > 1.0
    return (float(ratio.max()), float(np.diff(np.asarray(t))[above].sum()),
            int(ratio.max(axis=0).argmax()))


def first_true_index(flags, start=0):
    """Return the first index >= start where flags is true, or None."""
    indices = np.flatnonzero(np.asarray(flags, dtype=bool)[start:])
    return int(indices[0]) + start if indices.size else None


def first_sustained_index(t, flags, duration, start=0):
    """Return the first index >= start that begins a run of true flags lasting >= duration."""
    flags = np.asarray(flags, dtype=bool)
    t = np.asarray(t)
    index = start
    while True:
        begin = first_true_index(flags, index)
        if begin is None:
            return None
        end = first_true_index(~flags, begin)
        last = (end if end is not None else len(flags)) - 1
        if t[last] - t[begin] >= duration:
            return begin
        if end is None:
            return None
        index = end


def impact_speed(tool_velocity, contact_index, direction=None):
    """
    Return the tool speed [m/s] on the sample just before first contact.

    With a unit direction, return the velocity component along it (the impact speed along the
    desired impact direction) instead of the norm.
    """
    if contact_index is None or contact_index == 0:
        return None
    velocity = np.asarray(tool_velocity)[contact_index - 1]
    if direction is None:
        return float(np.linalg.norm(velocity))
    return float(velocity @ (np.asarray(direction) / np.linalg.norm(direction)))


def grasp_and_release_indices(t, left_contact, right_contact, criteria=EventCriteria(),
                              start=0):
    """Return (grasp index, release index): both pads on, then both off, sustained, >= start."""
    both_on = np.asarray(left_contact, bool) & np.asarray(right_contact, bool)
    grasp = first_sustained_index(t, both_on, criteria.grasp_hold_time, start)
    if grasp is None:
        return None, None
    both_off = ~np.asarray(left_contact, bool) & ~np.asarray(right_contact, bool)
    release = first_sustained_index(t, both_off, criteria.release_hold_time, start=grasp)
    return grasp, release


def grasp_segments(t, left_contact, right_contact, criteria=EventCriteria()):
    """Return [(grasp index, release index or None)] of every grasp in turn (a regrasp: two)."""
    segments, start = [], 0
    while start is not None:
        grasp, release = grasp_and_release_indices(t, left_contact, right_contact, criteria,
                                                   start)
        if grasp is None:
            break
        segments.append((grasp, release))
        start = release
    return segments


def max_pad_slip(tool_position, object_position, object_quat_xyzw, begin, end):
    """
    Return the largest slip [m] of a pad along its face between begin and end.

    The pad (tool centre) position is expressed in the object frame; slip is its displacement
    from where it was at begin, less the part along the face normal (the object axis the pad
    sits on at begin). That part is the pad seating and pressing on the face, not sliding: at
    a grasp the pads first touch tilted and then settle flat, the tool centres 1 cm closer to
    the box centre (pick_and_lift on the twin).
    """
    if begin is None or end is None or end <= begin:
        return None
    tool_position = np.asarray(tool_position)
    object_position = np.asarray(object_position)
    reference = None
    largest = 0.0
    for index in range(begin, end):
        rotation = quat_xyzw_to_matrix(object_quat_xyzw[index])
        p_object_tool = rotation.T @ (tool_position[index] - object_position[index])
        if reference is None:
            reference = p_object_tool
            along_face = np.ones(3)
            along_face[int(np.argmax(np.abs(reference)))] = 0.0
        largest = max(largest, float(np.linalg.norm((p_object_tool - reference) * along_face)))
    return largest


def landing_index(t, object_position, start, half_height, surface_height,
                  criteria=EventCriteria()):
    """
    Return the first index after start where the falling object's bottom reaches a surface.

    surface_height(x, y) gives the height of the surface below a point [m].
    """
    if start is None:
        return None
    object_position = np.asarray(object_position)
    for index in range(start, len(t)):
        x, y, z = object_position[index]
        if z - half_height <= surface_height(x, y) + criteria.landing_clearance:
            return index
    return None


def return_home_index(t, tool_positions, start, criteria=EventCriteria()):
    """Return the first index after start where every tool is back near its initial position."""
    if start is None:
        return None
    distances = [np.linalg.norm(np.asarray(p) - np.asarray(p)[0], axis=1)
                 for p in tool_positions]
    near = np.all([d <= criteria.home_tolerance for d in distances], axis=0)
    return first_true_index(near, start)


def release_state_on_plane(p_release, v_release, p_planned, v_planned, gravity):
    """
    Return the free-flying box's (position (3,) [m], velocity (3,) [m/s]) on the release plane.

    The release plane passes through the planned release position across the planned release
    velocity. The box's first free-flight sample lies on its parabola a few milliseconds past
    the pads' opening, where gravity has already turned its velocity (0.7 deg per ms at
    0.85 m/s); comparing that sample with the planned state at the plane mixes two points of
    the flight. Propagating the free flight (no drag) forward or back to the plane compares the
    actual and the planned release at the same place, and the parabola it lands on is the
    same.
    """
    p_release = np.asarray(p_release, dtype=float)
    v_release = np.asarray(v_release, dtype=float)
    direction = np.asarray(v_planned, dtype=float)
    direction = direction / np.linalg.norm(direction)
    a = -0.5 * gravity * float(direction[2])
    b = float(v_release @ direction)
    c = float((p_release - np.asarray(p_planned, dtype=float)) @ direction)
    if abs(a) < 1e-12:
        roots = [-c / b] if abs(b) > 1e-12 else []
    else:
        discriminant = b * b - 4.0 * a * c
        roots = ([(-b + sign * np.sqrt(discriminant)) / (2.0 * a) for sign in (1.0, -1.0)]
                 if discriminant >= 0.0 else [])
    if not roots:
        return p_release, v_release
    return drag_free_state(p_release, v_release, min(roots, key=abs), gravity)


def relative_velocity_error(velocity, desired_velocity):
    """Return ||v - v_d|| / ||v_d|| [-]."""
    desired_velocity = np.asarray(desired_velocity, dtype=float)
    return float(np.linalg.norm(np.asarray(velocity) - desired_velocity)
                 / np.linalg.norm(desired_velocity))


def relative_speed_error(velocity, desired_velocity):
    """Return ||v|| / ||v_d|| - 1 [-]: signed, negative when slower than desired."""
    return float(np.linalg.norm(velocity) / np.linalg.norm(desired_velocity) - 1.0)


def direction_error_degrees(velocity, desired_velocity):
    """Return the angle [deg] between v and v_d."""
    velocity, desired_velocity = np.asarray(velocity), np.asarray(desired_velocity)
    cosine = velocity @ desired_velocity / (np.linalg.norm(velocity)
                                            * np.linalg.norm(desired_velocity))
    return float(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))))


def tilt_degrees(object_quat_xyzw):
    """Return the angle [deg] between the object's z axis and the world's vertical."""
    z_axis = quat_xyzw_to_matrix(object_quat_xyzw)[:, 2]
    return float(np.degrees(np.arccos(np.clip(z_axis[2], -1.0, 1.0))))


def rotation_error_degrees(object_quat_xyzw, R_world_desired):
    """Return the angle [deg] of the rotation from R_world_desired to the object's orientation."""
    R_world_object = quat_xyzw_to_matrix(object_quat_xyzw)
    return float(np.degrees(np.linalg.norm(rotation_log(R_world_object @ R_world_desired.T))))
