"""
passive_controller: one arm's passive-DS torque law per FRI cycle (runtime ControllerStep).

Run one per arm in the arm's namespace (`-r __ns:=/left -p arm:=left`); all topics are relative.
Each joint state (FRI cycle t_k) is answered by one torque_command stamped t_k. With `lockstep`,
a DS tick cycle is answered only once ds_command(t_k) and contact_wrench(t_k) arrived (valid or
refused); other cycles, and every cycle in realtime, use the newest inputs at once. The
stale-input and hold policy is the runtime step's (runtime/controller_step.py).

Parameters: arm, lockstep, fri_period, ds_period (read-only), command_timeout, the
PassiveControllerConfig fields (live, from the next cycle on) and diagnostics_period.
"""

import math
import sys

from diagnostic_msgs.msg import DiagnosticStatus
from dual_arm_control import contract
from dual_arm_control.core.exceptions import ConfigError, InputError
from dual_arm_control.core.passive_control import PassiveControllerConfig
from dual_arm_control.core.validation import check_range
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.nodes.diagnostics import CounterDiagnostics, refusal_logger
from dual_arm_control.nodes.messages import (arm_command_of, joint_state_of, stamp_ns,
                                             time_msg, wrench_of)
from dual_arm_control.nodes.process import create_topic_publisher, run_node
from dual_arm_control.parameters import ConfigParameters, parameter_descriptor
from dual_arm_control.runtime.controller_step import ControllerStep
from dual_arm_control.runtime.inputs import ArrivalBarrier
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node

FRI_PERIODS = (0.001, 0.002, 0.005)
DS_PERIOD_RANGE = (0.001, 0.1)
MAX_COMMAND_TIMEOUT = 1.0
NODE_PARAMETERS = ('arm', 'lockstep', 'fri_period', 'ds_period', 'command_timeout')


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
        self._diagnostics = CounterDiagnostics(self)
        parameters = ConfigParameters(self, PassiveControllerConfig(),
                                      lambda config: self.step.reconfigure(config))
        cell = load_cell()
        self.step = ControllerStep(arm_model(self.arm, cell), cell.arm(self.arm).q_home,
                                   parameters.config, self.get_parameter('ds_period').value,
                                   self.get_parameter('command_timeout').value,
                                   refusal_logger(self.get_logger()))
        self._joint_names = contract.joint_names(self.arm)
        self._joint_state = None
        self._barrier = ArrivalBarrier(self._required)
        self._torque_pub = create_topic_publisher(self, contract.TORQUE_COMMAND)
        self._torque_msg = contract.TORQUE_COMMAND.msg_type()
        self._torque_msg.name = self._joint_names
        self.create_subscription(contract.DS_COMMAND.msg_type, contract.DS_COMMAND.name,
                                 self._on_ds_command, contract.DS_COMMAND.qos)
        self.create_subscription(contract.CONTACT_WRENCH.msg_type, contract.CONTACT_WRENCH.name,
                                 self._on_contact_wrench, contract.CONTACT_WRENCH.qos)
        self._joint_state_sub = self.create_subscription(
            contract.JOINT_STATES.msg_type, contract.JOINT_STATES.name, self._on_joint_state,
            contract.JOINT_STATES.qos)
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
        return self.step.controller

    @property
    def awaited_tick_ns(self):
        """Return the stamp of the cycle waiting for its DS command and wrench, or None."""
        state = self._joint_state
        if state is None or not self._barrier.pending(state.stamp_ns):
            return None
        return state.stamp_ns

    def _declare_parameters(self):
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
        current = {name: self.get_parameter(name).value for name in NODE_PARAMETERS
                   if self.has_parameter(name)}
        current.update({p.name: p.value for p in parameters if p.name in NODE_PARAMETERS})
        for parameter in parameters:
            problem = parameter_problem(parameter.name, parameter.value, current)
            if problem is not None:
                return SetParametersResult(successful=False, reason=problem)
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters):
        for parameter in parameters:
            if parameter.name == 'command_timeout':
                self.step.set_command_timeout(parameter.value)

    def _required(self, stamp):
        if self.lockstep and self.step.needs_tick_inputs(stamp):
            return {'joint_state', 'ds_command', 'contact_wrench'}
        return {'joint_state'}

    def _on_input(self, name, read, take, msg):
        try:
            take(read(msg))
        except InputError as error:
            self.step.refusals.refuse(name, f'stamp {stamp_ns(msg.header.stamp)} ns: {error}')
        for t_ns in self._barrier.arrived(stamp_ns(msg.header.stamp), name):
            self._answer(t_ns)

    def _on_ds_command(self, msg):
        self._on_input('ds_command', arm_command_of, self.step.command, msg)

    def _on_contact_wrench(self, msg):
        self._on_input('contact_wrench', wrench_of, self.step.wrench, msg)

    def _on_joint_state(self, msg):
        self._on_input('joint_state', lambda m: joint_state_of(m, self._joint_names),
                       self._keep_joint_state, msg)

    def _keep_joint_state(self, sample):
        self._joint_state = sample

    def _answer(self, t_ns):
        if self._joint_state is None or self._joint_state.stamp_ns != t_ns:
            return
        torque = self.step.cycle(self._joint_state)
        self._torque_msg.header.stamp = time_msg(t_ns)
        self._torque_msg.effort = torque.effort.tolist()
        self._torque_pub.publish(self._torque_msg)
        self._diagnostics.publish_if_due(t_ns, self._report)

    def _report(self):
        values = dict(self.step.counters, dropped_stamps=self._barrier.dropped)
        values.update({f'refused_{reason}': n for reason, n in self.step.refusals.counts.items()})
        if self.step.refusals.total or values['holds_by_controller']:
            return DiagnosticStatus.WARN, 'inputs refused or control law held', values
        return DiagnosticStatus.OK, 'running', values


def main(args=None):
    """Run one arm's controller until Ctrl-C or SIGTERM; return the exit code."""
    return run_node(PassiveControllerNode, 'passive_controller', args)


if __name__ == '__main__':
    sys.exit(main())
