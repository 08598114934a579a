"""
gravity_comp_controller: a test controller for one arm (stand-in for the passive controller).

Answers every joint state with a torque command stamped like the state, as the bridge's lockstep
mode expects: mode 'gravity' commands the gravity torque of the arm's pinocchio model minus joint
damping times velocity; mode 'zero' commands zero torque (the arm falls). States stamped within
`mute_window` are not answered (a stalled controller, for fault tests). Run one instance per arm
in the arm's namespace: `--ros-args -r __ns:=/left -p arm:=left`. Triggered by the incoming state,
no timers.
"""

import sys

from dual_arm_control import contract
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.description.cell import arm_model
from dual_arm_control.nodes.command_signature import command_key, command_signature
from dual_arm_control.nodes.messages import joint_state_of, stamp_ns
from dual_arm_control.nodes.process import create_topic_publisher, run_node
from dual_arm_control.parameters import NodeParameters
from dual_arm_control.runtime.node_settings import node_table
import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import JointState

LOG_THROTTLE_PERIOD = 1.0


def gravity_compensation_torque(gravity_torque, joint_velocity, joint_damping):
    """Return gravity torque [N m] minus joint_damping [N m s/rad] times velocity [rad/s]."""
    return np.asarray(gravity_torque) - joint_damping * np.asarray(joint_velocity)


class GravityCompController(Node):
    """Reply to each joint state of one arm with a gravity-compensation torque command."""

    def __init__(self, node_name='gravity_comp_controller', **node_options):
        super().__init__(node_name, **node_options)
        settings = NodeParameters(self, node_table('gravity_comp_controller').settings,
                                  on_change=self._on_setting)
        self.arm, self.mode, self.joint_damping = (settings[name] for name in (
            'arm', 'mode', 'joint_damping'))
        self._mute_ns = [int(round(v * 1e9)) for v in settings['mute_window']]
        self._model = arm_model(self.arm)
        self._joint_names = contract.joint_names(self.arm)
        self._command_pub = create_topic_publisher(self, contract.TORQUE_COMMAND)
        self._command_key = command_key()
        self._state_sub = self.create_subscription(
            contract.JOINT_STATES.msg_type, contract.JOINT_STATES.name, self._on_joint_state,
            contract.JOINT_STATES.qos)
        self.get_logger().info(
            f'{self.arm} gravity compensation: mode {self.mode}, joint damping '
            f'{self.joint_damping} N m s/rad, '
            f'state {self._state_sub.topic_name} -> command {self._command_pub.topic_name}')

    def _on_setting(self, name, value):
        """Apply a new mode or damping from the next state on."""
        if name == 'mode':
            self.mode = value
        elif name == 'joint_damping':
            self.joint_damping = value

    def _on_joint_state(self, msg):
        """Answer the state with a torque command carrying the state's stamp."""
        if self._mute_ns[0] <= stamp_ns(msg.header.stamp) < self._mute_ns[1]:
            return
        try:
            state = joint_state_of(msg, self._joint_names)
        except InputError as error:
            self.get_logger().error(f'joint state refused: {error}; no command',
                                    throttle_duration_sec=LOG_THROTTLE_PERIOD)
            return
        if self.mode == 'zero':
            torque = np.zeros(len(self._joint_names))
        else:
            torque = gravity_compensation_torque(self._model.gravity_torque(state.position),
                                                 state.velocity, self.joint_damping)
        command = JointState()
        command.header.stamp = msg.header.stamp
        command.name = self._joint_names
        command.position = state.position.tolist()
        command.effort = torque.tolist()
        if self._command_key is not None:
            command.header.frame_id = command_signature(
                self._command_key, stamp_ns(msg.header.stamp), self._joint_names, torque)
        self._command_pub.publish(command)


def main(args=None):
    """Run one arm's controller until Ctrl-C or SIGTERM."""
    return run_node(GravityCompController, 'gravity_comp_controller', args)


if __name__ == '__main__':
    sys.exit(main())
