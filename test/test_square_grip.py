"""
The grip chosen per grasp: a lighter one for a box grasped square, the full one for a yawed box.

A box whose squeeze axis lies within square_grip_yaw of the line between the arms is held at
square_grip_force; the choice is made on the estimate at the first tick of contact and kept
until the grasp ends, and a heavy box is still gripped as hard as its weight needs.
"""

from dataclasses import replace
import math

from conftest import yaw_rotation
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.geometry import rpy_to_matrix
from dual_arm_control.core.phases import Phase
from dual_arm_control.core.wrench_distribution import (grip_normal_force, grip_qp_config,
                                                       squeeze_axis_yaw, WrenchDistributor,
                                                       WrenchDistributorConfig)
import numpy as np
import pytest

CUBE_SIZE = (0.2, 0.2, 0.2)
CUBE_MASS = 0.7
DT = 0.005


@pytest.mark.parametrize('yaw_deg, expected', [
    (0.0, 0.0), (7.0, 7.0), (-7.0, 7.0), (173.0, 7.0), (-173.0, 7.0), (95.0, 85.0),
    (90.0, 90.0)])
def test_squeeze_axis_yaw_is_folded_over_the_half_turn(yaw_deg, expected):
    """The pads hold the +-y faces: a half turn is the same grasp, so 173 deg is 7 off."""
    assert squeeze_axis_yaw(yaw_rotation(math.radians(yaw_deg))) == pytest.approx(expected,
                                                                                  abs=1e-9)


def test_squeeze_axis_yaw_ignores_a_tilt_about_the_squeeze_axis():
    rotation = rpy_to_matrix((0.0, 0.3, math.radians(10.0)))
    assert squeeze_axis_yaw(rotation) == pytest.approx(10.0, abs=1e-9)


def test_a_square_box_gets_the_square_grip_and_a_yawed_one_the_full_grip():
    config = WrenchDistributorConfig()
    square = grip_qp_config(config, CUBE_MASS, 11.9)
    assert square.min_normal_force == square.squeeze_force == config.square_grip_force
    assert square.max_normal_force == config.qp.max_normal_force
    assert grip_qp_config(config, CUBE_MASS, 12.0) == config.qp
    off = replace(config, square_grip_yaw=0.0)
    assert grip_qp_config(off, CUBE_MASS, 0.0) == config.qp


def test_a_heavy_square_box_is_still_gripped_as_its_weight_needs():
    config = WrenchDistributorConfig()
    mass = 5.0
    required = grip_normal_force(mass, config.qp.friction_coefficient,
                                 config.design_acceleration, config.object.gravity,
                                 config.grip_safety_factor)
    assert required > config.qp.min_normal_force
    for yaw in (0.0, 30.0):
        qp = grip_qp_config(config, mass, yaw)
        assert qp.min_normal_force == pytest.approx(required)
        assert qp.min_normal_force <= qp.squeeze_force < qp.max_normal_force


def test_square_grip_force_must_stay_below_the_largest_normal_force():
    with pytest.raises(ConfigError, match='square_grip_force'):
        WrenchDistributorConfig(square_grip_force=105.0)
    with pytest.raises(ConfigError, match='square_grip_yaw'):
        WrenchDistributorConfig(square_grip_yaw=-1.0)


def _tick(distributor, phase, yaw_deg):
    """Step a distributor with both pads on the faces of a resting cube yawed yaw_deg."""
    rotation = yaw_rotation(math.radians(yaw_deg))
    p_object = np.array([0.5, 0.0, 0.42])
    tools = {arm: p_object + sign * 0.1 * rotation[:, 1]
             for arm, sign in (('left', 1.0), ('right', -1.0))}
    frames = {arm: rotation for arm in tools}
    return distributor.step(phase, tools, frames, p_object, rotation, np.zeros(3), np.zeros(3),
                            np.zeros(3), np.zeros(3), DT)


def _pad_normal_force(result, arm, yaw_deg):
    """Return the pad's push along its face's inward normal [N]."""
    inward = -(1.0 if arm == 'left' else -1.0) * yaw_rotation(math.radians(yaw_deg))[:, 1]
    return float(result.wrenches[arm][:3] @ inward)


def test_the_grip_is_chosen_at_contact_and_kept_until_the_grasp_ends():
    config = WrenchDistributorConfig()
    distributor = WrenchDistributor(config, CUBE_MASS, CUBE_SIZE)
    assert _tick(distributor, Phase.REACH, 5.0).normal_force_floor == 0.0
    assert _tick(distributor, Phase.CONTACT, 5.0).normal_force_floor == config.square_grip_force
    for _ in range(60):
        held = _tick(distributor, Phase.MANIPULATE, 20.0)
    assert held.normal_force_floor == config.square_grip_force
    for arm in ('left', 'right'):
        assert config.square_grip_force - 1e-3 <= _pad_normal_force(held, arm, 20.0) < (
            config.qp.min_normal_force)
    assert _tick(distributor, Phase.RELEASE, 20.0).normal_force_floor == 0.0
    assert _tick(distributor, Phase.CONTACT, 20.0).normal_force_floor == (
        config.qp.min_normal_force)
    for _ in range(60):
        held = _tick(distributor, Phase.MANIPULATE, 20.0)
    for arm in ('left', 'right'):
        assert _pad_normal_force(held, arm, 20.0) >= config.qp.min_normal_force - 1e-3


def test_a_new_config_mid_grasp_keeps_the_grasp_s_grip_choice():
    config = WrenchDistributorConfig()
    distributor = WrenchDistributor(config, CUBE_MASS, CUBE_SIZE)
    _tick(distributor, Phase.CONTACT, 3.0)
    distributor.reconfigure(replace(config, square_grip_force=50.0))
    assert _tick(distributor, Phase.MANIPULATE, 3.0).normal_force_floor == 50.0
