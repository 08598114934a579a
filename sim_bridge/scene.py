"""
MuJoCo model of the cell, built from the arm URDFs, config/cell.yaml and a scenario.

The URDFs are read here link by link into an MjSpec (no hand-written copy of kinematics or
inertias): every link with mass becomes a body with the URDF's inertial (the compiler never
infers inertia from geoms, never fuses or balances), every massless link connected by a fixed
joint becomes a site named after it (tool, flange, ft_sensor), so the frames keep their URDF
names under the arm prefix ('left/tool'). MuJoCo's own URDF importer is not used because it
fuses fixed links and may alter inertias (fusestatic, balanceinertia, inertiafromgeom).

Contacts: only the pads, the object and the static scene collide; arm links are visual. The
pad-object contact is an explicit pair with stiff, critically damped parameters that keep
0.5-1 m/s impacts stable at dt = 1 ms.
"""

from dataclasses import dataclass
import math
import xml.etree.ElementTree as ElementTree

from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.geometry import matrix_to_quat_xyzw
from dual_arm_control.description.cell_urdf import urdf_origin, urdf_vector
import mujoco
import numpy as np

PHYSICS_TIMESTEP = 0.001         # [s]
GRAVITY = (0.0, 0.0, -9.81)      # [m/s^2]
TOOL_SITE = 'tool'
FLANGE_SITE = 'flange'
SENSOR_SITE = 'ft_sensor'
FT_SITE = 'ft_measure'           # site on the body beyond the sensor: what the sensor carries
PAD_GEOM = 'pad'
OBJECT_BODY = 'object'
# Contact of pads with the object, and of the object with the pallet, table and floor:
# time constant 5 ms (>= 2 dt at dt = 1 ms), critically damped; impedance 0.95 -> 0.99 over
# 1 mm of penetration. Pads resist twisting (condim 4) as a flat patch pressed flush on a face
# with uniform pressure: torsional coefficient mu times the mean distance of the pad's points
# from its centre (pad_torsion_arm, 0.048 m for the 0.15 x 0.10 m pad).
CONTACT_SOLREF = (0.005, 1.0)
CONTACT_SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)
PAD_CONDIM = 4
PAD_ROLLING_FRICTION = 0.0001    # [m]
# Box against pallet, table and floor [-]. Set on both geoms (MuJoCo mixes geom frictions by
# taking the maximum); the pad-box friction comes from the object catalogue through the pair.
SCENE_FRICTION = 0.6
# Collision bits: static scene (1) touches the object (1) and the pads (2); the pads touch
# the object only through the explicit pair. Every other arm link (4 left, 8 right) touches the
# scene, the object and the other arm's links, not its own arm's: a link's contact with anything
# but the box through a pad is an arm collision (DualArmTwin counts them).
SCENE_CONTYPE, SCENE_CONAFFINITY = 1, 3
OBJECT_CONTYPE, OBJECT_CONAFFINITY = 1, 1
PAD_CONTYPE, PAD_CONAFFINITY = 2, 0
ARM_CONTYPES = {'left/': 4, 'right/': 8}


@dataclass(frozen=True)
class ArmIndex:
    """Addresses of one arm in the compiled model (7-element int arrays and ids)."""

    qpos: np.ndarray
    dof: np.ndarray
    actuators: np.ndarray
    tool_site: int
    flange_site: int
    sensor_site: int
    pad_geom: int
    force_sensor: slice
    torque_sensor: slice


@dataclass(frozen=True)
class SceneIndex:
    """Addresses of the arms and of the object (free joint, body, geom) in the model."""

    arms: dict
    object_body: int
    object_geom: int
    object_qpos: int
    object_dof: int


def _wxyz(rotation):
    x, y, z, w = matrix_to_quat_xyzw(rotation)
    return [w, x, y, z]


class _UrdfArm:
    """The parts of an URDF the scene needs: links, joints and the tree between them."""

    def __init__(self, path):
        try:
            root = ElementTree.parse(path).getroot()
        except (ElementTree.ParseError, OSError) as error:
            raise ConfigError(f'{path}: cannot read URDF: {error}') from None
        self.path = path
        self.links = {link.get('name'): link for link in root.iter('link')}
        self.joints = list(root.iter('joint'))
        self.children = {}
        child_links = set()
        for joint in self.joints:
            parent = joint.find('parent').get('link')
            child = joint.find('child').get('link')
            self.children.setdefault(parent, []).append(joint)
            child_links.add(child)
        roots = [name for name in self.links if name not in child_links]
        if len(roots) != 1:
            raise ConfigError(f'{path}: expected one root link, found {roots}')
        self.root = roots[0]

    def mass(self, link_name):
        inertial = self.links[link_name].find('inertial')
        if inertial is None:
            return 0.0
        return float(inertial.find('mass').get('value'))


def _add_inertial(body, link):
    inertial = link.find('inertial')
    position, rotation = urdf_origin(inertial)
    element = inertial.find('inertia')
    values = {key: float(element.get(key, '0')) for key in
              ('ixx', 'iyy', 'izz', 'ixy', 'ixz', 'iyz')}
    tensor = np.array([[values['ixx'], values['ixy'], values['ixz']],
                       [values['ixy'], values['iyy'], values['iyz']],
                       [values['ixz'], values['iyz'], values['izz']]])
    tensor = rotation @ tensor @ rotation.T
    body.explicitinertial = True
    body.mass = float(inertial.find('mass').get('value'))
    body.ipos = position
    body.iquat = [1.0, 0.0, 0.0, 0.0]
    body.fullinertia = [tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2],
                        tensor[1, 2]]


def _add_geoms(body, link, prefix, p_body_link, R_body_link):
    for index, collision in enumerate(link.findall('collision')):
        position, rotation = urdf_origin(collision)
        geometry = collision.find('geometry')
        shape = geometry[0]
        name = collision.get('name') or f'{link.get("name")}_{index}'
        geom = body.add_geom(name=prefix + name)
        geom.pos = p_body_link + R_body_link @ position
        geom.quat = _wxyz(R_body_link @ rotation)
        if shape.tag == 'box':
            geom.type = mujoco.mjtGeom.mjGEOM_BOX
            geom.size = 0.5 * urdf_vector(shape.get('size'))
        elif shape.tag == 'cylinder':
            geom.type = mujoco.mjtGeom.mjGEOM_CYLINDER
            geom.size = [float(shape.get('radius')), 0.5 * float(shape.get('length')), 0.0]
        elif shape.tag == 'sphere':
            geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
            geom.size = [float(shape.get('radius')), 0.0, 0.0]
        else:
            raise ConfigError(f'unsupported URDF collision shape {shape.tag!r} in link '
                              f'{link.get("name")}')
        geom.mass = 0.0
        if name == PAD_GEOM:
            geom.contype, geom.conaffinity = PAD_CONTYPE, PAD_CONAFFINITY
            geom.rgba = [0.2, 0.2, 0.2, 1.0]
        else:
            geom.contype = ARM_CONTYPES[prefix]
            geom.conaffinity = SCENE_CONTYPE | sum(
                bit for other, bit in ARM_CONTYPES.items() if other != prefix)
            geom.friction = [SCENE_FRICTION, 0.005, 0.0001]
            geom.solref = CONTACT_SOLREF
            geom.solimp = CONTACT_SOLIMP
            geom.group = 1
            geom.rgba = [1.0, 0.5, 0.1, 0.6]


def _add_link(spec, urdf, link_name, body, prefix, p_body_link, R_body_link, drives):
    """Add link_name (rigidly at p/R in body) and its subtree below body."""
    link = urdf.links[link_name]
    site = body.add_site(name=prefix + link_name, pos=p_body_link, quat=_wxyz(R_body_link))
    site.group = 3
    _add_geoms(body, link, prefix, p_body_link, R_body_link)
    for joint in urdf.children.get(link_name, []):
        child = joint.find('child').get('link')
        position, rotation = urdf_origin(joint)
        p_body_child = p_body_link + R_body_link @ position
        R_body_child = R_body_link @ rotation
        kind = joint.get('type')
        if kind == 'revolute':
            child_body = body.add_body(name=prefix + child, pos=p_body_child,
                                       quat=_wxyz(R_body_child))
            _add_inertial(child_body, urdf.links[child])
            _add_revolute(spec, child_body, joint, prefix, drives)
            _add_link(spec, urdf, child, child_body, prefix, np.zeros(3), np.eye(3), drives)
        elif kind == 'fixed' and urdf.mass(child) > 0.0:
            child_body = body.add_body(name=prefix + child, pos=p_body_child,
                                       quat=_wxyz(R_body_child))
            _add_inertial(child_body, urdf.links[child])
            _add_link(spec, urdf, child, child_body, prefix, np.zeros(3), np.eye(3), drives)
        elif kind == 'fixed':
            _add_link(spec, urdf, child, body, prefix, p_body_child, R_body_child, drives)
        else:
            raise ConfigError(f'{urdf.path}: joint {joint.get("name")} has unsupported type '
                              f'{kind!r}')


def _add_revolute(spec, body, joint, prefix, drives):
    name = joint.get('name')
    index = drives['names'].index(name)
    limit = joint.find('limit')
    hinge = body.add_joint(name=prefix + name, type=mujoco.mjtJoint.mjJNT_HINGE,
                           axis=urdf_vector(joint.find('axis').get('xyz')))
    hinge.range = [float(limit.get('lower')), float(limit.get('upper'))]
    hinge.limited = mujoco.mjtLimited.mjLIMITED_TRUE
    hinge.armature = float(drives['armature'][index])
    hinge.damping = [float(drives['damping'][index]), 0.0, 0.0]  # linear term only
    effort = float(limit.get('effort'))
    actuator = spec.add_actuator(name=prefix + name, target=prefix + name,
                                 trntype=mujoco.mjtTrn.mjTRN_JOINT)
    actuator.set_to_motor()
    actuator.ctrlrange = [-effort, effort]
    actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE


def add_arm(spec, description, prefix):
    """Add one arm (ArmDescription) under prefix, e.g. 'left/', welded at its base pose."""
    urdf = _UrdfArm(description.urdf)
    revolute = [joint.get('name') for joint in urdf.joints if joint.get('type') == 'revolute']
    drives = {'names': revolute, 'armature': description.armature,
              'damping': description.damping}
    if len(revolute) != len(description.armature):
        raise ConfigError(f'{urdf.path}: {len(revolute)} revolute joints, but cell armature has '
                          f'{len(description.armature)} entries')
    base = spec.worldbody.add_body(name=prefix + urdf.root, pos=description.base_position,
                                   quat=_wxyz(description.R_world_base))
    if urdf.mass(urdf.root) > 0.0:
        _add_inertial(base, urdf.links[urdf.root])
    _add_link(spec, urdf, urdf.root, base, prefix, np.zeros(3), np.eye(3), drives)
    sensor_children = [joint.find('child').get('link') for joint in urdf.children[SENSOR_SITE]]
    carried = spec.body(prefix + sensor_children[0])
    if len(sensor_children) != 1 or carried is None:
        raise ConfigError(f'{urdf.path}: the {SENSOR_SITE} frame needs exactly one child link '
                          f'with mass (the grabber), found {sensor_children}')
    ft_site = carried.add_site(name=prefix + FT_SITE)
    ft_site.group = 3
    spec.add_sensor(name=prefix + 'force', type=mujoco.mjtSensor.mjSENS_FORCE,
                    objtype=mujoco.mjtObj.mjOBJ_SITE, objname=prefix + FT_SITE)
    spec.add_sensor(name=prefix + 'torque', type=mujoco.mjtSensor.mjSENS_TORQUE,
                    objtype=mujoco.mjtObj.mjOBJ_SITE, objname=prefix + FT_SITE)


def _add_block(spec, name, block):
    geom = spec.worldbody.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX,
                                   pos=block.center, size=0.5 * block.size)
    scene_contact(geom)
    geom.rgba = [0.6, 0.5, 0.4, 1.0]


def scene_contact(geom):
    geom.contype, geom.conaffinity = SCENE_CONTYPE, SCENE_CONAFFINITY
    geom.friction = [SCENE_FRICTION, 0.005, 0.0001]
    geom.solref = CONTACT_SOLREF
    geom.solimp = CONTACT_SOLIMP


def add_object(spec, object_config):
    """Add the scenario's box as a free body at its initial pose (centre = body origin)."""
    body = spec.worldbody.add_body(name=OBJECT_BODY, pos=object_config.position)
    yaw = float(object_config.yaw)
    body.quat = [np.cos(0.5 * yaw), 0.0, 0.0, np.sin(0.5 * yaw)]
    body.add_freejoint(name=OBJECT_BODY)
    size = np.asarray(object_config.size, dtype=float)
    mass = float(object_config.mass)
    body.explicitinertial = True
    body.mass = mass
    body.ipos = [0.0, 0.0, 0.0]
    body.inertia = mass / 12.0 * (np.sum(size ** 2) - size ** 2)
    geom = body.add_geom(name=OBJECT_BODY, type=mujoco.mjtGeom.mjGEOM_BOX, size=0.5 * size)
    geom.mass = 0.0
    geom.contype, geom.conaffinity = OBJECT_CONTYPE, OBJECT_CONAFFINITY
    geom.friction = [SCENE_FRICTION, 0.005, 0.0001]
    geom.solref = CONTACT_SOLREF
    geom.solimp = CONTACT_SOLIMP
    geom.rgba = [0.8, 0.7, 0.5, 1.0]
    return body


def build_spec(cell, object_config):
    """Return the MjSpec of the cell: both arms, pads, FT sensors, object, pallet, table."""
    spec = mujoco.MjSpec()
    spec.modelname = 'dual_arm_cell'
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    spec.compiler.balanceinertia = False
    spec.compiler.fusestatic = False
    spec.compiler.autolimits = True
    spec.compiler.degree = False
    spec.option.timestep = PHYSICS_TIMESTEP
    spec.option.gravity = GRAVITY
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = 10.0
    floor = spec.worldbody.add_geom(name='floor', type=mujoco.mjtGeom.mjGEOM_PLANE,
                                    pos=[0.0, 0.0, cell.floor_height], size=[3.0, 3.0, 0.1])
    scene_contact(floor)
    floor.rgba = [0.3, 0.3, 0.35, 1.0]
    _add_block(spec, 'pallet', cell.pallet)
    _add_block(spec, 'front_table', cell.front_table)
    for arm in ARMS:
        add_arm(spec, cell.arm(arm), f'{arm}/')
    add_object(spec, object_config)
    for arm in ARMS:
        pair = spec.add_pair(name=f'{arm}/pad_object', geomname1=f'{arm}/{PAD_GEOM}',
                             geomname2=OBJECT_BODY)
        pair.condim = PAD_CONDIM
        friction = float(object_config.friction)
        half_length, half_width, _ = spec.geom(f'{arm}/{PAD_GEOM}').size
        pair.friction = [friction, friction, friction * pad_torsion_arm(half_length, half_width),
                         PAD_ROLLING_FRICTION, PAD_ROLLING_FRICTION]
        pair.solref = CONTACT_SOLREF
        pair.solimp = CONTACT_SOLIMP
    return spec


def pad_torsion_arm(half_length, half_width):
    """
    Return the mean distance [m] of a rectangular pad's points from its centre.

    Pressed flush with uniform pressure p, a pad of half sides a, b twisting on a face resists
    with mu p times the integral of r over the patch, that is mu N times this mean distance:
    (2 a b d + a^3 ln((b + d) / a) + b^3 ln((a + d) / b)) / (6 a b), d = sqrt(a^2 + b^2).
    """
    a, b = float(half_length), float(half_width)
    d = math.hypot(a, b)
    return (2.0 * a * b * d + a ** 3 * math.log((b + d) / a)
            + b ** 3 * math.log((a + d) / b)) / (6.0 * a * b)


def build_model(cell, object_config):
    """Compile the cell into (mujoco.MjModel, SceneIndex)."""
    model = build_spec(cell, object_config).compile()
    return model, scene_index(model)


def scene_index(model):
    """Return the SceneIndex of a compiled cell model."""
    arms = {}
    for arm in ARMS:
        prefix = f'{arm}/'
        joint_ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f'{prefix}A{index}')
                     for index in range(1, 8)]
        actuator_ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR,
                                          f'{prefix}A{index}') for index in range(1, 8)]
        force_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, prefix + 'force')
        torque_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, prefix + 'torque')

        def site(name, prefix=prefix):
            return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, prefix + name)

        force_adr = model.sensor_adr[force_id]
        torque_adr = model.sensor_adr[torque_id]
        arms[arm] = ArmIndex(
            qpos=np.array([model.jnt_qposadr[j] for j in joint_ids]),
            dof=np.array([model.jnt_dofadr[j] for j in joint_ids]),
            actuators=np.array(actuator_ids),
            tool_site=site(TOOL_SITE), flange_site=site(FLANGE_SITE),
            sensor_site=site(SENSOR_SITE),
            pad_geom=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, prefix + PAD_GEOM),
            force_sensor=slice(force_adr, force_adr + 3),
            torque_sensor=slice(torque_adr, torque_adr + 3))
    object_joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, OBJECT_BODY)
    return SceneIndex(
        arms=arms,
        object_body=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, OBJECT_BODY),
        object_geom=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, OBJECT_BODY),
        object_qpos=int(model.jnt_qposadr[object_joint]),
        object_dof=int(model.jnt_dofadr[object_joint]))


def site_pose(data, site_id):
    """Return (p_world (3,), R_world (3, 3)) of a site in compiled data."""
    return data.site_xpos[site_id].copy(), data.site_xmat[site_id].reshape(3, 3).copy()


def quat_wxyz_to_xyzw(quat_wxyz):
    """Reorder a MuJoCo quaternion (w, x, y, z) to the project's (x, y, z, w)."""
    return np.array([quat_wxyz[1], quat_wxyz[2], quat_wxyz[3], quat_wxyz[0]])


def quat_xyzw_to_wxyz(quat_xyzw):
    """Reorder a project quaternion (x, y, z, w) to MuJoCo's (w, x, y, z)."""
    return np.array([quat_xyzw[3], quat_xyzw[0], quat_xyzw[1], quat_xyzw[2]])
