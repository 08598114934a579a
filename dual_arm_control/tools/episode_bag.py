"""
Episode bags for dual_arm_render: the joint, object and phase signals of a recorded episode.

read_episode reads an MCAP bag (split files included) into an EpisodeRecord: joint states of
both arms, the object pose (ground truth, else the tracker's estimate), the phase and the
scenario the bag names. EpisodeRecord.state_at interpolates them linearly at any sim time.
"""

from dataclasses import dataclass, field

from dual_arm_control import contract
from dual_arm_control.bags import BagError
from dual_arm_control.bags.reader import BagReader
from dual_arm_control.bags.writer import METADATA_NAME
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.nodes.bag_record import message_class
import numpy as np
from rclpy.serialization import deserialize_message

PARAMETER_EVENTS_TOPIC = '/parameter_events'
SCENARIO_PARAMETER = 'scenario'
# A phase stamped within this of a frame's time is shown in that frame [s].
_TIME_EPSILON = 1e-9


@dataclass(frozen=True)
class EpisodeRecord:
    """
    Time-indexed signals of a recorded episode; times are sim seconds (message header stamps).

    joint_time {arm: (N,)}; joint_position and joint_velocity {arm: (N, 7)} [rad], [rad/s]
    in URDF order A1..A7; object_time (M,); object_position (M, 3) [m]; object_quat_xyzw
    (M, 4); object_velocity (M, 3) [m/s], world frame; object_source: the topic the object
    came from (None: no object pose in the bag); phase_time (K,) and phase (K,) names;
    scenario: scenario file recorded in the bag, or None.
    """

    joint_time: dict
    joint_position: dict
    joint_velocity: dict
    object_time: np.ndarray = field(default_factory=lambda: np.zeros(0))
    object_position: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    object_quat_xyzw: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    object_velocity: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    object_source: str = None
    phase_time: np.ndarray = field(default_factory=lambda: np.zeros(0))
    phase: tuple = ()
    scenario: str = None

    @property
    def start(self):
        """First sim time at which both arms have a joint sample [s]."""
        return max(float(times[0]) for times in self.joint_time.values())

    @property
    def end(self):
        """Last sim time at which both arms have a joint sample [s]."""
        return min(float(times[-1]) for times in self.joint_time.values())

    def state_at(self, t):
        """Return the FrameState at sim time t [s], interpolated between samples."""
        q = {arm: _interpolate(self.joint_time[arm], self.joint_position[arm], t)
             for arm in self.joint_time}
        qd = {arm: _interpolate(self.joint_time[arm], self.joint_velocity[arm], t)
              for arm in self.joint_time}
        if self.object_source is None:
            position = quat = object_speed = None
        else:
            position = _interpolate(self.object_time, self.object_position, t)
            quat = _interpolate_quaternion(self.object_time, self.object_quat_xyzw, t)
            object_speed = float(np.linalg.norm(
                _interpolate(self.object_time, self.object_velocity, t)))
        index = int(np.searchsorted(self.phase_time, t + _TIME_EPSILON, side='right')) - 1
        phase = self.phase[index] if index >= 0 else None
        return FrameState(t, q, qd, position, quat, object_speed, phase)


@dataclass(frozen=True)
class FrameState:
    """What one frame shows: sim time [s], joints, object pose (None: scenario pose), phase."""

    t: float
    q: dict
    qd: dict
    object_position: np.ndarray = None
    object_quat_xyzw: np.ndarray = None
    object_speed: float = None
    phase: str = None


def _interpolate(times, values, t):
    """Return values (N, k) linearly interpolated at t, held beyond the first and last sample."""
    index = int(np.searchsorted(times, t, side='right'))
    if index == 0:
        return values[0].copy()
    if index == len(times):
        return values[-1].copy()
    t0, t1 = times[index - 1], times[index]
    weight = (t - t0) / (t1 - t0) if t1 > t0 else 0.0
    return values[index - 1] + weight * (values[index] - values[index - 1])


def _interpolate_quaternion(times, quats, t):
    """Return the normalised linear interpolation of unit quaternions (N, 4) at t."""
    index = int(np.searchsorted(times, t, side='right'))
    if index == 0 or index == len(times):
        quat = quats[0 if index == 0 else -1]
        return quat / np.linalg.norm(quat)
    q0, q1 = quats[index - 1], quats[index]
    if np.dot(q0, q1) < 0.0:
        q1 = -q1
    t0, t1 = times[index - 1], times[index]
    weight = (t - t0) / (t1 - t0) if t1 > t0 else 0.0
    quat = q0 + weight * (q1 - q0)
    return quat / np.linalg.norm(quat)


def _stamp(msg):
    """Return the header stamp of a message [s]."""
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def _read_bag(path, topics):
    """
    Return ([(topic, message, log_time_ns)], scenario or None) of a bag (bags/reader.py).

    The scenario is the one its METADATA_NAME record names. InputError if it cannot be read.
    """
    try:
        reader = BagReader(path)
        recorded = reader.metadata(METADATA_NAME) or {}
        return list(decoded_messages(reader, topics)), recorded.get('scenario') or None
    except (BagError, ValueError, EOFError) as error:
        raise InputError(f'bag {path} cannot be read: {error}') from None


def decoded_messages(reader, topics):
    """Yield (topic, message, log_time_ns) of a BagReader's topics, in log-time order."""
    classes = {}
    for message in reader.messages(topics):
        if message.type_name not in classes:
            classes[message.type_name] = message_class(message.type_name)
        yield (message.topic, deserialize_message(message.data, classes[message.type_name]),
               message.log_time)


def _scenario_from_parameter_event(msg):
    """Return the scenario a ParameterEvent sets (new or changed), or None."""
    for parameter in list(msg.new_parameters) + list(msg.changed_parameters):
        if parameter.name == SCENARIO_PARAMETER and parameter.value.string_value:
            return parameter.value.string_value
    return None


def read_episode(path):
    """
    Read an episode's joint states, object pose, phase and scenario from an MCAP bag.

    Joint states from /<arm>/joint_states (required); the object from the ground-truth topic,
    else the tracker's /object/state; the phase from /dual_arm/phase. Split bags
    (<stem>_1.mcap, ...) are read as one. Returns an EpisodeRecord. Raises InputError naming
    the file and the problem (missing file, unreadable bag, no joint states of an arm).
    """
    joint_topics = {contract.JOINT_STATES.resolved(arm): arm for arm in contract.ARMS}
    object_topics = (contract.GROUND_TRUTH_OBJECT.name, contract.OBJECT_STATE.name)
    topics = (list(joint_topics) + list(object_topics)
              + [contract.PHASE.name, PARAMETER_EVENTS_TOPIC])
    joints = {arm: [] for arm in contract.ARMS}
    objects = {topic: [] for topic in object_topics}
    phases = []
    scenario_parameter = None
    messages, recorded_scenario = _read_bag(path, topics)
    for topic, msg, log_time in messages:
        if topic in joint_topics:
            arm = joint_topics[topic]
            joints[arm].append(_joint_sample(topic, msg, arm, log_time))
        elif topic in objects:
            pose, twist = msg.pose.pose, msg.twist.twist
            quat = (pose.orientation.x, pose.orientation.y, pose.orientation.z,
                    pose.orientation.w)
            if np.linalg.norm(quat) < 0.5:
                continue  # no estimate yet (a zero quaternion)
            objects[topic].append((_stamp(msg), log_time,
                                   (pose.position.x, pose.position.y, pose.position.z),
                                   quat, (twist.linear.x, twist.linear.y, twist.linear.z)))
        elif topic == contract.PHASE.name:
            for status in msg.status:
                if status.name == contract.PHASE_STATUS_NAME:
                    phases.append((_stamp(msg), log_time, status.message))
        elif topic == PARAMETER_EVENTS_TOPIC:
            scenario_parameter = _scenario_from_parameter_event(msg) or scenario_parameter
    for arm, samples in joints.items():
        if not samples:
            raise InputError(f'bag {path} has no {contract.JOINT_STATES.resolved(arm)} '
                             'messages: nothing to render')
    use_log_time = all(sample[0] == joints[contract.ARMS[0]][0][0]
                       for samples in joints.values() for sample in samples)
    joint_time, joint_position, joint_velocity = {}, {}, {}
    for arm, samples in joints.items():
        times = _times(samples, use_log_time)
        order = np.argsort(times, kind='stable')
        joint_time[arm] = times[order]
        joint_position[arm] = np.array([sample[2] for sample in samples])[order]
        velocity = np.array([sample[3] for sample in samples])[order]
        if np.isnan(velocity).any():
            velocity = (np.gradient(joint_position[arm], joint_time[arm], axis=0)
                        if len(samples) > 1 and np.all(np.diff(joint_time[arm]) > 0.0)
                        else np.zeros_like(joint_position[arm]))
        joint_velocity[arm] = velocity
    record = {'joint_time': joint_time, 'joint_position': joint_position,
              'joint_velocity': joint_velocity,
              'scenario': recorded_scenario or scenario_parameter}
    source = next((topic for topic in object_topics if objects[topic]), None)
    if source is not None:
        samples = objects[source]
        times = _times(samples, use_log_time)
        order = np.argsort(times, kind='stable')
        record.update(object_source=source, object_time=times[order],
                      object_position=np.array([s[2] for s in samples])[order],
                      object_quat_xyzw=np.array([s[3] for s in samples])[order],
                      object_velocity=np.array([s[4] for s in samples])[order])
    if phases:
        times = _times(phases, use_log_time)
        order = np.argsort(times, kind='stable')
        record.update(phase_time=times[order], phase=tuple(phases[i][2] for i in order))
    return EpisodeRecord(**record)


def _times(samples, use_log_time):
    """Return the sample times [s]: header stamps, or log times if the stamps are all equal."""
    if use_log_time:
        return np.array([1e-9 * sample[1] for sample in samples])
    return np.array([sample[0] for sample in samples])


def _joint_sample(topic, msg, arm, log_time):
    """Return (stamp, log_time, position (7,), velocity (7,) or NaN) of a JointState."""
    names = contract.joint_names(arm)
    if list(msg.name) and set(names) <= set(msg.name) and len(msg.position) == len(msg.name):
        order = [list(msg.name).index(name) for name in names]
    elif not list(msg.name) and len(msg.position) == len(names):
        order = list(range(len(names)))
    else:
        raise InputError(f'{topic}: joint state names {list(msg.name)} with '
                         f'{len(msg.position)} positions do not cover {names}')
    position = np.array(msg.position)[order]
    velocity = (np.array(msg.velocity)[order] if len(msg.velocity) == len(msg.position)
                else np.full(len(names), np.nan))
    return _stamp(msg), log_time, position, velocity
