"""The URDFs and config/cell.yaml against the public KUKA figures and the standby poses."""

import math
import xml.etree.ElementTree as ElementTree

from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.motion_config import MotionGeneratorConfig
from dual_arm_control.core.robot_model import ArmModel
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.resources import urdf_path
import numpy as np
import pinocchio as pin
import pytest

# Public figures (robot facts of the project): offsets [m], limits [deg, deg/s, N m], masses [kg].
FACTS = {
    'iiwa7': {
        'offsets': (0.340, 0.400, 0.400, 0.126),
        'position_deg': (170, 120, 170, 120, 170, 120, 175),
        'velocity_deg': (98, 98, 100, 130, 140, 180, 180),
        'torque': (176, 176, 110, 110, 110, 40, 40),
        'robot_mass': 23.9,
        'link_masses': (4.856, 3.394, 4.032, 3.394, 4.032, 1.529, 2.404, 0.259),
    },
    'iiwa14': {
        'offsets': (0.360, 0.420, 0.400, 0.126),
        'position_deg': (170, 120, 170, 120, 170, 120, 175),
        'velocity_deg': (85, 85, 100, 75, 130, 135, 135),
        'torque': (320, 320, 176, 176, 110, 40, 40),
        'robot_mass': 29.9,
        'link_masses': (7.050, 5.290, 5.689, 3.461, 4.123, 1.564, 2.458, 0.265),
    },
}
TOOL_MASS = 0.2             # [kg]
TOOL_COM_FROM_SENSOR = 0.035  # [m] along flange z
TOOL_OFFSET = 0.115         # [m] flange -> tool along flange z
PAD_SIZE = (0.15, 0.10)     # [m] along tool x, tool y
AXES = ('z', 'y', 'z', 'y', 'z', 'y', 'z')
MODELS = sorted(FACTS)


def urdf_tree(model):
    return ElementTree.parse(urdf_path(model)).getroot()


def joint_elements(model):
    return {joint.get('name'): joint for joint in urdf_tree(model).iter('joint')}


def bare_model(model):
    return ArmModel(urdf_path(model), [f'A{i}' for i in range(1, 8)])


@pytest.mark.parametrize('model', MODELS)
def test_total_mass_is_robot_plus_tool(model):
    masses = {link.get('name'): float(link.find('inertial/mass').get('value'))
              for link in urdf_tree(model).iter('link') if link.find('inertial') is not None}
    expected = FACTS[model]['robot_mass'] + TOOL_MASS
    found = sum(masses.values())
    assert found == pytest.approx(expected, abs=1e-9), \
        f'{model}: total mass expected {expected} kg, found {found} kg'
    split = [masses[f'link_{i}'] for i in range(8)]
    assert split == pytest.approx(FACTS[model]['link_masses'], abs=1e-9), \
        f'{model}: link masses expected {FACTS[model]["link_masses"]} kg, found {split} kg'
    assert masses['grabber'] == pytest.approx(TOOL_MASS), \
        f'{model}: tool mass expected {TOOL_MASS} kg, found {masses["grabber"]} kg'


@pytest.mark.parametrize('model', MODELS)
def test_limits_match_data_sheet(model):
    facts = FACTS[model]
    joints = joint_elements(model)
    for index in range(7):
        name = f'A{index + 1}'
        limit = joints[name].find('limit')
        expected = (math.radians(facts['position_deg'][index]),
                    math.radians(facts['velocity_deg'][index]), facts['torque'][index])
        found = (float(limit.get('upper')), float(limit.get('velocity')),
                 float(limit.get('effort')))
        assert float(limit.get('lower')) == pytest.approx(-expected[0], abs=1e-6), \
            f'{model} {name}: lower limit expected {-expected[0]:.6f} rad, found ' \
            f'{limit.get("lower")} rad'
        assert found == pytest.approx(expected, abs=1e-6), \
            f'{model} {name}: (position rad, velocity rad/s, torque N m) expected ' \
            f'{expected}, found {found}'


@pytest.mark.parametrize('model', MODELS)
def test_link_offsets_axes_and_tool_frames(model):
    arm = bare_model(model)
    data = arm.model.createData()
    pin.forwardKinematics(arm.model, data, np.zeros(7))
    pin.updateFramePlacements(arm.model, data)
    joint_origin = [data.oMi[index].translation for index in range(1, 8)]
    flange = data.oMf[arm.model.getFrameId('flange')]
    offsets = (joint_origin[1][2], joint_origin[3][2] - joint_origin[1][2],
               joint_origin[5][2] - joint_origin[3][2], flange.translation[2] - joint_origin[5][2])
    assert offsets == pytest.approx(FACTS[model]['offsets'], abs=1e-9), \
        f'{model}: offsets d1, d3, d5, d7 expected {FACTS[model]["offsets"]} m, found {offsets} m'
    for origin in joint_origin + [flange.translation]:
        assert origin[:2] == pytest.approx([0.0, 0.0], abs=1e-12), \
            f'{model}: zero pose must be straight up, found joint at {origin} m'
    angular = arm.tool_jacobian(np.zeros(7))[3:]
    axes = tuple('xyz'[int(np.argmax(np.abs(column)))] for column in angular.T)
    assert np.abs(angular).max(axis=0) == pytest.approx(np.ones(7), abs=1e-12)
    assert axes == AXES, f'{model}: joint axes expected {AXES}, found {axes}'
    tool = data.oMf[arm.model.getFrameId('tool')]
    sensor = data.oMf[arm.model.getFrameId('ft_sensor')]
    assert flange.actInv(tool).translation == pytest.approx([0, 0, TOOL_OFFSET], abs=1e-12), \
        f'{model}: tool expected {TOOL_OFFSET} m along flange z'
    assert flange.actInv(tool).rotation == pytest.approx(np.eye(3), abs=1e-12)
    assert flange.actInv(sensor).translation == pytest.approx(np.zeros(3), abs=1e-12)


@pytest.mark.parametrize('model', MODELS)
def test_tool_inertia_and_pad_geometry(model):
    links = {link.get('name'): link for link in urdf_tree(model).iter('link')}
    grabber = links['grabber']
    com = [float(v) for v in grabber.find('inertial/origin').get('xyz').split()]
    assert com == pytest.approx([0, 0, TOOL_COM_FROM_SENSOR]), \
        f'{model}: tool CoM expected {TOOL_COM_FROM_SENSOR} m along z, found {com} m'
    joints = joint_elements(model)
    assert joints['grabber_joint'].find('parent').get('link') == 'ft_sensor'
    pad = grabber.find("collision[@name='pad']")
    size = [float(v) for v in pad.find('geometry/box').get('size').split()]
    centre = [float(v) for v in pad.find('origin').get('xyz').split()]
    assert size[:2] == pytest.approx(PAD_SIZE), f'{model}: pad expected {PAD_SIZE} m, found {size}'
    assert 0.01 <= size[2] <= 0.02, f'{model}: pad thickness {size[2]} m outside [0.01, 0.02] m'
    outer_face = centre[2] + 0.5 * size[2]
    assert outer_face == pytest.approx(TOOL_OFFSET, abs=1e-12), \
        f'{model}: pad outer face expected at {TOOL_OFFSET} m from the flange, found {outer_face}'


@pytest.mark.parametrize('arm', ['left', 'right'])
def test_urdf_damping_equals_cell_damping(arm):
    description = load_cell().arm(arm)
    joints = joint_elements(description.model)
    urdf_damping = [float(joints[f'A{i}'].find('dynamics').get('damping')) for i in range(1, 8)]
    assert urdf_damping == pytest.approx(description.damping.tolist(), abs=0.0), \
        f'{arm}: URDF damping {urdf_damping} N m s/rad differs from cell.yaml ' \
        f'{description.damping.tolist()}'


def test_cell_places_arms_as_the_convention():
    cell = load_cell()
    assert cell.arm('left').model == 'iiwa7' and cell.arm('right').model == 'iiwa14'
    assert cell.arm('left').base_position == pytest.approx([0.0, 0.65, 0.0])
    assert cell.arm('right').base_position == pytest.approx([0.0, -0.65, 0.0])
    assert cell.pallet.top_height == pytest.approx(0.22)
    assert cell.front_table.top_height == pytest.approx(0.15)
    assert cell.surface_height(0.41, 0.0) == pytest.approx(0.22)
    assert cell.surface_height(0.9, 0.3) == pytest.approx(0.15)
    assert cell.surface_height(0.6, 0.0) == pytest.approx(0.0)


@pytest.mark.parametrize('arm', ['left', 'right'])
def test_home_configuration_reaches_standby_pose(arm):
    cell = load_cell()
    description = cell.arm(arm)
    model = arm_model(arm, cell)
    p_world_tool, R_world_tool = model.tool_pose(description.q_home)
    position_error = np.linalg.norm(p_world_tool - description.standby_position)
    angle_error = np.linalg.norm(pin.log3(description.R_world_standby.T @ R_world_tool))
    assert position_error <= 0.02, \
        f'{arm}: home tool at {p_world_tool} m, standby {description.standby_position} m'
    assert angle_error <= math.radians(5.0), f'{arm}: home tool orientation off by ' \
        f'{math.degrees(angle_error):.2f} deg (limit 5 deg)'
    side = 1.0 if arm == 'left' else -1.0
    expected_z = np.array([0.0, -side, -1.0]) / math.sqrt(2.0)
    assert R_world_tool[:, 2] == pytest.approx(expected_z, abs=math.radians(5.0))
    lower, upper = model.position_limits
    assert np.all(description.q_home > lower) and np.all(description.q_home < upper)


def test_arm_model_dynamics_identities():
    model = arm_model('right')
    rng = np.random.default_rng(3)
    lower, upper = model.position_limits
    q = rng.uniform(lower, upper)
    dq = rng.uniform(-1.0, 1.0, 7)
    tau = rng.uniform(-20.0, 20.0, 7)
    mass = model.mass_matrix(q)
    ddq = model.forward_dynamics(q, dq, tau)
    residual = mass @ ddq + model.nonlinear_effects(q, dq) + model.damping * dq - tau
    assert np.max(np.abs(residual)) < 1e-9, f'M ddq + h + D dq - tau = {residual} N m'
    bare = ArmModel(model.urdf_path, model.joint_names, base_position=[0.0, -0.5, 0.0])
    assert np.diag(mass - bare.mass_matrix(q)) == pytest.approx(model.armature, abs=1e-12)
    step = 1e-7
    twist = np.concatenate(model.tool_twist(q, dq))
    p_next, R_next = model.tool_pose(q + step * dq)
    p_now, R_now = model.tool_pose(q)
    numeric = np.concatenate(((p_next - p_now) / step, pin.log3(R_next @ R_now.T) / step))
    assert twist == pytest.approx(numeric, abs=1e-5)


def test_arm_model_rejects_bad_input():
    with pytest.raises(ConfigError, match='joint_names'):
        ArmModel(urdf_path('iiwa7'), ['A1'])
    model = arm_model('left')
    with pytest.raises(ValueError, match='q'):
        model.tool_pose([0.0] * 6)
    with pytest.raises(ValueError, match='NaN'):
        model.gravity_torque([math.nan] * 7)


def test_motion_generator_standby_defaults_are_the_cells():
    """The motion generator's standby default repeats config/cell.yaml: they must agree."""
    cell = load_cell()
    np.testing.assert_allclose(MotionGeneratorConfig().standby_positions,
                               [cell.arm(arm).standby_position for arm in ('left', 'right')])
