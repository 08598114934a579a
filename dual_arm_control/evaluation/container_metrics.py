"""
Metrics of a toss into a conveyor's moving container, from the ground-truth trajectory.

The landing is the first sample after the release at which the box's bottom has come down to
the container's rim (its centre at rim height + half the box height): the instant it enters
the opening or hits the rim. landing_error_in_container is the horizontal distance, in the plane
of the opening, from the container's centre to the box's centre then (landing_offset_in_container
the offset itself, world x and y). landed_in_container says
where the box ended: its centre inside the opening's footprint and its bottom below the rim at
the end of the run (in the container, not on its walls or beside it).
"""

import numpy as np

# Tolerance on "the bottom below the rim" for a box resting in the container [m].
RIM_TOLERANCE = 0.005


def rim_crossing_index(object_position, start, half_height, rim_height):
    """Return the first index >= start where the box's bottom is at or below the rim, or None."""
    if start is None:
        return None
    bottom = np.asarray(object_position)[start:, 2] - half_height
    below = np.flatnonzero(bottom <= rim_height)
    return None if below.size == 0 else int(start + below[0])


def horizontal_offset(object_position, container_position):
    """Return the box centre's horizontal distance [m] from the container centre."""
    return float(np.linalg.norm((np.asarray(object_position) - container_position)[:2]))


def inside_container(object_position, container_position, half_height, conveyor):
    """Return True if the box's centre is over the opening and its bottom below the rim."""
    offset = np.abs((np.asarray(object_position) - container_position)[:2])
    half_opening = 0.5 * np.asarray(conveyor.inner_size)
    bottom = object_position[2] - half_height
    return bool(np.all(offset <= half_opening)
                and bottom <= conveyor.rim_height - 0.5 * conveyor.wall_height + RIM_TOLERANCE)


def container_metrics(data, conveyor, object_height, release_index):
    """
    Return the container metrics of a toss released at release_index.

    Keys: landing_error_in_container, landing_offset_in_container, landed_in_container and
    container_landing_index (the landing's sample, None without one).
    """
    half_height = 0.5 * object_height
    landed = rim_crossing_index(data['object_position'], release_index, half_height,
                                conveyor.rim_height)
    error = offset = None
    if landed is not None:
        error = horizontal_offset(data['object_position'][landed],
                                  data['container_position'][landed])
        offset = [float(value) for value in (data['object_position'][landed]
                                             - data['container_position'][landed])[:2]]
    return {'landing_error_in_container': error, 'landing_offset_in_container': offset,
            'landed_in_container': inside_container(
                data['object_position'][-1], data['container_position'][-1], half_height,
                conveyor),
            'container_landing_index': landed}
