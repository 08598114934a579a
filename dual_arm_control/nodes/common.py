"""
What every node shell shares.

Time stamps, the lockstep tick schedule, message conversions with validation, refusal counting
and the Jazzy process lifetime.
Times travel as integer nanoseconds inside the nodes so that schedules computed in different
processes agree exactly.
"""

import math
import time

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from dual_arm_control import contract
from dual_arm_control.core.exceptions import DualArmControlError, InputError
from dual_arm_control.core.geometry import matrix_to_quat_xyzw, quat_xyzw_to_matrix
from dual_arm_control.pipeline import NANOSECONDS_PER_SECOND, seconds_to_ns, TickSchedule
import numpy as np
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor

LOG_THROTTLE_PERIOD = 1.0
DEFAULT_DIAGNOSTICS_PERIOD = 1.0
DIAGNOSTICS_PERIOD_RANGE = (0.01, 100.0)


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


def fill_odometry(msg, position, R_world, linear, angular):
    """Write a pose (position, rotation matrix) and twist into an Odometry message."""
    set_vector3(msg.pose.pose.position, position)
    set_quaternion(msg.pose.pose.orientation, matrix_to_quat_xyzw(R_world))
    set_vector3(msg.twist.twist.linear, linear)
    set_vector3(msg.twist.twist.angular, angular)


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


def run_node(node_factory, name, args=None):
    """
    Run one node until Ctrl-C or SIGTERM, the Jazzy way; return the process exit code.

    The node is built before the spin loop so a constructor error (bad parameters, bad files)
    is reported once and exits 2. EventsExecutor.spin() ignores signals, so the loop spins once
    at a time and checks rclpy.ok().
    """
    rclpy.init(args=args)
    try:
        node = node_factory()
    except (DualArmControlError, rclpy.exceptions.ParameterException) as error:
        rclpy.logging.get_logger(name).fatal(f'cannot start: {error}')
        rclpy.try_shutdown()
        return 2
    executor = EventsExecutor()
    executor.add_node(node)
    try:
        while rclpy.ok() and not getattr(node, 'finished', False):
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.remove_node(node)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


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
                               ParameterDescriptor(
                                   description='sim time between two /diagnostics messages of '
                                               'this node [s]',
                                   floating_point_range=[FloatingPointRange(
                                       from_value=low, to_value=high, step=0.0)]))
        self._publisher = node.create_publisher(
            contract.DIAGNOSTICS.msg_type, contract.DIAGNOSTICS.name, contract.DIAGNOSTICS.qos)
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
        status.values = [KeyValue(key=key, value=_format_value(value))
                         for key, value in values.items()]
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = time_msg(t_ns)
        self._publisher.publish(msg)
        return True


def _format_value(value):
    """Format a diagnostic value: floats to 6 significant digits, the rest as str()."""
    return f'{value:.6g}' if isinstance(value, float) else str(value)


__all__ = ['NANOSECONDS_PER_SECOND', 'seconds_to_ns', 'TickSchedule']
