"""
Grasp frames on the object's faces, from the object pose and size.

The object's y axis is the squeeze axis. The left pad grasps the +y face, the right pad the -y
face. Each grasp frame has z = contact normal pointing into the object, x = object x and
y = z x x, and its origin at the face centre (plus an optional offset in the object frame).
A pad may also be rolled about the face normal (the flat pad is flush with its face at any
roll): the grasp frame then turns by that angle about its z axis. At contact the tool frame
coincides with the grasp frame.
"""

from dataclasses import dataclass
import functools
import math
from typing import NamedTuple

from dual_arm_control.core.geometry import cross3, turned_rectangle_half_extents
import numpy as np

_FACE_SIGN = {'left': 1.0, 'right': -1.0}


@dataclass(frozen=True)
class GraspFrame:
    """A grasp frame in the world: origin p_world_grasp [m], rotation R_world_grasp."""

    p_world_grasp: np.ndarray
    R_world_grasp: np.ndarray

    @property
    def normal(self):
        """Return the contact normal, the grasp z axis in the world, pointing into the object."""
        return self.R_world_grasp[:, 2]


def R_object_grasp(arm):
    """Return the rotation of an arm's grasp frame in the object frame (columns x, y, z)."""
    return _R_object_grasp(arm).copy()


@functools.lru_cache(maxsize=None)
def _R_object_grasp(arm):
    sign = _FACE_SIGN[arm]
    z_axis = np.array([0.0, -sign, 0.0])
    x_axis = np.array([1.0, 0.0, 0.0])
    return np.column_stack((x_axis, cross3(z_axis, x_axis), z_axis))


class FaceRectangle(NamedTuple):
    """The face a pad grasps, in the world: a rectangle on the box."""

    centre: np.ndarray
    """(3,) [m], the face's centre."""
    normal: np.ndarray
    """(3,) the inward normal (into the object)."""
    axes: np.ndarray
    """(2, 3) the face's in-plane axes: object x and object z."""
    half_extents: np.ndarray
    """(2,) [m], the face's half extents along axes."""


def face_rectangle(arm, p_world_object, R_world_object, size):
    """Return the FaceRectangle of an arm's face for an object pose and box size [m]."""
    R_world_object = np.asarray(R_world_object, dtype=float)
    return FaceRectangle(p_world_object + R_world_object @ p_object_grasp(arm, size),
                         R_world_object @ _R_object_grasp(arm)[:, 2],
                         R_world_object[:, [0, 2]].T, 0.5 * np.array([size[0], size[2]]))


def p_object_grasp(arm, size, offset=(0.0, 0.0, 0.0)):
    """Return the grasp point of an arm in the object frame [m]: its face centre plus offset."""
    return np.array([0.0, _FACE_SIGN[arm] * 0.5 * size[1], 0.0]) + np.asarray(offset, float)


def pad_roll_rotation(roll):
    """Return the rotation by roll [rad] about the grasp z axis (the face normal)."""
    cosine, sine = math.cos(roll), math.sin(roll)
    return np.array([[cosine, -sine, 0.0], [sine, cosine, 0.0], [0.0, 0.0, 1.0]])


def rolled_pad_half_extents(roll, half_length, half_width):
    """
    Return the half extents [m] of a pad rolled by roll [rad] along grasp x and grasp y.

    The pad spans half_length along its own x and half_width along its own y; rolled about
    its normal, the rectangle covers |cos| half_length + |sin| half_width along the unrolled
    grasp x (the object x axis) and |sin| half_length + |cos| half_width along grasp y (the
    object z axis, across the impact plane).
    """
    return turned_rectangle_half_extents(roll, half_length, half_width)


def grasp_frame(arm, p_world_object, R_world_object, size, offset=(0.0, 0.0, 0.0), roll=0.0):
    """Return the world grasp frame of an arm for an object pose, box size [m] and pad roll."""
    p_world_grasp = p_world_object + R_world_object @ p_object_grasp(arm, size, offset)
    R_world_grasp = R_world_object @ _R_object_grasp(arm)
    if roll != 0.0:
        R_world_grasp = R_world_grasp @ pad_roll_rotation(roll)
    return GraspFrame(p_world_grasp, R_world_grasp)
