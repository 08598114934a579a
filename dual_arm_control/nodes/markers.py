"""RViz markers of the motion generator: attractors, grasp frames, release, landing."""

from dual_arm_control.contract import ARMS, WORLD_FRAME
from dual_arm_control.core.ballistics import landing_without_drag
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.nodes.messages import set_vector3
from geometry_msgs.msg import Point
from visualization_msgs.msg import Marker, MarkerArray

ARM_COLOURS = {'left': (0.9, 0.2, 0.2), 'right': (0.2, 0.3, 0.9)}
ARROW_LENGTH = 0.15
# Height of the plane on which the landing is predicted [m] (front-table top + half a box).
LANDING_HEIGHT = 0.25


def _marker(stamp, namespace, marker_id, marker_type, rgb, scale):
    marker = Marker(type=marker_type, action=Marker.ADD, ns=namespace, id=marker_id)
    marker.header.stamp = stamp
    marker.header.frame_id = WORLD_FRAME
    marker.pose.orientation.w = 1.0
    marker.color.r, marker.color.g, marker.color.b = rgb
    marker.color.a = 1.0
    set_vector3(marker.scale, scale)
    return marker


def _point(values):
    point = Point()
    set_vector3(point, values)
    return point


def _sphere(stamp, namespace, marker_id, position, rgb, diameter=0.03):
    marker = _marker(stamp, namespace, marker_id, Marker.SPHERE, rgb, (diameter,) * 3)
    set_vector3(marker.pose.position, position)
    return marker


def _arrow(stamp, namespace, marker_id, start, direction, rgb):
    marker = _marker(stamp, namespace, marker_id, Marker.ARROW, rgb, (0.01, 0.02, 0.03))
    marker.points = [_point(start), _point(start + ARROW_LENGTH * direction)]
    return marker


def motion_markers(stamp, output):
    """Return the MarkerArray of one MotionOutput."""
    markers = []
    for index, arm in enumerate(ARMS):
        rgb = ARM_COLOURS[arm]
        frame = output.grasp_frames[arm]
        markers.append(_sphere(stamp, 'attractors', index,
                               output.commands[arm].p_world_attractor, rgb))
        markers.append(_arrow(stamp, 'grasp_normals', index, frame.p_world_grasp,
                              frame.normal, rgb))
        markers.append(_arrow(stamp, 'impact_directions', index, frame.p_world_grasp,
                              output.impact_directions[arm], (0.9, 0.0, 0.9)))
    if output.release_position is not None:
        markers.append(_sphere(stamp, 'release', 0, output.release_position, (0.9, 0.0, 0.9)))
        try:
            landing = landing_without_drag(output.release_position, output.release_velocity,
                                           LANDING_HEIGHT)
            markers.append(_sphere(stamp, 'predicted_landing', 0, landing.position,
                                   (0.0, 0.8, 0.8), 0.05))
        except InputError:
            pass
    return MarkerArray(markers=markers)
