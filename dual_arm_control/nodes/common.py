"""
What every node shell shares.

Time stamps, the lockstep tick schedule, message conversions with validation, refusal counting
and the Jazzy process lifetime.
Times travel as integer nanoseconds inside the nodes so that schedules computed in different
processes agree exactly.
"""

import json
import math
import signal
import time

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from dual_arm_control import contract
from dual_arm_control.core.exceptions import DualArmControlError, InputError
from dual_arm_control.core.geometry import matrix_to_quat_xyzw, quat_xyzw_to_matrix
from dual_arm_control.parameters import parameter_descriptor
from dual_arm_control.runtime.timing import NANOSECONDS_PER_SECOND, seconds_to_ns, TickSchedule
import numpy as np
import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.publisher import Publisher
from rclpy.signals import SignalHandlerOptions

LOG_THROTTLE_PERIOD = 1.0
DEFAULT_DIAGNOSTICS_PERIOD = 1.0
DIAGNOSTICS_PERIOD_RANGE = (0.01, 100.0)
# Wall time a stopping node waits for its subscribers to acknowledge its last messages [s].
FLUSH_TIMEOUT = 2.0
# The line a stopping node prints with {topic: messages published} (read by the bag tests).
PUBLISHED_COUNTS_PREFIX = 'published counts: '


def time_msg(stamp_ns):
    """Return a builtin_interfaces/Time for a time in integer nanoseconds."""
    seconds, nanoseconds = divmod(int(stamp_ns), NANOSECONDS_PER_SECOND)
    return Time(sec=seconds, nanosec=nanoseconds)


def stamp_ns(stamp):
    """Return a builtin_interfaces/Time as integer nanoseconds."""
    return stamp.sec * NANOSECONDS_PER_SECOND + stamp.nanosec


def joint_state_arrays(msg, expected_names, need_effort=False):
    """
    Return (position, velocity, effort) arrays of a JointState, checked.

    Raises InputError naming the problem: wrong or misordered joint names, wrong lengths,
    non-finite values. Effort may be empty unless need_effort.
    """
    if list(msg.name) != list(expected_names):
        raise InputError(f'joint names {list(msg.name)} differ from {list(expected_names)}')
    count = len(expected_names)
    fields = [('position', msg.position), ('velocity', msg.velocity), ('effort', msg.effort)]
    arrays = []
    for name, values in fields:
        if name == 'effort' and not need_effort and len(values) == 0:
            arrays.append(np.zeros(count))
            continue
        if len(values) != count:
            raise InputError(f'{name} has {len(values)} values, expected {count}')
        array = np.array(values, dtype=float)
        if not np.all(np.isfinite(array)):
            raise InputError(f'{name} contains NaN or Inf')
        arrays.append(array)
    return tuple(arrays)


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


def wrench_array(msg):
    """Return a geometry_msgs Wrench as (6,) [force; torque], checked finite."""
    array = np.concatenate((vector3(msg.force), vector3(msg.torque)))
    if not np.all(np.isfinite(array)):
        raise InputError('wrench contains NaN or Inf')
    return array


def set_wrench(msg, wrench):
    """Write a (6,) [force; torque] array into a Wrench message."""
    set_vector3(msg.force, wrench[:3])
    set_vector3(msg.torque, wrench[3:])


def odometry_arrays(msg):
    """
    Return (position, R_world, linear velocity, angular velocity) of an Odometry, checked.

    The quaternion must be finite and non-zero (it is normalised).
    """
    position = vector3(msg.pose.pose.position)
    quat_xyzw = quaternion(msg.pose.pose.orientation)
    linear = vector3(msg.twist.twist.linear)
    angular = vector3(msg.twist.twist.angular)
    values = np.concatenate((position, quat_xyzw, linear, angular))
    if not np.all(np.isfinite(values)):
        raise InputError('odometry contains NaN or Inf')
    return position, quat_xyzw_to_matrix(quat_xyzw), linear, angular


def has_estimate(msg):
    """Return False for an /object/state that says the tracker has no estimate yet."""
    return msg.pose.covariance[0] != contract.NO_ESTIMATE_COVARIANCE


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


def recorder_matched_counts(msg):
    """Return {topic: publishers matched} of a bag_record status, or None if a count is no int."""
    try:
        return {value.key: int(value.value) for status in msg.status for value in status.values}
    except ValueError:
        return None


def recorder_has_matched(node, matched):
    """Return True if bag_record matched every publisher node sees on each topic it records."""
    return matched is not None and all(node.count_publishers(topic) <= count
                                       for topic, count in matched.items())


class RefusalCounter:
    """Count refused inputs per reason and log them, throttled per reason."""

    def __init__(self, logger):
        self._logger = logger
        self.counts = {}
        self._last_log = {}

    def refuse(self, reason, detail):
        """Count one refusal and log it at most once per LOG_THROTTLE_PERIOD per reason."""
        self.counts[reason] = self.counts.get(reason, 0) + 1
        now = time.monotonic()
        if now - self._last_log.get(reason, -math.inf) >= LOG_THROTTLE_PERIOD:
            self._last_log[reason] = now
            self._logger.warning(f'refused {reason} ({self.counts[reason]} so far): {detail}')

    @property
    def total(self):
        """Return the number of refusals of every reason."""
        return sum(self.counts.values())


class CountingPublisher(Publisher):
    """A publisher that counts its messages, so a recording can be checked against it."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.published = 0

    def publish(self, msg):
        """Publish msg and count it."""
        super().publish(msg)
        self.published += 1


def create_topic_publisher(node, topic, arm=None):
    """
    Return a counting publisher of a contract topic with the contract's publisher QoS.

    arm resolves a per-arm topic to /<arm>/...; without it a per-arm topic stays relative to
    the node's namespace.
    """
    name = topic.name if arm is None else topic.resolved(arm)
    return node.create_publisher(topic.msg_type, name, topic.publisher_qos,
                                 publisher_class=CountingPublisher)


def published_counts(node):
    """Return {topic: messages published} over the node's counting publishers."""
    counts = {}
    for publisher in node.publishers:
        if isinstance(publisher, CountingPublisher):
            counts[publisher.topic_name] = counts.get(publisher.topic_name, 0) + \
                publisher.published
    return counts


def flush_publishers(node, timeout=FLUSH_TIMEOUT):
    """Wait until every reliable subscriber acknowledged the node's messages; return success."""
    deadline = time.monotonic() + timeout
    acknowledged = True
    for publisher in node.publishers:
        remaining = max(deadline - time.monotonic(), 0.0)
        try:
            acknowledged &= publisher.wait_for_all_acked(Duration(seconds=remaining))
        except RuntimeError:
            acknowledged = False  # rclpy's InvalidHandle/RCLError: the context is already gone
    return acknowledged


class StopRequest:
    """
    SIGINT/SIGTERM set a flag (with rclpy's own handlers off), until restore().

    So a stopping process can still finish its work with rclpy up: flush, drain, print.
    """

    def __init__(self):
        self.requested = False
        self._previous = {signum: signal.getsignal(signum)
                          for signum in (signal.SIGINT, signal.SIGTERM)}
        for signum in self._previous:
            signal.signal(signum, self.request)

    def request(self, signum=None, frame=None):
        """Ask the process to stop (the signal handler)."""
        self.requested = True

    def restore(self):
        """Put back the signal handlers that were there before."""
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)


def run_node(node_factory, name, args=None, drain=False, on_exit=None):
    """
    Run one node until Ctrl-C or SIGTERM, the Jazzy way; return the process exit code.

    The node is built before the spin loop so a constructor error (bad parameters, bad files)
    is reported once and exits 2. EventsExecutor.spin() ignores signals, so signals only set a
    flag and the loop spins once at a time. On the way out, with drain, node.drain(executor)
    still spins (a recorder takes the messages already delivered to it); then the node waits
    (FLUSH_TIMEOUT) until its subscribers acknowledged its last messages, prints its published
    counts and is destroyed. on_exit(node), if given, runs before that and returns the exit
    code (0 otherwise).
    """
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop = StopRequest()
    try:
        node = node_factory()
    except (DualArmControlError, rclpy.exceptions.ParameterException) as error:
        rclpy.logging.get_logger(name).fatal(f'cannot start: {error}')
        rclpy.try_shutdown()
        stop.restore()
        return 2
    executor = EventsExecutor()
    executor.add_node(node)
    status = 0
    try:
        while rclpy.ok() and not stop.requested and not getattr(node, 'finished', False):
            executor.spin_once(timeout_sec=0.1)
        if drain:
            node.drain(executor)
        flush_publishers(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if on_exit is not None:
            status = on_exit(node)
        counts = published_counts(node)
        if counts:
            print(PUBLISHED_COUNTS_PREFIX + json.dumps(counts, sort_keys=True), flush=True)
        executor.remove_node(node)
        node.destroy_node()
        rclpy.try_shutdown()
        stop.restore()
    return status


class CounterDiagnostics:
    """
    A node's counters on /diagnostics, at most once per `diagnostics_period` of sim time.

    Declares the `diagnostics_period` parameter [s]. Driven by the stamps of the messages the
    node handles, so it reports in lockstep runs (faster or slower than real time) as in real
    time; a stamp earlier than the last report (simulation reset) reports at once.
    """

    def __init__(self, node):
        self._node = node
        low, high = DIAGNOSTICS_PERIOD_RANGE
        node.declare_parameter('diagnostics_period', DEFAULT_DIAGNOSTICS_PERIOD,
                               parameter_descriptor('sim time between two /diagnostics '
                                                    'messages of this node [s]',
                                                    floating_range=(low, high)))
        self._publisher = create_topic_publisher(node, contract.DIAGNOSTICS)
        self._last_ns = None
        self.name = node.get_fully_qualified_name().lstrip('/')

    def publish_if_due(self, t_ns, report):
        """
        Publish report() = (level, message, {key: value}) if a period passed since the last one.

        report is only called when a message goes out. Return True if one was published.
        """
        period_ns = seconds_to_ns(self._node.get_parameter('diagnostics_period').value)
        if self._last_ns is not None and 0 <= t_ns - self._last_ns < period_ns:
            return False
        self._last_ns = t_ns
        level, message, values = report()
        status = DiagnosticStatus(level=level, name=self.name, message=message,
                                  hardware_id=self._node.get_name())
        status.values = [KeyValue(key=key, value=diagnostic_value(value))
                         for key, value in values.items()]
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = time_msg(t_ns)
        self._publisher.publish(msg)
        return True


def diagnostic_value(value):
    """Format a diagnostic value: floats to 6 significant digits, the rest as str()."""
    return f'{value:.6g}' if isinstance(value, float) else str(value)


__all__ = ['NANOSECONDS_PER_SECOND', 'seconds_to_ns', 'TickSchedule']
