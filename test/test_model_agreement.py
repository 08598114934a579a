"""pinocchio (controllers) and MuJoCo (twin) load the same description, and the configs agree."""

import xml.etree.ElementTree as ElementTree

from dual_arm_control.core.motion_config import MotionGeneratorConfig
from dual_arm_control.core.wrench_qp import WrenchQPConfig
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.description.cell_urdf import urdf_vector
from dual_arm_control.scenario import load_scenario
import mujoco
import numpy as np
import pytest
from sim_bridge.scene import build_model

CONFIGURATIONS = 60
# Both libraries evaluate the same rigid-body algorithms in double precision; differences
# are rounding (~1e-15 measured). 1e-6 leaves room for summation order, not for a modelling
# difference (a wrong armature, inertia or offset shows up at >= 1e-3).
RELATIVE_TOLERANCE = 1e-6


@pytest.fixture(scope='module')
def cell():
    return load_cell()


@pytest.fixture(scope='module')
def mujoco_cell(cell):
    model, index = build_model(cell, load_scenario('hold', cell).object)
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    return model, index


def relative_error(found, expected):
    return np.linalg.norm(np.asarray(found) - expected) / max(np.linalg.norm(expected), 1e-12)


@pytest.mark.parametrize('arm', ['left', 'right'])
def test_pinocchio_and_mujoco_agree(cell, mujoco_cell, arm):
    model, index = mujoco_cell
    data = mujoco.MjData(model)
    pinocchio_arm = arm_model(arm, cell)
    arm_index = index.arms[arm]
    lower, upper = pinocchio_arm.position_limits
    rng = np.random.default_rng(11 if arm == 'left' else 12)
    dense_mass = np.zeros((model.nv, model.nv))
    jacobian_position = np.zeros((3, model.nv))
    jacobian_rotation = np.zeros((3, model.nv))
    worst = dict.fromkeys(('tool', 'flange', 'sensor', 'mass', 'gravity', 'jacobian',
                           'forward_dynamics'), 0.0)
    for _ in range(CONFIGURATIONS):
        q = rng.uniform(lower, upper)
        dq = rng.uniform(-1.0, 1.0, 7)
        tau = rng.uniform(-0.5, 0.5, 7) * pinocchio_arm.torque_limits
        data.qpos[:] = 0.0
        data.qvel[:] = 0.0
        data.ctrl[:] = 0.0
        data.qpos[arm_index.qpos] = q
        mujoco.mj_forward(model, data)
        for name, site, pose in (('tool', arm_index.tool_site, pinocchio_arm.tool_pose),
                                 ('flange', arm_index.flange_site, pinocchio_arm.flange_pose),
                                 ('sensor', arm_index.sensor_site, pinocchio_arm.sensor_pose)):
            p_world, R_world = pose(q)
            error = max(relative_error(data.site_xpos[site], p_world),
                        np.abs(data.site_xmat[site].reshape(3, 3) - R_world).max())
            worst[name] = max(worst[name], error)
        mujoco.mj_fullM(model, data, dense_mass)
        worst['mass'] = max(worst['mass'], relative_error(
            dense_mass[np.ix_(arm_index.dof, arm_index.dof)], pinocchio_arm.mass_matrix(q)))
        worst['gravity'] = max(worst['gravity'], relative_error(
            data.qfrc_bias[arm_index.dof], pinocchio_arm.gravity_torque(q)))
        mujoco.mj_jacSite(model, data, jacobian_position, jacobian_rotation,
                          arm_index.tool_site)
        jacobian = np.vstack((jacobian_position, jacobian_rotation))[:, arm_index.dof]
        worst['jacobian'] = max(worst['jacobian'], relative_error(
            jacobian, pinocchio_arm.tool_jacobian(q)))
        data.qvel[arm_index.dof] = dq
        data.ctrl[arm_index.actuators] = tau
        mujoco.mj_forward(model, data)
        worst['forward_dynamics'] = max(worst['forward_dynamics'], relative_error(
            data.qacc[arm_index.dof], pinocchio_arm.forward_dynamics(q, dq, tau)))
    print(f'{arm}: worst relative errors over {CONFIGURATIONS} configurations: {worst}')
    for quantity, error in worst.items():
        assert error <= RELATIVE_TOLERANCE, \
            f'{arm} {quantity}: relative error {error:.3g} > {RELATIVE_TOLERANCE:g}'


@pytest.mark.parametrize('arm', ['left', 'right'])
def test_mujoco_uses_cell_drive_parameters_and_urdf_masses(cell, mujoco_cell, arm):
    model, index = mujoco_cell
    description = cell.arm(arm)
    dofs = index.arms[arm].dof
    assert model.dof_armature[dofs] == pytest.approx(description.armature, abs=0.0)
    assert model.dof_damping[dofs] == pytest.approx(description.damping, abs=0.0)
    arm_bodies = [body for body in range(model.nbody)
                  if model.body(body).name.startswith(f'{arm}/')]
    total_mass = model.body_mass[arm_bodies].sum()
    expected = {'iiwa7': 23.9, 'iiwa14': 29.9}[description.model] + 0.2
    assert total_mass == pytest.approx(expected, abs=1e-9), \
        f'{arm}: MuJoCo arm + tool mass {total_mass} kg, expected {expected} kg'
    limits = model.actuator_ctrlrange[index.arms[arm].actuators, 1]
    assert limits == pytest.approx(arm_model(arm, cell).torque_limits, abs=0.0)


@pytest.mark.parametrize('arm', ['left', 'right'])
def test_every_pad_extent_the_controllers_use_is_the_robot_descriptions_pad(cell, arm):
    """
    The pad is described once, in the URDF; the config fields that repeat it must agree.

    The contact detector, the grasp planner, the run-in's clearance and the wrench QP's
    centre-of-pressure limits each carry the pad's size as a parameter of their own node or
    config. A default changed in one place and not the others would plan grasps, clearances
    and wrenches for a pad the robot does not have.
    """
    pads = [collision for collision in ElementTree.parse(cell.arm(arm).urdf).iter('collision')
            if collision.get('name') == 'pad']
    assert len(pads) == 1
    length, width, _ = urdf_vector(pads[0].find('geometry/box').get('size'))
    motion = MotionGeneratorConfig()
    qp = WrenchQPConfig()
    np.testing.assert_allclose(motion.contact.pad_size, (length, width), rtol=1e-12)
    np.testing.assert_allclose(2.0 * np.array([motion.reachability.pad_half_length,
                                               motion.reachability.pad_half_width]),
                               (length, width), rtol=1e-12)
    assert 2.0 * motion.impact.pad_half_height == pytest.approx(width, rel=1e-12)
    np.testing.assert_allclose(2.0 * np.array([qp.pad_half_length, qp.pad_half_width]),
                               (length, width), rtol=1e-12)
