"""Grasp frames sit on the squeezed faces with normals pointing into the object."""

from dual_arm_control.core.geometry import rotation_exp
from dual_arm_control.core.grasp import grasp_frame, R_object_grasp
import numpy as np
import pytest

SIZE = (0.2, 0.3, 0.25)


@pytest.mark.parametrize('arm', ['left', 'right'])
def test_grasp_rotation_is_proper(arm):
    rotation = R_object_grasp(arm)
    assert np.allclose(rotation.T @ rotation, np.eye(3))
    assert np.linalg.det(rotation) == pytest.approx(1.0)


def test_faces_and_normals_for_a_rotated_object():
    rng = np.random.default_rng(3)
    for _ in range(20):
        R_world_object = rotation_exp(rng.uniform(-2.0, 2.0, 3))
        p_world_object = rng.uniform(-1.0, 1.0, 3)
        left = grasp_frame('left', p_world_object, R_world_object, SIZE)
        right = grasp_frame('right', p_world_object, R_world_object, SIZE)
        y_axis = R_world_object[:, 1]
        assert np.allclose(left.p_world_grasp - p_world_object, 0.15 * y_axis)
        assert np.allclose(right.p_world_grasp - p_world_object, -0.15 * y_axis)
        for frame in (left, right):
            towards_centre = p_world_object - frame.p_world_grasp
            assert frame.normal @ towards_centre == pytest.approx(0.15)
            assert np.allclose(frame.R_world_grasp[:, 0], R_world_object[:, 0])


def test_world_aligned_object_puts_left_pad_on_plus_y():
    frame = grasp_frame('left', np.array([0.41, 0.0, 0.32]), np.eye(3), (0.2, 0.2, 0.2))
    assert np.allclose(frame.p_world_grasp, [0.41, 0.1, 0.32])
    assert np.allclose(frame.normal, [0.0, -1.0, 0.0])
