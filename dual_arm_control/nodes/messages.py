"""
Messages <-> runtime signals: the only place that knows both.

Every field is copied as float64 both ways, so a signal that crosses a topic arrives with the
same bits it left with. Reading a message validates it through the signal's constructor, which
raises InputError naming the problem. Stamps are integer nanoseconds.
"""

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from dual_arm_control import contract
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.geometry import matrix_to_quat_xyzw
from dual_arm_control.runtime.signals import (arm_command_sample, joint_state_sample,
                                              no_object_state, object_state, phase_sample,
                                              pose_sample, twist_sample, wrench_sample)
from dual_arm_control.runtime.timing import NANOSECONDS_PER_SECOND
from geometry_msgs.msg import Transform, Twist
import numpy as np
from std_msgs.msg import Header
from trajectory_msgs.msg import MultiDOFJointTrajectory, MultiDOFJointTrajectoryPoint


def time_msg(stamp_ns):
    """Return a builtin_interfaces/Time for a time in integer nanoseconds."""
    seconds, nanoseconds = divmod(int(stamp_ns), NANOSECONDS_PER_SECOND)
    return Time(sec=seconds, nanosec=nanoseconds)


def stamp_ns(stamp):
    """Return a builtin_interfaces/Time as integer nanoseconds."""
    return stamp.sec * NANOSECONDS_PER_SECOND + stamp.nanosec


def header(stamp, frame_id=contract.WORLD_FRAME):
    """Return a std_msgs/Header with a stamp in nanoseconds and a frame."""
    return Header(stamp=time_msg(stamp), frame_id=frame_id)


def vector3(msg):
    """Return a geometry_msgs Vector3/Point as a (3,) array."""
    return np.array([msg.x, msg.y, msg.z], dtype=float)


def set_vector3(msg, values):
    """Write a (3,) array into a Vector3/Point message."""
    msg.x, msg.y, msg.z = (float(v) for v in values)


def quaternion(msg):
    """Return a geometry_msgs Quaternion as (x, y, z, w)."""
    return np.array([msg.x, msg.y, msg.z, msg.w], dtype=float)


def set_quaternion(msg, quat_xyzw):
    """Write (x, y, z, w) into a Quaternion message."""
    msg.x, msg.y, msg.z, msg.w = (float(v) for v in quat_xyzw)


def set_pose(msg, position, quat_xyzw):
    """Write a position and an (x, y, z, w) quaternion into a Pose message."""
    set_vector3(msg.position, position)
    set_quaternion(msg.orientation, quat_xyzw)


def set_odometry(msg, position, quat_xyzw, linear, angular):
    """Write a pose (position, quaternion) and twist into an Odometry message."""
    set_pose(msg.pose.pose, position, quat_xyzw)
    set_vector3(msg.twist.twist.linear, linear)
    set_vector3(msg.twist.twist.angular, angular)


def fill_odometry(msg, position, R_world, linear, angular):
    """Write a pose (position, rotation matrix) and twist into an Odometry message."""
    set_odometry(msg, position, matrix_to_quat_xyzw(R_world), linear, angular)


def set_wrench(msg, wrench):
    """Write a (6,) [force; torque] array into a Wrench message."""
    set_vector3(msg.force, wrench[:3])
    set_vector3(msg.torque, wrench[3:])


def joint_state_of(msg, expected_names):
    """Return the JointStateSample of expected_names in a JointState (matched by name)."""
    return joint_state_sample(stamp_ns(msg.header.stamp), msg.name, msg.position,
                              msg.velocity, msg.effort, expected_names)


def fill_joint_state(msg, names, sample):
    """Write a JointStateSample (positions, velocities, efforts of names) into a JointState."""
    msg.header.stamp = time_msg(sample.stamp_ns)
    msg.name = list(names)
    msg.position = sample.position.tolist()
    msg.velocity = sample.velocity.tolist()
    msg.effort = sample.effort.tolist()


def wrench_of(msg):
    """Return the WrenchSample of a WrenchStamped."""
    return wrench_sample(stamp_ns(msg.header.stamp), vector3(msg.wrench.force),
                         vector3(msg.wrench.torque))


def fill_wrench(msg, sample):
    """Write a WrenchSample into a WrenchStamped (frame left as set)."""
    msg.header.stamp = time_msg(sample.stamp_ns)
    set_wrench(msg.wrench, sample.wrench)


def pose_of(msg):
    """Return the PoseSample of a PoseStamped."""
    return pose_sample(stamp_ns(msg.header.stamp), vector3(msg.pose.position),
                       quaternion(msg.pose.orientation))


def fill_pose(msg, sample):
    """Write a PoseSample into a PoseStamped (frame left as set)."""
    msg.header.stamp = time_msg(sample.stamp_ns)
    set_pose(msg.pose, sample.position, sample.quat_xyzw)


def object_state_of(msg):
    """Return the ObjectState of an /object/state Odometry (no estimate: contract flag)."""
    stamp = stamp_ns(msg.header.stamp)
    if msg.pose.covariance[0] == contract.NO_ESTIMATE_COVARIANCE:
        return no_object_state(stamp)
    return object_state(stamp, vector3(msg.pose.pose.position),
                        quaternion(msg.pose.pose.orientation), vector3(msg.twist.twist.linear),
                        vector3(msg.twist.twist.angular))


def fill_object_state(msg, state):
    """Write an ObjectState into an Odometry (no estimate: contract flag in the covariance)."""
    msg.header.stamp = time_msg(state.stamp_ns)
    set_odometry(msg, state.position, state.quat_xyzw, state.linear_velocity,
                 state.angular_velocity)
    for covariance, values in ((msg.pose.covariance, state.pose_covariance),
                               (msg.twist.covariance, state.twist_covariance)):
        covariance[:] = np.zeros(36) if values is None else np.ravel(values)
    if not state.valid:
        msg.pose.covariance[0] = contract.NO_ESTIMATE_COVARIANCE


def arm_command_of(msg):
    """Return the ArmCommandSample of a ds_command (one-point MultiDOFJointTrajectory)."""
    if len(msg.points) != 1 or len(msg.points[0].transforms) != 1 \
            or len(msg.points[0].velocities) != 1:
        raise InputError('a DS command is one trajectory point with one transform and one '
                         f'velocity, got {len(msg.points)} point(s)')
    point = msg.points[0]
    transform, velocity = point.transforms[0], point.velocities[0]
    return arm_command_sample(stamp_ns(msg.header.stamp), vector3(transform.translation),
                              quaternion(transform.rotation), vector3(velocity.linear),
                              vector3(velocity.angular))


def arm_command_message(arm, sample):
    """Return the ds_command of an ArmCommandSample for arm (joint '<arm>_tool', frame world)."""
    transform = Transform()
    set_vector3(transform.translation, sample.p_world_attractor)
    set_quaternion(transform.rotation, sample.quat_xyzw)
    velocity = Twist()
    set_vector3(velocity.linear, sample.v_world)
    set_vector3(velocity.angular, sample.w_world)
    point = MultiDOFJointTrajectoryPoint(transforms=[transform], velocities=[velocity],
                                         accelerations=[Twist()])
    return MultiDOFJointTrajectory(header=header(sample.stamp_ns), joint_names=[f'{arm}_tool'],
                                   points=[point])


def twist_of(msg):
    """Return the TwistSample of a TwistStamped."""
    return twist_sample(stamp_ns(msg.header.stamp), vector3(msg.twist.linear),
                        vector3(msg.twist.angular))


def fill_twist(msg, sample):
    """Write a TwistSample into a TwistStamped."""
    msg.header.stamp = time_msg(sample.stamp_ns)
    set_vector3(msg.twist.linear, sample.linear)
    set_vector3(msg.twist.angular, sample.angular)


def phase_message(sample):
    """Return the DiagnosticArray that carries one tick's phase, task, events and reason."""
    status = DiagnosticStatus(
        level=DiagnosticStatus.OK, name=contract.PHASE_STATUS_NAME, hardware_id='dual_arm',
        message=sample.phase.value,
        values=[KeyValue(key='task', value=sample.task.value),
                KeyValue(key='time_in_phase', value=f'{sample.time_in_phase:.6f}'),
                KeyValue(key='events', value=','.join(sample.events)),
                KeyValue(key='reason', value=sample.reason)])
    return DiagnosticArray(header=header(sample.stamp_ns), status=[status])


def phase_of(msg):
    """Return the PhaseSample of a /dual_arm/phase message; InputError if it has none."""
    for status in msg.status:
        if status.name == contract.PHASE_STATUS_NAME:
            values = {value.key: value.value for value in status.values}
            events = tuple(e for e in values.get('events', '').split(',') if e)
            return phase_sample(stamp_ns(msg.header.stamp), status.message,
                                values.get('task'), values.get('time_in_phase', 'nan'),
                                events, values.get('reason', ''))
    return phase_sample(stamp_ns(msg.header.stamp), None, None, 'nan')


class LatestMessage:
    """
    The newest message of an input, read (converted and checked) only when its value is used.

    Sensor streams arrive at 500 Hz while a tick uses them at 200 Hz: keeping the raw message
    and reading it on use saves the conversion of the others. value() returns the reading of the
    newest message, or, if that one is refused (InputError, counted by refuse(reason, detail)),
    the last valid reading; None before any valid one.
    """

    def __init__(self, read, name, refuse):
        self._read = read
        self._name = name
        self._refuse = refuse
        self._message = None
        self._value = None

    def offer(self, msg):
        """Keep msg as the newest message (read later)."""
        self._message = msg

    def value(self):
        """Return the newest valid reading (see the class text)."""
        if self._message is not None:
            msg, self._message = self._message, None
            try:
                self._value = self._read(msg)
            except InputError as error:
                self._refuse(self._name, f'stamp {stamp_ns(msg.header.stamp)} ns: {error}')
        return self._value
