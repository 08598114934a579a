"""
Metrics of a grab from the moving incoming belt, from the ground-truth trajectory.

impact_speed_relative_<arm> is the tool's velocity on the sample just before that pad's first
contact minus the box's velocity on the sample just before the first contact of either pad
(the box as the belt carries it), along the desired impact direction. It generalises
impact_speed_along_direction, which measures both pads against the box at rest: a second pad
meets a box the first has already pushed (by up to 0.15 m/s within 2 ms for the 0.7 kg cube),
which the contact-time gap and belt_drag account for, not this speed.
belt_drag is how far the box moved along the belt, relative to the belt's own surface, between
the first pad's contact and the first sample with both pads in contact: a box pushed along by
the first pad, or held back, before the grasp closes (0 when the grab does not disturb it).
"""

import numpy as np

# The belt runs along world y.
BELT_AXIS = np.array([0.0, 1.0, 0.0])
# Pass/fail thresholds of a grab from the belt: relative impact speed within 15 % of the
# desired one, and at most 1 cm of drag along the belt.
RELATIVE_IMPACT_LIMIT = 0.15
BELT_DRAG_LIMIT = 0.01


def relative_impact_speed(tool_velocity, box_velocity, contact_index, direction):
    """Return (v_tool - box_velocity) . direction [m/s] on the sample before contact, or None."""
    if contact_index is None or contact_index == 0 or box_velocity is None:
        return None
    unit = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    relative = np.asarray(tool_velocity)[contact_index - 1] - np.asarray(box_velocity)
    return float(relative @ unit)


def belt_drag(t, object_position, belt_velocity, first_contact, both_contact):
    """
    Return |box displacement - belt surface displacement| [m] along the belt, or None.

    From the first contact's sample to the first sample with both pads in contact; the belt's
    displacement is its logged surface velocity integrated over the samples (rectangle rule,
    each sample's velocity held to the next).
    """
    if first_contact is None or both_contact is None:
        return None
    box = float((np.asarray(object_position)[both_contact]
                 - np.asarray(object_position)[first_contact]) @ BELT_AXIS)
    steps = np.diff(np.asarray(t)[first_contact:both_contact + 1])
    belt = float(np.sum(np.asarray(belt_velocity)[first_contact:both_contact] @ BELT_AXIS
                        * steps))
    return abs(box - belt)


def grab_metrics(data, contact_index, directions):
    """
    Return the metrics of a grab from the belt.

    contact_index {arm: first contact sample or None}; directions {arm: desired impact
    direction (3,)}. Keys: impact_speed_relative_<arm>, belt_drag.
    """
    touched = [index for index in contact_index.values() if index is not None]
    first = min(touched) if touched else None
    box_velocity = None if not first else np.asarray(data['object_velocity'])[first - 1]
    result = {f'impact_speed_relative_{arm}': relative_impact_speed(
        data[f'{arm}_tool_velocity'], box_velocity, index, directions[arm])
        for arm, index in contact_index.items()}
    both = np.flatnonzero(np.asarray(data['left_pad_contact'], dtype=bool)
                          & np.asarray(data['right_pad_contact'], dtype=bool))
    first = None if None in contact_index.values() else first
    result['belt_drag'] = belt_drag(data['t'], data['object_position'],
                                    data['incoming_belt_velocity'], first,
                                    None if both.size == 0 else int(both[0]))
    return result


def belt_grab_impact_speed(scenario):
    """Return the desired impact speed [m/s] of a scenario's grab from the belt, else None."""
    return None if scenario.incoming_belt is None else scenario.speeds.impact


def grab_misses(result, impact_speed):
    """
    Return the grab criteria result misses: [(key, value, limit, unit, detail)] (empty: none).

    Both relative impact speeds within RELATIVE_IMPACT_LIMIT of impact_speed [m/s] (value: the
    relative error, detail: the speed and its side), and the belt drag within BELT_DRAG_LIMIT
    [m]. value is None where the metric is missing (a pad that never touched).
    """
    misses = []
    for arm in ('left', 'right'):
        key = f'impact_speed_relative_{arm}'
        speed = result.get(key)
        error = None if speed is None else abs(speed - impact_speed) / impact_speed
        if error is None or error > RELATIVE_IMPACT_LIMIT:
            detail = None if speed is None else (
                f'{speed:.4g} m/s for {impact_speed:g}: '
                f'{"slow" if speed < impact_speed else "fast"}')
            misses.append((key, error, RELATIVE_IMPACT_LIMIT, '', detail))
    drag = result.get('belt_drag')
    if drag is None or drag > BELT_DRAG_LIMIT:
        misses.append(('belt_drag', drag, BELT_DRAG_LIMIT, 'm', None))
    return misses


def grab_succeeded(result, impact_speed):
    """Return True if both relative impact speeds are within the limit and the drag is too."""
    return not grab_misses(result, impact_speed)
