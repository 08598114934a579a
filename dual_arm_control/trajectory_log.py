"""
Ground-truth trajectory of an episode: what the simulator really did, one row per FRI cycle.

Written by the bridge (or any runner stepping the twin) and read by the metrics; it lives outside
evaluation/ so the bridge writes it without depending on the evaluation layer. Stored as a
compressed .npz; keys are documented in ARM_FIELDS, OBJECT_FIELDS and COUNTER_FIELDS.
"""

from pathlib import Path

from dual_arm_control.contract import ARMS
from dual_arm_control.core.exceptions import ConfigError
import numpy as np

# name -> (per-sample shape, meaning). Per-arm fields are stored as '<arm>_<name>'.
ARM_FIELDS = {
    'q': ((7,), 'joint positions [rad]'),
    'dq': ((7,), 'joint velocities [rad/s]'),
    'tau': ((7,), 'applied joint torques after clamping [N m]'),
    'tool_position': ((3,), 'tool-centre position in world [m]'),
    'tool_velocity': ((3,), 'tool-centre linear velocity in world [m/s]'),
    'pad_force': ((3,), 'force the pad exerts on the object, world [N]'),
    'pad_contact': ((), 'pad touches the object [bool]'),
}
OBJECT_FIELDS = {
    'object_position': ((3,), 'object centre in world [m]'),
    'object_quat_xyzw': ((4,), 'object orientation (x, y, z, w)'),
    'object_velocity': ((3,), 'object linear velocity in world [m/s]'),
    'object_angular_velocity': ((3,), 'object angular velocity in world [rad/s]'),
}
# The container of a scenario with a conveyor (optional in a log: absent without one).
CONTAINER_FIELDS = {
    'container_position': ((3,), 'centre of the container floor in world [m]'),
    'container_velocity': ((3,), 'container linear velocity in world [m/s]'),
}
COUNTER_FIELDS = ('torque_clamp_count', 'refused_message_count', 'watchdog_hold_count')
# The arm collisions of the episode (optional in a log: older logs lack them).
COLLISION_FIELDS = {
    'arm_collision_times': ((), 'sim time each arm collision began [s]'),
    'arm_collision_geoms': ((2,), 'the two MuJoCo geoms of each arm collision [str]'),
}


class TrajectoryRecorder:
    """Collect one row per cycle from a DualArmTwin and save it as a trajectory .npz."""

    def __init__(self):
        self._rows = {'t': []}
        for arm in ARMS:
            for name in ARM_FIELDS:
                self._rows[f'{arm}_{name}'] = []
        for name in (*OBJECT_FIELDS, *CONTAINER_FIELDS):
            self._rows[name] = []
        self.counters = dict.fromkeys(COUNTER_FIELDS, 0)
        self._twin = None

    def __len__(self):
        return len(self._rows['t'])

    def append(self, twin, applied_torques):
        """Append the twin's current ground truth; applied_torques = {arm: (7,)} last applied."""
        self._rows['t'].append(twin.time)
        self._twin = twin
        for arm in ARMS:
            joints = twin.joint_state(arm)
            tool_position, _ = twin.tool_pose(arm)
            tool_velocity, _ = twin.tool_twist(arm)
            pad_force, in_contact = twin.pad_contact(arm)
            values = {'q': joints.position, 'dq': joints.velocity, 'tau': applied_torques[arm],
                      'tool_position': tool_position, 'tool_velocity': tool_velocity,
                      'pad_force': pad_force, 'pad_contact': bool(in_contact)}
            for name, value in values.items():
                self._rows[f'{arm}_{name}'].append(np.array(value, dtype=float, copy=True))
        object_position, object_quat = twin.object_pose()
        object_velocity, object_angular_velocity = twin.object_twist()
        for name, value in (('object_position', object_position),
                            ('object_quat_xyzw', object_quat),
                            ('object_velocity', object_velocity),
                            ('object_angular_velocity', object_angular_velocity)):
            self._rows[name].append(np.array(value, dtype=float, copy=True))
        container = getattr(twin, 'container', None)
        if container is not None:
            for name, value in zip(CONTAINER_FIELDS, container.pose(twin.data)):
                self._rows[name].append(value)

    def arrays(self):
        """Return the log as a dict of NumPy arrays, first axis = sample."""
        data = {name: np.array(rows) for name, rows in self._rows.items()
                if rows or name not in CONTAINER_FIELDS}
        for arm in ARMS:
            data[f'{arm}_pad_contact'] = data[f'{arm}_pad_contact'].astype(bool)
        for name, value in self.counters.items():
            data[name] = np.array(value)
        collisions = () if self._twin is None else self._twin.arm_collisions
        data['arm_collision_times'] = np.array([item.time for item in collisions],
                                               dtype=float)
        data['arm_collision_geoms'] = np.array([item.geoms for item in collisions],
                                               dtype=str).reshape(-1, 2)
        return data

    def save(self, path):
        """Write the log to path (.npz, compressed)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, **self.arrays())


def load_trajectory(path):
    """Load a trajectory .npz into a dict of arrays; raise ConfigError naming a missing key."""
    path = Path(path)
    try:
        with np.load(path) as archive:
            data = {name: archive[name] for name in archive.files}
    except (OSError, ValueError) as error:
        raise ConfigError(f'{path}: cannot read trajectory log ({error})') from None
    required = ['t'] + list(OBJECT_FIELDS) + [f'{arm}_{name}' for arm in ARMS
                                              for name in ARM_FIELDS]
    missing = [name for name in required if name not in data]
    if missing:
        raise ConfigError(f'{path}: trajectory log lacks {missing}')
    return data
