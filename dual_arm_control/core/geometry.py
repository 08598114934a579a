"""
Small rotation and frame helpers shared by the DS, tracker and controllers.

Quaternions are stored as (x, y, z, w), the ROS message order; names carry ``quat_xyzw``.
"""

import math

from dual_arm_control.core.exceptions import InputError
import numpy as np


_SMALL_ANGLE = 1e-9
_IDENTITY = np.eye(3)
_IDENTITY.setflags(write=False)


def skew(vector):
    """Return the (3, 3) skew-symmetric matrix [v]x such that [v]x @ u = v x u."""
    x, y, z = np.asarray(vector, dtype=float).tolist()
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def cross3(a, b):
    """Return a x b (3,) for two 3-vectors (np.cross without its generic-axis overhead)."""
    a0, a1, a2 = float(a[0]), float(a[1]), float(a[2])
    b0, b1, b2 = float(b[0]), float(b[1]), float(b[2])
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def vector_norm(vector):
    """
    Return the Euclidean norm of a float array (its entries as one vector) as a float.

    The same number np.linalg.norm returns (the square root of the flat array's dot product with
    itself), without its dispatch: the per-tick code takes many norms of 3-vectors.
    """
    flat = vector.ravel(order='K')
    return math.sqrt(flat.dot(flat))


def last_axis_norms(vectors):
    """
    Return the norms (..., 1) of a float array's vectors along its last axis.

    np.linalg.norm(vectors, axis=-1, keepdims=True), computed as it computes it (the square
    root of the summed squares), without its dispatch.
    """
    return np.sqrt(np.add.reduce(vectors * vectors, axis=-1, keepdims=True))


def unit(vector, name='vector'):
    """Return vector / ||vector||; raise InputError for a (near) zero vector."""
    vector = np.asarray(vector, dtype=float)
    norm = vector_norm(vector)
    if not np.isfinite(norm) or norm < 1e-12:
        raise InputError(f'{name} has no direction (norm {norm:g})')
    return vector / norm


def orthonormal_basis(first_axis):
    """
    Return a deterministic right-handed (3, 3) basis [e1 e2 e3] with e1 along first_axis.

    e2 is built from the world axis least aligned with e1, so the same input always gives the
    same basis (unlike a basis completed from a random matrix).
    """
    e1 = unit(first_axis, 'first_axis')
    helper_axis = np.eye(3)[int(np.argmin(np.abs(e1)))]
    e2 = unit(helper_axis - e1 * (e1 @ helper_axis))
    e3 = cross3(e1, e2)
    return np.column_stack((e1, e2, e3))


def quat_xyzw_to_matrix(quat_xyzw):
    """Return the rotation matrix of a (possibly unnormalised) quaternion (x, y, z, w)."""
    x, y, z, w = unit(quat_xyzw, 'quaternion').tolist()
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def rpy_to_matrix(rpy):
    """Return the rotation of URDF roll, pitch, yaw [rad]: Rz(yaw) Ry(pitch) Rx(roll)."""
    roll, pitch, yaw = rpy
    cr, sr, cp, sp, cy, sy = (np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch),
                              np.cos(yaw), np.sin(yaw))
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def matrix_to_rpy(rotation):
    """Return URDF roll, pitch, yaw [rad] of a rotation matrix (inverse of rpy_to_matrix)."""
    pitch = np.arcsin(-np.clip(rotation[2, 0], -1.0, 1.0))
    if abs(np.cos(pitch)) < 1e-9:
        return 0.0, float(pitch), float(np.arctan2(-rotation[0, 1], rotation[1, 1]))
    return (float(np.arctan2(rotation[2, 1], rotation[2, 2])), float(pitch),
            float(np.arctan2(rotation[1, 0], rotation[0, 0])))


def matrix_to_quat_xyzw(rotation):
    """Return the unit quaternion (x, y, z, w) with w >= 0 of a rotation matrix."""
    r = np.asarray(rotation, dtype=float)
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = r.tolist()
    trace = r00 + r11 + r22
    if trace > 0.0:
        s = 2.0 * math.sqrt(trace + 1.0)
        quat = np.array([(r21 - r12) / s, (r02 - r20) / s, (r10 - r01) / s, 0.25 * s])
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(max(1.0 + r[i, i] - r[j, j] - r[k, k], 0.0))
        quat = np.empty(4)
        quat[i] = 0.25 * s
        quat[j] = (r[j, i] + r[i, j]) / s
        quat[k] = (r[k, i] + r[i, k]) / s
        quat[3] = (r[k, j] - r[j, k]) / s
    quat /= vector_norm(quat)
    return quat if quat[3] >= 0.0 else -quat


def rotation_log(rotation):
    """Return the rotation vector theta * mu (rad) of a rotation matrix (SO(3) logarithm)."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = np.asarray(rotation, dtype=float).tolist()
    cos_theta = min(1.0, max(-1.0, 0.5 * (r00 + r11 + r22 - 1.0)))
    theta = math.acos(cos_theta)
    axis_times_sin = np.array([0.5 * (r21 - r12), 0.5 * (r02 - r20), 0.5 * (r10 - r01)])
    if theta < _SMALL_ANGLE:
        return axis_times_sin
    if math.pi - theta < 1e-6:
        r = np.asarray(rotation, dtype=float)
        symmetric = 0.5 * (r + np.eye(3))
        axis = symmetric[:, int(np.argmax(np.diag(symmetric)))]
        axis = unit(axis)
        if axis @ axis_times_sin < 0.0:
            axis = -axis
        return theta * axis
    return theta / math.sin(theta) * axis_times_sin


def rotation_exp(rotation_vector):
    """Return the rotation matrix of a rotation vector theta * mu (SO(3) exponential)."""
    rotation_vector = np.asarray(rotation_vector, dtype=float)
    theta = vector_norm(rotation_vector)
    k = skew(rotation_vector)
    if theta < _SMALL_ANGLE:
        return _IDENTITY + k
    return (_IDENTITY + np.sin(theta) / theta * k
            + (1.0 - np.cos(theta)) / theta ** 2 * k @ k)


def slerp_rotation(rotation_start, rotation_end, fraction):
    """Return the geodesic interpolation between two rotation matrices, fraction in [0, 1]."""
    delta = rotation_log(np.asarray(rotation_start).T @ rotation_end)
    return rotation_start @ rotation_exp(fraction * delta)


def turned_rectangle_half_extents(angle, half_x, half_y):
    """
    Return the half extents (along x, along y) of a rectangle turned by angle [rad] in its plane.

    The rectangle spans half_x along its own x and half_y along its own y; turned, its bounding
    rectangle is |cos| half_x + |sin| half_y along x and |sin| half_x + |cos| half_y along y.
    """
    cosine, sine = abs(math.cos(angle)), abs(math.sin(angle))
    return (cosine * half_x + sine * half_y, sine * half_x + cosine * half_y)
