"""The cell configuration (config/cell.yaml) as frozen dataclasses, and per-arm models."""

from dataclasses import dataclass
from pathlib import Path

from dual_arm_control.core.arms import ARMS, joint_names
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.geometry import quat_xyzw_to_matrix
from dual_arm_control.core.robot_model import ArmModel, JOINTS_PER_ARM
from dual_arm_control.resources import config_path, load_yaml, require, urdf_path
import numpy as np


def _frozen(array):
    array = np.array(array, dtype=float)
    array.setflags(write=False)
    return array


@dataclass(frozen=True)
class ArmDescription:
    """
    Placement, drives and home posture of one arm.

    Fields: arm ('left' or 'right'); model (URDF name); urdf (path); base_position (3,) [m];
    base_orientation (4,) quaternion (x, y, z, w); armature (7,) [kg m^2]; damping (7,) viscous
    [N m s/rad]; hold_damping (7,) [N m s/rad] and hold_stiffness (7,) [N m/rad] of the safety
    hold; q_home (7,) [rad];
    standby_position (3,) [m] and R_world_standby (3, 3): the tool pose q_home reaches.
    """

    arm: str
    model: str
    urdf: Path
    base_position: np.ndarray
    base_orientation: np.ndarray
    armature: np.ndarray
    damping: np.ndarray
    hold_damping: np.ndarray
    hold_stiffness: np.ndarray
    q_home: np.ndarray
    standby_position: np.ndarray
    R_world_standby: np.ndarray

    @property
    def R_world_base(self):
        """Rotation of the arm base in the world frame, (3, 3)."""
        return quat_xyzw_to_matrix(self.base_orientation)

    @property
    def joint_names(self):
        """Joint names of this arm in messages ('left_A1', ...)."""
        return joint_names(self.arm)


@dataclass(frozen=True)
class Block:
    """An axis-aligned solid block resting on the floor: centre (3,) and size (3,) [m]."""

    center: np.ndarray
    size: np.ndarray

    @property
    def top_height(self):
        """World z of the top face [m]."""
        return float(self.center[2] + 0.5 * self.size[2])

    def top_face(self):
        """Return ((x_min, x_max), (y_min, y_max), top height) [m] of the top face."""
        half = 0.5 * self.size
        return ((float(self.center[0] - half[0]), float(self.center[0] + half[0])),
                (float(self.center[1] - half[1]), float(self.center[1] + half[1])),
                self.top_height)

    def covers(self, x, y):
        """Return True if the world point (x, y) [m] lies over the block's top face."""
        (x_min, x_max), (y_min, y_max), _ = self.top_face()
        return bool(x_min <= x <= x_max and y_min <= y <= y_max)


@dataclass(frozen=True)
class CellDescription:
    """The whole cell: arms by name, the pallet, the front (landing) table and the floor."""

    arms: dict
    pallet: Block
    front_table: Block
    floor_height: float
    path: Path

    def arm(self, name):
        """Return the ArmDescription of 'left' or 'right'."""
        if name not in self.arms:
            raise ConfigError(f'unknown arm {name!r}; expected one of {ARMS}')
        return self.arms[name]

    def surface_height(self, x, y):
        """Return the world z [m] of the highest static surface under the point (x, y)."""
        heights = [block.top_height for block in (self.pallet, self.front_table)
                   if block.covers(x, y)]
        return max(heights, default=self.floor_height)


def _numbers(mapping, key, path, context, size, unit, positive=False):
    value = require(mapping, key, path, list, context)
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f'{path}: key {context}.{key!r} must be {size} numbers [{unit}], '
                          f'got {value!r}') from None
    if array.shape != (size,) or not np.all(np.isfinite(array)):
        raise ConfigError(f'{path}: key {context}.{key!r} must be {size} finite numbers '
                          f'[{unit}], got {value!r}')
    if positive and np.any(array < 0.0):
        raise ConfigError(f'{path}: key {context}.{key!r} must be >= 0 [{unit}], got {value!r}')
    return array


def _arm_description(arm, entry, path):
    context = f'arms.{arm}'
    model = require(entry, 'model', path, str, context)
    try:
        urdf = urdf_path(model)
    except ConfigError as error:
        raise ConfigError(f'{path}: key {context}.model: {error}') from None
    orientation = _numbers(entry, 'base_orientation', path, context, 4, 'quaternion x y z w')
    if abs(np.linalg.norm(orientation) - 1.0) > 1e-6:
        raise ConfigError(f'{path}: key {context}.base_orientation must be a unit quaternion, '
                          f'got {orientation.tolist()}')
    tool_z = _numbers(entry, 'standby_tool_z', path, context, 3, '-')
    tool_x = _numbers(entry, 'standby_tool_x', path, context, 3, '-')
    if abs(np.linalg.norm(tool_z) - 1.0) > 1e-6 or abs(np.linalg.norm(tool_x) - 1.0) > 1e-6 \
            or abs(tool_z @ tool_x) > 1e-6:
        raise ConfigError(f'{path}: keys {context}.standby_tool_x and standby_tool_z must be '
                          f'orthogonal unit vectors, got {tool_x.tolist()}, {tool_z.tolist()}')
    return ArmDescription(
        arm=arm, model=model, urdf=urdf,
        base_position=_frozen(_numbers(entry, 'base_position', path, context, 3, 'm')),
        base_orientation=_frozen(orientation),
        armature=_frozen(_numbers(entry, 'armature', path, context, JOINTS_PER_ARM,
                                  'kg m^2', positive=True)),
        damping=_frozen(_numbers(entry, 'damping', path, context, JOINTS_PER_ARM,
                                 'N m s/rad', positive=True)),
        hold_damping=_frozen(_numbers(entry, 'hold_damping', path, context, JOINTS_PER_ARM,
                                      'N m s/rad', positive=True)),
        hold_stiffness=_frozen(_numbers(entry, 'hold_stiffness', path, context, JOINTS_PER_ARM,
                                        'N m/rad', positive=True)),
        q_home=_frozen(_numbers(entry, 'q_home', path, context, JOINTS_PER_ARM, 'rad')),
        standby_position=_frozen(_numbers(entry, 'standby_position', path, context, 3, 'm')),
        R_world_standby=_frozen(np.column_stack((tool_x, np.cross(tool_z, tool_x), tool_z))))


def _number(mapping, key, path, context, unit):
    value = require(mapping, key, path, (int, float), context)
    if not np.isfinite(value):
        raise ConfigError(f'{path}: key {context}.{key!r} must be finite [{unit}]')
    return float(value)


def load_cell(path=None):
    """Load config/cell.yaml (or path) into a CellDescription; errors name the file and key."""
    path = Path(path) if path is not None else config_path('cell.yaml')
    data = load_yaml(path)
    arms_entry = require(data, 'arms', path, dict)
    arms = {arm: _arm_description(arm, require(arms_entry, arm, path, dict, 'arms'), path)
            for arm in ARMS}
    scene = require(data, 'scene', path, dict)
    floor = _number(scene, 'floor_height', path, 'scene', 'm')
    pallet = require(scene, 'pallet', path, dict, 'scene')
    center = _numbers(pallet, 'center', path, 'scene.pallet', 2, 'm')
    size = _numbers(pallet, 'size', path, 'scene.pallet', 2, 'm', positive=True)
    top = _number(pallet, 'top_height', path, 'scene.pallet', 'm')
    table = require(scene, 'front_table', path, dict, 'scene')
    x_range = _numbers(table, 'x_range', path, 'scene.front_table', 2, 'm')
    y_range = _numbers(table, 'y_range', path, 'scene.front_table', 2, 'm')
    table_top = _number(table, 'top_height', path, 'scene.front_table', 'm')
    for key, low, high in (('scene.pallet.top_height', floor, top),
                           ('scene.front_table.top_height', floor, table_top),
                           ('scene.front_table.x_range', *x_range),
                           ('scene.front_table.y_range', *y_range)):
        if not high > low:
            raise ConfigError(f'{path}: key {key!r}: need a positive extent, got {low}..{high}')
    return CellDescription(
        arms=arms,
        pallet=Block(_frozen([center[0], center[1], 0.5 * (floor + top)]),
                     _frozen([size[0], size[1], top - floor])),
        front_table=Block(_frozen([x_range.mean(), y_range.mean(), 0.5 * (floor + table_top)]),
                          _frozen([np.ptp(x_range), np.ptp(y_range), table_top - floor])),
        floor_height=floor, path=path)


def arm_model(arm, cell=None):
    """Return the pinocchio ArmModel of an arm placed and parameterised as in the cell."""
    description = (cell or load_cell()).arm(arm)
    return ArmModel(description.urdf, description.joint_names,
                    base_position=description.base_position,
                    R_world_base=description.R_world_base, armature=description.armature,
                    damping=description.damping)
