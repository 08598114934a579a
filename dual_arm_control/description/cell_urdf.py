"""
The URDF of the whole cell, built from the arm URDFs and config/cell.yaml (one source).

Both arms hang off a root link 'world' at their cell base poses, every link and joint named
with the arm's prefix ('left_link_3', 'left_A3', 'left_tool'), so the joint names are those of
/<arm>/joint_states. Each collision shape is repeated as a visual (the arm URDFs carry
collision geometry only), so RViz and Foxglove draw the arms; the pallet and the front table
are fixed boxes. This is the text on /robot_description.
"""

import copy
import xml.etree.ElementTree as ElementTree

from dual_arm_control.core.arms import ARMS, joint_names
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.geometry import matrix_to_rpy, quat_xyzw_to_matrix, rpy_to_matrix
from dual_arm_control.description.cell import load_cell
import numpy as np

ROBOT_NAME = 'dual_arm_cell'
WORLD_LINK = 'world'
SCENE_BLOCKS = ('pallet', 'front_table')


def arm_frame(arm, link):
    """Return the cell name of an arm URDF link or joint, e.g. ('left', 'tool') -> 'left_tool'."""
    return f'{arm}_{link}'


def base_joint(arm):
    """Return the name of the fixed joint that places an arm's base in the world."""
    return arm_frame(arm, 'base_joint')


def urdf_vector(text, default='0 0 0'):
    """Return the numbers of a URDF attribute ('0.1 0 0.3') as an array; default if absent."""
    return np.array([float(value) for value in (text or default).split()])


def urdf_origin(element):
    """Return (p (3,), R (3, 3)) of the <origin> child of a URDF element (identity if absent)."""
    origin = element.find('origin') if element is not None else None
    if origin is None:
        return np.zeros(3), np.eye(3)
    return urdf_vector(origin.get('xyz')), rpy_to_matrix(urdf_vector(origin.get('rpy')))


def _origin(parent, position, rotation):
    text = ' '.join(f'{value:.9g}' for value in position)
    rpy = ' '.join(f'{value:.9g}' for value in matrix_to_rpy(rotation))
    ElementTree.SubElement(parent, 'origin', xyz=text, rpy=rpy)


def _fixed_joint(robot, name, parent, child, position, rotation):
    joint = ElementTree.SubElement(robot, 'joint', name=name, type='fixed')
    ElementTree.SubElement(joint, 'parent', link=parent)
    ElementTree.SubElement(joint, 'child', link=child)
    _origin(joint, position, rotation)


def _add_arm(robot, description):
    """Append one arm's links and joints, prefixed, and its base joint to the world."""
    try:
        arm_root = ElementTree.parse(description.urdf).getroot()
    except (ElementTree.ParseError, OSError) as error:
        raise ConfigError(f'{description.urdf}: cannot read URDF: {error}') from None
    arm = description.arm
    children = set()
    revolute = []
    for element in arm_root:
        if element.tag not in ('link', 'joint'):
            continue
        element = copy.deepcopy(element)
        element.set('name', arm_frame(arm, element.get('name')))
        if element.tag == 'link':
            for collision in element.findall('collision'):
                visual = copy.deepcopy(collision)
                visual.tag = 'visual'
                element.append(visual)
        else:
            for end in ('parent', 'child'):
                reference = element.find(end)
                reference.set('link', arm_frame(arm, reference.get('link')))
            children.add(element.find('child').get('link'))
            if element.get('type') == 'revolute':
                revolute.append(element.get('name'))
        robot.append(element)
    if revolute != joint_names(arm):
        raise ConfigError(f'{description.urdf}: revolute joints {revolute} do not give the '
                          f'message joint names {joint_names(arm)}')
    roots = [link.get('name') for link in robot.findall('link')
             if link.get('name').startswith(arm_frame(arm, '')) and
             link.get('name') not in children]
    if len(roots) != 1:
        raise ConfigError(f'{description.urdf}: expected one root link, found {roots}')
    _fixed_joint(robot, base_joint(arm), WORLD_LINK, roots[0], description.base_position,
                 quat_xyzw_to_matrix(description.base_orientation))


def _add_block(robot, name, block):
    """Append a fixed box link (pallet, front table) at its place in the world."""
    link = ElementTree.SubElement(robot, 'link', name=name)
    size = ' '.join(f'{value:.9g}' for value in block.size)
    for tag in ('visual', 'collision'):
        shape = ElementTree.SubElement(ElementTree.SubElement(link, tag), 'geometry')
        ElementTree.SubElement(shape, 'box', size=size)
    _fixed_joint(robot, f'{name}_joint', WORLD_LINK, name, block.center, np.eye(3))


def cell_urdf(cell=None):
    """Return the cell's URDF text: both arms placed and prefixed, the pallet and the table."""
    cell = cell or load_cell()
    robot = ElementTree.Element('robot', name=ROBOT_NAME)
    ElementTree.SubElement(robot, 'link', name=WORLD_LINK)
    for arm in ARMS:
        _add_arm(robot, cell.arm(arm))
    for name in SCENE_BLOCKS:
        _add_block(robot, name, getattr(cell, name))
    ElementTree.indent(robot)
    return '<?xml version="1.0"?>\n' + ElementTree.tostring(robot, encoding='unicode') + '\n'
