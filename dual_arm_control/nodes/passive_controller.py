"""
passive_controller: the passive-DS torque law of one arm (core.passive_control), per FRI cycle.

Run one per arm in the arm's namespace (`-r __ns:=/left -p arm:=left`); all topics are relative.
Each joint state (FRI cycle t_k) is answered by one torque_command stamped t_k. On a tick cycle
(TickSchedule(ds_period), the same ticks the DS and the wrench QP compute) in lockstep mode the
state is buffered until ds_command(t_k) and contact_wrench(t_k) have arrived; on other cycles,
and always in realtime mode (`lockstep` false), the newest inputs are used at once.

Inputs: a ds_command (Odometry: desired tool orientation and twist) more than `command_timeout`
sim seconds away from t_k, or none yet, gives the hold torque g(q) - D_hold dq (counted); the
same age limit drops a contact wrench (no contact wrench, counted). Malformed or non-finite
inputs are refused and counted; a refused input still counts as arrived for the lockstep wait
and the newest valid one is used, so the torque is never NaN. A cycle stamp equal to the last
one (the bridge republished the state) is answered with the same command again; an earlier one
(simulation reset) restarts the tick schedule.

Parameters: arm, lockstep, fri_period, ds_period (read-only), command_timeout, the
PassiveControllerConfig fields (ConfigParameters, applied from the next cycle on) and
diagnostics_period.
"""

import math
import sys

from diagnostic_msgs.msg import DiagnosticStatus
from dual_arm_control import contract
from dual_arm_control.core.exceptions import ConfigError, InputError
from dual_arm_control.core.passive_control import (hold_torque, PassiveController,
                                                   PassiveControllerConfig)
from dual_arm_control.core.validation import check_range
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.nodes.common import (CounterDiagnostics, create_topic_publisher,
                                           joint_state_arrays, odometry_arrays, RefusalCounter,
                                           run_node, seconds_to_ns, stamp_ns,
                                           TickSchedule, time_msg, wrench_array)
from dual_arm_control.parameters import ConfigParameters, parameter_descriptor
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node

FRI_PERIODS = (0.001, 0.002, 0.005)
DS_PERIOD_RANGE = (0.001, 0.1)
MAX_COMMAND_TIMEOUT = 1.0
COUNTERS = ('cycles', 'ds_commands_received', 'contact_wrenches_received', 'commands_published',
            'repeated_answers', 'abandoned_waits', 'holds_no_command', 'holds_stale_command',
            'holds_by_controller', 'saturated', 'no_contact_wrench', 'stale_contact_wrench',
            'schedule_restarts')


def parameter_problem(name, value, current):
    """
    Return why a node parameter value is invalid, or None if it is acceptable.

    current: {name: value} of the other node parameters as they will be after the set (for the
    checks that relate two of them).
    """
    try:
        if name == 'arm' and value not in contract.ARMS:
            return f'arm must be one of {contract.ARMS}, got {value!r}'
        if name == 'fri_period' and not any(math.isclose(value, p) for p in FRI_PERIODS):
            return f'fri_period must be one of {FRI_PERIODS} s, got {value!r}'
        if name == 'ds_period':
            check_range('ds_period', value, max(DS_PERIOD_RANGE[0],
                                                current.get('fri_period', 0.0)),
                        DS_PERIOD_RANGE[1], 's')
        if name == 'command_timeout':
            longest_gap = current.get('ds_period', 0.0) + current.get('fri_period', 0.0)
            check_range('command_timeout (must exceed ds_period + fri_period, the longest gap '
                        'between two DS commands)', value, longest_gap, MAX_COMMAND_TIMEOUT,
                        's', low_open=True)
    except ConfigError as error:
        return str(error)
    return None


class PassiveControllerNode(Node):
    """Answer each joint state of one arm with the passive-DS torque command."""

    def __init__(self, node_name='passive_controller', **node_options):
        super().__init__(node_name, **node_options)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self._declare_parameters()
        self.add_post_set_parameters_callback(self._apply_parameters)
        self.arm = self.get_parameter('arm').value
        self.lockstep = self.get_parameter('lockstep').value
        self._command_timeout_ns = seconds_to_ns(self.get_parameter('command_timeout').value)
        self._diagnostics = CounterDiagnostics(self)
        self._config_parameters = ConfigParameters(self, PassiveControllerConfig(),
                                                   self._on_config)
        cell = load_cell()
        self._model = arm_model(self.arm, cell)
        self._q_home = cell.arm(self.arm).q_home
        self._torque_limits = self._model.torque_limits
        self._controller = PassiveController(self._model, self._q_home,
                                             self._config_parameters.config)
        self._pending_config = None
        self._schedule = TickSchedule(self.get_parameter('ds_period').value)
        self._joint_names = contract.joint_names(self.arm)

        self.refusals = RefusalCounter(self.get_logger())
        self.counters = dict.fromkeys(COUNTERS, 0)
        self._command = None
        self._command_arrived_ns = None
        self._wrench = None
        self._wrench_arrived_ns = None
        self._waiting = None
        self._last_cycle_ns = None
        self._answer_msg = None

        self._torque_pub = create_topic_publisher(self, contract.TORQUE_COMMAND)
        self._ds_command_sub, self._contact_wrench_sub, self._joint_state_sub = (
            self.create_subscription(topic.msg_type, topic.name, callback, topic.qos)
            for topic, callback in ((contract.DS_COMMAND, self._on_ds_command),
                                    (contract.CONTACT_WRENCH, self._on_contact_wrench),
                                    (contract.JOINT_STATES, self._on_joint_state)))
        if self.get_namespace() != f'/{self.arm}':
            self.get_logger().warning(f'arm {self.arm} runs in namespace '
                                      f'{self.get_namespace()}, expected /{self.arm}')
        self.get_logger().info(
            f'{self.arm} passive controller up: {"lockstep" if self.lockstep else "realtime"}, '
            f'ticks every {self.get_parameter("ds_period").value * 1e3:g} ms, state '
            f'{self._joint_state_sub.topic_name} -> command {self._torque_pub.topic_name}')

    @property
    def controller(self):
        """Return the core PassiveController in use (its config is the applied one)."""
        return self._controller

    @property
    def awaited_tick_ns(self):
        """Return the stamp of the tick waiting for its DS command and wrench, or None."""
        return None if self._waiting is None else self._waiting[0]

    def _declare_parameters(self):
        """Declare the node parameters (the core config is declared by ConfigParameters)."""
        self.declare_parameter('arm', '', parameter_descriptor(
            'which arm this controller drives', read_only=True,
            constraints=f'one of {contract.ARMS}'))
        self.declare_parameter('lockstep', True, parameter_descriptor(
            'true: on tick cycles wait for ds_command and contact_wrench of the same stamp '
            '(deterministic, with the lockstep bridge); false: never wait, use the newest',
            read_only=True))
        self.declare_parameter('fri_period', 0.002, parameter_descriptor(
            'FRI cycle of the joint states [s]', read_only=True,
            floating_range=(FRI_PERIODS[0], FRI_PERIODS[-1]), constraints=f'one of {FRI_PERIODS}'))
        self.declare_parameter('ds_period', 0.005, parameter_descriptor(
            'period of the DS and wrench QP ticks on the FRI cycles (TickSchedule) [s]',
            read_only=True, floating_range=DS_PERIOD_RANGE, constraints='>= fri_period'))
        self.declare_parameter('command_timeout', 0.05, parameter_descriptor(
            'a ds_command or contact_wrench further than this from the cycle is stale: hold '
            'torque / no wrench [s, sim time]', floating_range=(0.0, MAX_COMMAND_TIMEOUT),
            constraints='> ds_period + fri_period'))

    def _validate_parameters(self, parameters):
        """Refuse node parameter values with a reason naming the parameter and range."""
        names = ('arm', 'lockstep', 'fri_period', 'ds_period', 'command_timeout')
        current = {name: self.get_parameter(name).value for name in names
                   if self.has_parameter(name)}
        current.update({p.name: p.value for p in parameters if p.name in names})
        for parameter in parameters:
            problem = parameter_problem(parameter.name, parameter.value, current)
            if problem is not None:
                return SetParametersResult(successful=False, reason=problem)
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters):
        """Use a new command timeout from the next cycle on."""
        for parameter in parameters:
            if parameter.name == 'command_timeout':
                self._command_timeout_ns = seconds_to_ns(parameter.value)

    def _on_config(self, config):
        """Keep an accepted controller config for the next cycle."""
        self._pending_config = config

    # -- inputs ----------------------------------------------------------------------------------

    def _on_ds_command(self, msg):
        """Keep the newest valid DS command; a refused one still ends a lockstep wait."""
        t_ns = stamp_ns(msg.header.stamp)
        self.counters['ds_commands_received'] += 1
        try:
            _, R_world_desired, v_world_desired, w_world_desired = odometry_arrays(msg)
        except InputError as error:
            self.refusals.refuse('ds_command', f'stamp {t_ns} ns: {error}')
        else:
            self._command = (t_ns, v_world_desired, w_world_desired, R_world_desired)
        self._command_arrived_ns = t_ns
        self._answer_waiting_tick()

    def _on_contact_wrench(self, msg):
        """Keep the newest valid contact wrench; a refused one still ends a lockstep wait."""
        t_ns = stamp_ns(msg.header.stamp)
        self.counters['contact_wrenches_received'] += 1
        try:
            wrench = wrench_array(msg.wrench)
        except InputError as error:
            self.refusals.refuse('contact_wrench', f'stamp {t_ns} ns: {error}')
        else:
            self._wrench = (t_ns, wrench)
        self._wrench_arrived_ns = t_ns
        self._answer_waiting_tick()

    def _on_joint_state(self, msg):
        """Answer a cycle now, or (lockstep tick) once its DS command and wrench are in."""
        t_ns = stamp_ns(msg.header.stamp)
        try:
            q, dq, _ = joint_state_arrays(msg, self._joint_names)
        except InputError as error:
            self.refusals.refuse('joint_state', f'stamp {t_ns} ns: {error}')
            return
        if self._last_cycle_ns is not None and t_ns <= self._last_cycle_ns:
            if t_ns == self._last_cycle_ns:
                if self._waiting is None and self._answer_msg is not None:
                    self._torque_pub.publish(self._answer_msg)
                    self.counters['repeated_answers'] += 1
                return
            self._schedule.reset()
            self.counters['schedule_restarts'] += 1
            self.get_logger().info(f'cycle stamp went back to {t_ns} ns: tick schedule restarted')
        if self._waiting is not None:
            self.counters['abandoned_waits'] += 1
            self._waiting = None
        self._last_cycle_ns = t_ns
        self.counters['cycles'] += 1
        tick = self._schedule.due(t_ns)
        if tick:
            self._schedule.take(t_ns)
        if tick and self.lockstep and not self._inputs_arrived(t_ns):
            self._waiting = (t_ns, q, dq)
            return
        self._answer(t_ns, q, dq)

    def _inputs_arrived(self, t_ns):
        """Return True once the DS command and the wrench stamped t_ns arrived (valid or not)."""
        return self._command_arrived_ns == t_ns and self._wrench_arrived_ns == t_ns

    def _answer_waiting_tick(self):
        """Answer the buffered tick if its inputs are complete."""
        if self._waiting is not None and self._inputs_arrived(self._waiting[0]):
            waiting, self._waiting = self._waiting, None
            self._answer(*waiting)

    # -- output ----------------------------------------------------------------------------------

    def _answer(self, t_ns, q, dq):
        """Publish the torque command of cycle t_ns from the newest valid inputs."""
        if self._pending_config is not None:
            self._controller = PassiveController(self._model, self._q_home,
                                                 self._pending_config)
            self._pending_config = None
        torque = self._torque(t_ns, q, dq)
        msg = contract.TORQUE_COMMAND.msg_type()
        msg.header.stamp = time_msg(t_ns)
        msg.name = self._joint_names
        msg.effort = torque.tolist()
        self._torque_pub.publish(msg)
        self._answer_msg = msg
        self.counters['commands_published'] += 1
        self._diagnostics.publish_if_due(t_ns, self._report)

    def _torque(self, t_ns, q, dq):
        """Return the joint torques [N m] of cycle t_ns: the control law, or the hold."""
        if self._command is None:
            self.counters['holds_no_command'] += 1
            return self._hold_torque(q, dq)
        command_ns, v_world_desired, w_world_desired, R_world_desired = self._command
        if abs(t_ns - command_ns) > self._command_timeout_ns:
            self.counters['holds_stale_command'] += 1
            return self._hold_torque(q, dq)
        contact_wrench = None
        if self._wrench is None:
            self.counters['no_contact_wrench'] += 1
        elif abs(t_ns - self._wrench[0]) > self._command_timeout_ns:
            self.counters['stale_contact_wrench'] += 1
        else:
            contact_wrench = self._wrench[1]
        result = self._controller.torque_command(q, dq, v_world_desired, w_world_desired,
                                                 R_world_desired, contact_wrench)
        self.counters['holds_by_controller'] += int(result.held)
        self.counters['saturated'] += int(result.saturated)
        return result.torque

    def _hold_torque(self, q, dq):
        """Return the safety hold g(q) - D_hold dq within the torque limits [N m]."""
        torque = hold_torque(self._model.gravity_torque(q), dq,
                             self._controller.config.hold_damping)
        return np.clip(torque, -self._torque_limits, self._torque_limits)

    def _report(self):
        """Return (level, message, values) of the diagnostics."""
        values = dict(self.counters)
        values.update({f'refused_{reason}': n for reason, n in self.refusals.counts.items()})
        if self.refusals.total or values['holds_by_controller']:
            return DiagnosticStatus.WARN, 'inputs refused or control law held', values
        return DiagnosticStatus.OK, 'running', values


def main(args=None):
    """Run one arm's controller until Ctrl-C or SIGTERM; return the exit code."""
    return run_node(PassiveControllerNode, 'passive_controller', args)


if __name__ == '__main__':
    sys.exit(main())
