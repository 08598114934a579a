"""
The cell's coordinate frames for TF, from its URDF, the joint positions, the object and the task.

Like robot_state_publisher: each URDF joint is one parent -> child transform; fixed joints are
static, a revolute joint's transform is its origin times the rotation about its axis by the
joint position. The object frame follows the object pose; the task's target frames (planned
release, predicted landing, place target) are static, from the scenario. Transforms are
(parent, child, translation (3,) [m], quaternion (x, y, z, w)).
"""

from dataclasses import dataclass
import xml.etree.ElementTree as ElementTree

from dual_arm_control.core.arms import ARMS, joint_names
from dual_arm_control.core.exceptions import ConfigError, InputError
from dual_arm_control.core.geometry import matrix_to_quat_xyzw, rotation_exp
from dual_arm_control.description.cell_urdf import urdf_origin, urdf_vector, WORLD_LINK
from dual_arm_control.runtime.configuration import planned_landing, planned_release
from dual_arm_control.scenario import PLACE_TASKS, TOSS_TASKS
import numpy as np

OBJECT_FRAME = 'object'
RELEASE_FRAME = 'release_target'
LANDING_FRAME = 'landing_target'
PLACE_FRAME = 'place_target'
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


@dataclass(frozen=True)
class FrameTransform:
    """Pose of child in parent: translation (3,) [m] and rotation quaternion (x, y, z, w)."""

    parent: str
    child: str
    translation: np.ndarray
    rotation: np.ndarray


@dataclass(frozen=True)
class _Revolute:
    parent: str
    child: str
    translation: np.ndarray
    R_parent_origin: np.ndarray
    axis: np.ndarray


class CellFrames:
    """The cell's joint tree, read once from its URDF text; transforms on request."""

    def __init__(self, urdf_text):
        try:
            robot = ElementTree.fromstring(urdf_text)
        except ElementTree.ParseError as error:
            raise ConfigError(f'cannot read the cell URDF: {error}') from None
        self.links = tuple(link.get('name') for link in robot.iter('link'))
        static, revolute = [], {}
        for joint in robot.iter('joint'):
            translation, rotation = urdf_origin(joint)
            parent = joint.find('parent').get('link')
            child = joint.find('child').get('link')
            kind = joint.get('type')
            if kind == 'fixed':
                static.append(FrameTransform(parent, child, translation,
                                             matrix_to_quat_xyzw(rotation)))
            elif kind == 'revolute':
                axis = urdf_vector(joint.find('axis').get('xyz'))
                revolute[joint.get('name')] = _Revolute(parent, child, translation, rotation,
                                                        axis / np.linalg.norm(axis))
            else:
                raise ConfigError(f'cell URDF: joint {joint.get("name")} has unsupported type '
                                  f'{kind!r}')
        self.static_transforms = tuple(static)
        self._revolute = revolute
        for arm in ARMS:
            missing = set(joint_names(arm)) - set(revolute)
            if missing:
                raise ConfigError(f'cell URDF: joints {sorted(missing)} of arm {arm} missing')

    def arm_transforms(self, arm, positions):
        """Return the transforms of an arm's seven joints at positions (7,) [rad]."""
        transforms = []
        for name, angle in zip(joint_names(arm), positions):
            joint = self._revolute[name]
            rotation = joint.R_parent_origin @ rotation_exp(joint.axis * float(angle))
            transforms.append(FrameTransform(joint.parent, joint.child, joint.translation,
                                             matrix_to_quat_xyzw(rotation)))
        return transforms


def object_transform(position, quat_xyzw):
    """Return the transform world -> object of an object pose."""
    return FrameTransform(WORLD_LINK, OBJECT_FRAME, np.asarray(position, dtype=float),
                          np.asarray(quat_xyzw, dtype=float))


def target_transforms(scenario, cell):
    """
    Return the static target frames of a scenario's task, in the world.

    Toss tasks: the planned release point of the box centre and where the drag-free flight
    from it lands the centre on the surface below (half a box above it); place tasks: the place
    target. The motion generator starts from the same targets (live tuning may move them).
    """
    transforms = []
    release = planned_release(scenario, cell) if scenario.task in TOSS_TASKS else None
    if release is not None:
        transforms.append(FrameTransform(WORLD_LINK, RELEASE_FRAME, release[0], IDENTITY))
        try:
            landing = planned_landing(scenario, cell)
        except InputError:
            landing = None
        if landing is not None:
            transforms.append(FrameTransform(WORLD_LINK, LANDING_FRAME, landing, IDENTITY))
    if scenario.task in PLACE_TASKS and scenario.place is not None:
        transforms.append(FrameTransform(WORLD_LINK, PLACE_FRAME,
                                         np.asarray(scenario.place, dtype=float), IDENTITY))
    return transforms


class UpdateSchedule:
    """Which stamped inputs go out on /tf: at most one per period [ns] of sim time per source."""

    def __init__(self, period_ns):
        self.period_ns = int(period_ns)
        self._last = {}

    def due(self, source, stamp_ns):
        """Return True (and note it) if source's input at stamp_ns is due; a reset restarts it."""
        last = self._last.get(source)
        if last is not None and last <= stamp_ns < last + self.period_ns:
            return False
        self._last[source] = stamp_ns
        return True
