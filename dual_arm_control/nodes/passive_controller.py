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

import sys

from diagnostic_msgs.msg import DiagnosticStatus
from dual_arm_control import contract
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.passive_control import PassiveControllerConfig
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.nodes.command_signature import command_key, command_signature
from dual_arm_control.nodes.diagnostics import CounterDiagnostics, refusal_logger
from dual_arm_control.nodes.messages import (arm_command_of, joint_state_of, stamp_ns,
                                             time_msg, wrench_of)
from dual_arm_control.nodes.process import create_topic_publisher, run_node
from dual_arm_control.parameters import ConfigParameters, NodeParameters
from dual_arm_control.runtime.controller_step import ControllerStep, DS_COMMAND_LAG_KEY
from dual_arm_control.runtime.inputs import ArrivalBarrier
from dual_arm_control.runtime.node_settings import controller_parameter_problem, node_table
from rclpy.node import Node


class PassiveControllerNode(Node):
    """Answer each joint state of one arm with the passive-DS torque command."""

    def __init__(self, node_name='passive_controller', **node_options):
        super().__init__(node_name, **node_options)
        settings = NodeParameters(self, node_table('passive_controller').settings,
                                  extra_problem=controller_parameter_problem,
                                  on_change=self._on_setting)
        self.arm = settings['arm']
        self.lockstep = settings['lockstep']
        self._diagnostics = CounterDiagnostics(self)
        parameters = ConfigParameters(self, PassiveControllerConfig(),
                                      lambda config: self.step.reconfigure(config))
        cell = load_cell()
        self.step = ControllerStep(arm_model(self.arm, cell), cell.arm(self.arm).q_home,
                                   parameters.config, settings['ds_period'],
                                   settings['command_timeout'], settings['torque_interface'],
                                   refusal_logger(self.get_logger()))
        self._joint_names = contract.joint_names(self.arm)
        self._joint_state = None
        self._barrier = ArrivalBarrier(self._required)
        self._torque_pub = create_topic_publisher(self, contract.TORQUE_COMMAND)
        self._torque_msg = contract.TORQUE_COMMAND.msg_type()
        self._torque_msg.name = self._joint_names
        self._command_key = command_key()
        self.create_subscription(contract.DS_COMMAND.msg_type, contract.DS_COMMAND.name,
                                 self._on_ds_command,
                                 contract.DS_COMMAND.subscription_qos(self.lockstep))
        self.create_subscription(contract.CONTACT_WRENCH.msg_type, contract.CONTACT_WRENCH.name,
                                 self._on_contact_wrench,
                                 contract.CONTACT_WRENCH.subscription_qos(self.lockstep))
        self._joint_state_sub = self.create_subscription(
            contract.JOINT_STATES.msg_type, contract.JOINT_STATES.name, self._on_joint_state,
            contract.JOINT_STATES.subscription_qos(self.lockstep))
        if self.get_namespace() != f'/{self.arm}':
            self.get_logger().warning(f'arm {self.arm} runs in namespace '
                                      f'{self.get_namespace()}, expected /{self.arm}')
        self.get_logger().info(
            f'{self.arm} passive controller up: {"lockstep" if self.lockstep else "realtime"}, '
            f'torque interface {settings["torque_interface"]}, '
            f'ticks every {settings["ds_period"] * 1e3:g} ms, state '
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

    def _on_setting(self, name, value):
        if name == 'command_timeout':
            self.step.set_command_timeout(value)

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
        if self._command_key is not None:
            self._torque_msg.header.frame_id = command_signature(
                self._command_key, t_ns, self._joint_names, torque.effort)
        self._torque_pub.publish(self._torque_msg)
        self._diagnostics.publish_if_due(t_ns, self._report)

    def _report(self):
        values = dict(self.step.counters, dropped_stamps=self._barrier.dropped)
        lag = self.step.take_ds_command_lag()
        if lag is not None:
            values[DS_COMMAND_LAG_KEY] = round(lag * 1e3, 3)
        values.update({f'refused_{reason}': n for reason, n in self.step.refusals.counts.items()})
        if self.step.refusals.total or values['holds_by_controller']:
            return DiagnosticStatus.WARN, 'inputs refused or control law held', values
        return DiagnosticStatus.OK, 'running', values


def main(args=None):
    """Run one arm's controller until Ctrl-C or SIGTERM; return the exit code."""
    return run_node(PassiveControllerNode, 'passive_controller', args)


if __name__ == '__main__':
    sys.exit(main())
