"""
The pads' contacts with the box and the grasp matrix of eq. 10 (paper section II-E).

pad_contact_geometry gives each pad's contact point, frame and distance to its face from the
measured tool pose and the estimated box pose; grasp_matrix maps the pad wrenches to the net
wrench on the box. The wrench QP (wrench_qp.py) is built on both.
"""

import dataclasses

from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.geometry import cross3
from dual_arm_control.core.validation import finite_array
import numpy as np

PAD_ORDER = ('left', 'right')
_OBJECT_FACE_SIGN = {'left': 1.0, 'right': -1.0}
_GRASP_MATRIX_IDENTITY_BLOCKS = np.hstack((np.eye(6), np.eye(6)))
# Entries of the [p_i - p_o]x blocks: rows 3-5, columns 6 i + 0..2, for pads i = 0, 1.
_SKEW_ROWS = np.tile([3, 3, 4, 4, 5, 5], 2)
_SKEW_COLUMNS = np.array([1, 2, 0, 2, 0, 1, 7, 8, 6, 8, 6, 7])
_SKEW_COMPONENTS = np.array([2, 1, 2, 0, 1, 0])
_SKEW_SIGNS = np.tile([-1.0, 1.0, 1.0, -1.0, -1.0, 1.0], 2)
_N_WRENCH = 12


@dataclasses.dataclass(frozen=True)
class PadContact:
    """
    Contact geometry of one pad, world frame.

    p_world_contact: (3,) contact point = pad centre projected on the object face [m].
    R_world_pad: (3, 3) pad frame, z = contact normal INTO the object, x along the 0.15 m side.
    normal_distance: signed distance of the pad centre from the face plane, > 0 outside [m].
    """

    p_world_contact: np.ndarray
    R_world_pad: np.ndarray
    normal_distance: float


def grasp_matrix(p_world_contacts, p_world_object, out=None):
    """
    Return the (6, 12) grasp matrix G_o of eq. 10, world frame.

    G maps the stacked pad wrenches [f_L; m_L; f_R; m_R] (moments about each contact point
    p_world_contacts, (2, 3) [m]) to the net wrench on the object about its centre of mass
    p_world_object: block i = [[I, 0], [[p_i - p_o]x, I]], so the net moment is
    sum_i (p_i - p_o) x f_i + m_i. out: optional (6, >= 12) array whose first 12 columns
    receive G (and which is returned) instead of a new array.
    """
    lever_arms = np.subtract(p_world_contacts, p_world_object)  # (2, 3) p_i - p_o
    if out is None:
        out = _GRASP_MATRIX_IDENTITY_BLOCKS.copy()
    else:
        out[:, :_N_WRENCH] = _GRASP_MATRIX_IDENTITY_BLOCKS
    out[_SKEW_ROWS, _SKEW_COLUMNS] = _SKEW_SIGNS * lever_arms[:, _SKEW_COMPONENTS].ravel()
    return out


def pad_contact_geometry(arm, p_world_tool, R_world_tool, p_world_object, R_world_object,
                         object_size):
    """
    Return the PadContact of an arm's pad on its face of a box object.

    The left pad works on the object's +y face, the right pad on the -y face. The contact
    normal is the face normal (into the object); the pad x axis is the tool x axis projected
    on the face (object x if the tool x is normal to the face). object_size: (3,) edge
    lengths along the object axes [m].
    """
    if arm not in _OBJECT_FACE_SIGN:
        raise InputError(f'arm must be one of {PAD_ORDER}, got {arm!r}')
    p_world_tool = finite_array('p_world_tool', p_world_tool, (3,))
    R_world_tool = finite_array('R_world_tool', R_world_tool, (3, 3))
    p_world_object = finite_array('p_world_object', p_world_object, (3,))
    R_world_object = finite_array('R_world_object', R_world_object, (3, 3))
    object_size = finite_array('object_size', object_size, (3,))
    outward_normal = _OBJECT_FACE_SIGN[arm] * R_world_object[:, 1]
    normal_distance = float((p_world_tool - p_world_object) @ outward_normal
                            - 0.5 * object_size[1])
    z_axis = -outward_normal
    x_axis = R_world_tool[:, 0] - (R_world_tool[:, 0] @ z_axis) * z_axis
    if np.linalg.norm(x_axis) < 1e-6:
        x_axis = R_world_object[:, 0]
    x_axis = x_axis / np.linalg.norm(x_axis)
    R_world_pad = np.column_stack((x_axis, cross3(z_axis, x_axis), z_axis))
    return PadContact(p_world_contact=p_world_tool - normal_distance * outward_normal,
                      R_world_pad=R_world_pad, normal_distance=normal_distance)
